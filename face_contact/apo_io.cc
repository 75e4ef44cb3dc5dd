#include "face_contact/apo_io.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <set>
#include <sstream>

#include "common/error.h"

namespace visco::face_contact {
namespace {

using Eigen::Matrix4d;
using Eigen::Vector3d;
using nlohmann::json;

constexpr double kDeg = std::numbers::pi / 180.0;

class Parser {
 public:
  explicit Parser(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void Fail(const std::string& where, const std::string& what) const {
    throw InputError(source_, where, what);
  }

  void Keys(const json& j, const std::string& where, const std::set<std::string>& allowed) const {
    if (!j.is_object()) Fail(where, "must be a JSON object");
    for (const auto& [key, value] : j.items()) {
      if (!allowed.count(key)) {
        std::string list;
        for (const std::string& a : allowed) list += (list.empty() ? "" : ", ") + a;
        Fail(where, fmt::format("unknown field '{}' (allowed: {})", key, list));
      }
    }
  }

  double Number(const json& j, const std::string& where) const {
    if (!j.is_number()) Fail(where, "must be a number");
    const double v = j.get<double>();
    if (!std::isfinite(v)) Fail(where, "must be finite");
    return v;
  }

  double Positive(const json& j, const std::string& where) const {
    const double v = Number(j, where);
    if (!(v > 0)) Fail(where, "must be positive");
    return v;
  }

  std::vector<double> Numbers(const json& j, const std::string& where, size_t n) const {
    if (!j.is_array() || j.size() != n) Fail(where, fmt::format("must be an array of {} numbers", n));
    std::vector<double> out;
    for (size_t i = 0; i < n; ++i) out.push_back(Number(j[i], fmt::format("{}[{}]", where, i)));
    return out;
  }

  Vector3d Vec3(const json& j, const std::string& where) const {
    const auto v = Numbers(j, where, 3);
    return {v[0], v[1], v[2]};
  }

  Matrix4d Pose(const json& j, const std::string& where) const {
    Keys(j, where, {"t", "rxyz_deg", "R"});
    if (!j.contains("t")) Fail(where, "needs 't': [x, y, z] in metres");
    Matrix4d m = Matrix4d::Identity();
    m.block<3, 1>(0, 3) = Vec3(j["t"], where + ".t");
    if (j.contains("rxyz_deg") == j.contains("R")) {
      Fail(where, "give exactly one of 'rxyz_deg' ([a, b, c]: R = Rx(a)·Ry(b)·Rz(c)) or 'R' (3x3 rows)");
    }
    if (j.contains("rxyz_deg")) {
      const Vector3d a = Vec3(j["rxyz_deg"], where + ".rxyz_deg") * kDeg;
      Vector6d q;
      q << 0, 0, 0, a.x(), a.y(), a.z();
      m.block<3, 3>(0, 0) = DeltaTransform(q).block<3, 3>(0, 0);
    } else {
      const json& r = j["R"];
      if (!r.is_array() || r.size() != 3) Fail(where + ".R", "must be 3 rows of 3 numbers");
      Eigen::Matrix3d rot;
      for (int row = 0; row < 3; ++row) {
        const auto v = Numbers(r[row], fmt::format("{}.R[{}]", where, row), 3);
        for (int col = 0; col < 3; ++col) rot(row, col) = v[col];
      }
      const double err = (rot.transpose() * rot - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
      if (err > 1e-6 || rot.determinant() <= 0) {
        Fail(where + ".R", fmt::format("is not a rotation (|RᵀR − I| = {:.3g}, det = {:.6g})", err, rot.determinant()));
      }
      // Remove the rounding of the file: nearest rotation.
      Eigen::JacobiSVD<Eigen::Matrix3d> svd(rot, Eigen::ComputeFullU | Eigen::ComputeFullV);
      m.block<3, 3>(0, 0) = svd.matrixU() * svd.matrixV().transpose();
    }
    return m;
  }

  Polyhedron Model(const json& j, const std::string& where) const {
    Keys(j, where, {"box", "prism", "vertices", "faces"});
    const int kinds = static_cast<int>(j.contains("box")) + static_cast<int>(j.contains("prism")) +
                      static_cast<int>(j.contains("vertices") || j.contains("faces"));
    if (kinds != 1) Fail(where, "give exactly one of 'box', 'prism', or 'vertices' with 'faces'");
    if (j.contains("box")) {
      const Vector3d size = Vec3(j["box"], where + ".box");
      if (!(size.minCoeff() > 0)) Fail(where + ".box", "sizes must be positive");
      return MakeBox(size);
    }
    if (j.contains("prism")) {
      const json& p = j["prism"];
      Keys(p, where + ".prism", {"profile", "length"});
      if (!p.contains("profile") || !p.contains("length")) Fail(where + ".prism", "needs 'profile' and 'length'");
      const json& prof = p["profile"];
      if (!prof.is_array() || prof.size() < 3) Fail(where + ".prism.profile", "must list at least 3 points [x, z]");
      std::vector<Eigen::Vector2d> profile;
      for (size_t i = 0; i < prof.size(); ++i) {
        const auto v = Numbers(prof[i], fmt::format("{}.prism.profile[{}]", where, i), 2);
        profile.emplace_back(v[0], v[1]);
      }
      double area = 0;
      for (size_t i = 0; i < profile.size(); ++i) {
        const auto& a = profile[i];
        const auto& b = profile[(i + 1) % profile.size()];
        area += a.x() * b.y() - b.x() * a.y();
      }
      if (area < 0) std::reverse(profile.begin(), profile.end());  // either orientation is accepted
      return MakePrism(profile, Positive(p["length"], where + ".prism.length"));
    }
    if (!j.contains("vertices") || !j.contains("faces")) Fail(where, "'vertices' needs 'faces' and vice versa");
    Polyhedron model;
    const json& vs = j["vertices"];
    if (!vs.is_array()) Fail(where + ".vertices", "must be an array of [x, y, z]");
    for (size_t i = 0; i < vs.size(); ++i)
      model.vertices.push_back(Vec3(vs[i], fmt::format("{}.vertices[{}]", where, i)));
    const json& fs = j["faces"];
    if (!fs.is_array()) Fail(where + ".faces", "must be an array of vertex index lists");
    for (size_t f = 0; f < fs.size(); ++f) {
      const std::string fw = fmt::format("{}.faces[{}]", where, f);
      if (!fs[f].is_array()) Fail(fw, "must be an array of vertex indices");
      std::vector<int> face;
      for (const json& idx : fs[f]) {
        if (!idx.is_number_integer()) Fail(fw, "vertex indices must be integers");
        face.push_back(idx.get<int>());
      }
      model.faces.push_back(face);
    }
    return model;
  }

  int Object(const json& j, const std::string& where, const std::vector<ApoObject>& objects) const {
    if (!j.is_string()) Fail(where, "must be an object id (string)");
    const std::string id = j.get<std::string>();
    for (size_t o = 0; o < objects.size(); ++o) {
      if (objects[o].id == id) return static_cast<int>(o);
    }
    Fail(where, fmt::format("unknown object id '{}'", id));
  }

  int Integer(const json& j, const std::string& where) const {
    if (!j.is_number_integer()) Fail(where, "must be an integer");
    return j.get<int>();
  }

  ApoInput Parse(const std::string& text) const {
    json root;
    try {
      root = json::parse(text);
    } catch (const json::parse_error& e) {
      Fail("", fmt::format("not valid JSON: {}", e.what()));
    }
    ApoInput input;
    input.source = source_;
    input.options.source = source_;
    Keys(root, "(top level)", {"settings", "objects", "operations", "description"});
    if (root.contains("settings")) Settings(root["settings"], input.options);
    if (!root.contains("objects") || !root["objects"].is_array() || root["objects"].empty()) {
      Fail("objects", "must be a non-empty array");
    }
    ApoObservation& obs = input.observation;
    for (size_t i = 0; i < root["objects"].size(); ++i) {
      const json& o = root["objects"][i];
      const std::string where = fmt::format("objects[{}]", i);
      Keys(o, where, {"id", "model", "stable", "pose"});
      ApoObject obj;
      if (!o.contains("id") || !o["id"].is_string()) Fail(where, "needs an 'id' string");
      obj.id = o["id"].get<std::string>();
      for (const ApoObject& other : obs.objects) {
        if (other.id == obj.id) Fail(where, fmt::format("duplicate id '{}'", obj.id));
      }
      if (!o.contains("model")) Fail(where, "needs a 'model'");
      obj.model = Model(o["model"], where + ".model");
      if (o.contains("stable")) {
        if (!o["stable"].is_boolean()) Fail(where + ".stable", "must be true or false");
        obj.stable = o["stable"].get<bool>();
      }
      if (obj.stable) {
        if (!o.contains("pose")) Fail(where, "a stable object needs its 'pose'");
        obj.pose = Pose(o["pose"], where + ".pose");
      } else if (o.contains("pose")) {
        Fail(where + ".pose", "only stable objects have a pose here; others get theirs from operations");
      }
      obs.objects.push_back(std::move(obj));
    }
    if (!root.contains("operations") || !root["operations"].is_array()) Fail("operations", "must be an array");
    for (size_t i = 0; i < root["operations"].size(); ++i) {
      const json& o = root["operations"][i];
      const std::string where = fmt::format("operations[{}]", i);
      Keys(o, where, {"object", "pose", "remove", "carries", "contacts", "note", "pose_noise", "pose_covariance"});
      ApoOperation op;
      if (!o.contains("object")) Fail(where, "needs the manipulated 'object'");
      op.object = Object(o["object"], where + ".object", obs.objects);
      const bool remove = o.contains("remove") && o["remove"].is_boolean() && o["remove"].get<bool>();
      if (o.contains("remove") && !o["remove"].is_boolean()) Fail(where + ".remove", "must be true or false");
      if (remove) {
        op.kind = ApoOperation::Kind::kRemove;
        if (o.contains("pose")) Fail(where, "a removal has no 'pose'");
      } else {
        if (!o.contains("pose"))
          Fail(where, "needs the observed 'pose' of the manipulated object (or \"remove\": true)");
        op.observed = Pose(o["pose"], where + ".pose");
      }
      if (o.contains("pose_noise") && o.contains("pose_covariance")) {
        Fail(where, "give 'pose_noise' or 'pose_covariance', not both");
      }
      if ((o.contains("pose_noise") || o.contains("pose_covariance")) && remove) {
        Fail(where, "a removal has no observed pose, so no pose noise");
      }
      if (o.contains("pose_noise")) op.covariance = PoseNoise(o["pose_noise"], where + ".pose_noise");
      if (o.contains("pose_covariance")) {
        op.covariance = Covariance(o["pose_covariance"], where + ".pose_covariance");
      }
      if (o.contains("carries")) {
        if (!o["carries"].is_array()) Fail(where + ".carries", "must be an array of object ids");
        for (size_t c = 0; c < o["carries"].size(); ++c) {
          op.carries.push_back(Object(o["carries"][c], fmt::format("{}.carries[{}]", where, c), obs.objects));
        }
      }
      if (o.contains("contacts")) {
        if (!o["contacts"].is_array()) Fail(where + ".contacts", "must be an array");
        std::vector<GivenContact> contacts;
        for (size_t c = 0; c < o["contacts"].size(); ++c) {
          const json& g = o["contacts"][c];
          const std::string cw = fmt::format("{}.contacts[{}]", where, c);
          Keys(g, cw, {"object", "face", "against", "against_face", "points"});
          GivenContact gc;
          if (!g.contains("object") || !g.contains("face") || !g.contains("against")) {
            Fail(cw, "needs 'object', 'face' and 'against'");
          }
          gc.object = Object(g["object"], cw + ".object", obs.objects);
          gc.face = Integer(g["face"], cw + ".face");
          gc.against = Object(g["against"], cw + ".against", obs.objects);
          if (g.contains("against_face")) gc.against_face = Integer(g["against_face"], cw + ".against_face");
          if (g.contains("points")) {
            if (!g["points"].is_array()) Fail(cw + ".points", "must be an array of [x, y, z]");
            for (size_t k = 0; k < g["points"].size(); ++k) {
              gc.points.push_back(Vec3(g["points"][k], fmt::format("{}.points[{}]", cw, k)));
            }
          } else if (!g.contains("against_face")) {
            Fail(cw, "needs 'against_face' (the contact region is the faces' overlap) or 'points'");
          }
          contacts.push_back(std::move(gc));
        }
        op.contacts = std::move(contacts);
      }
      obs.operations.push_back(std::move(op));
    }
    return input;
  }

  // A standard deviation: one number for every axis, or one per axis.
  Vector3d Stddev3(const json& j, const std::string& where) const {
    Vector3d v;
    if (j.is_number()) {
      v.setConstant(j.get<double>());
    } else {
      v = Vec3(j, where);
    }
    if (!(v.minCoeff() >= 0) || !v.allFinite()) Fail(where, "standard deviations must be finite and not negative");
    return v;
  }

  // {"t": metres, "rxyz_deg": degrees}: 1-sigma noise of a pose's perturbation observed·ΔT(q) (object frame), each
  // a number (every axis) or [x, y, z]; independent axes.
  PoseCovariance PoseNoise(const json& j, const std::string& where) const {
    if (!j.is_object()) Fail(where, "must be {\"t\": metres, \"rxyz_deg\": degrees}");
    Keys(j, where, {"t", "rxyz_deg"});
    if (!j.contains("t") || !j.contains("rxyz_deg")) Fail(where, "needs 't' and 'rxyz_deg'");
    Vector6d sd;
    sd << Stddev3(j["t"], where + ".t"), Stddev3(j["rxyz_deg"], where + ".rxyz_deg") * std::numbers::pi / 180;
    return sd.cwiseAbs2().asDiagonal();
  }

  // 6 rows of 6: covariance of (x, y, z, α, β, γ) in metres and radians; symmetric, positive semi-definite.
  PoseCovariance Covariance(const json& j, const std::string& where) const {
    if (!j.is_array() || j.size() != 6) Fail(where, "must be 6 rows of 6 numbers (x, y, z in m, α, β, γ in rad)");
    PoseCovariance c;
    for (size_t r = 0; r < 6; ++r) {
      const auto row = Numbers(j[r], fmt::format("{}[{}]", where, r), 6);
      for (size_t k = 0; k < 6; ++k) c(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(k)) = row[k];
    }
    if (!c.allFinite() ||
        (c - c.transpose()).cwiseAbs().maxCoeff() > 1e-12 * std::max(1e-30, c.cwiseAbs().maxCoeff())) {
      Fail(where, "must be symmetric");
    }
    const Eigen::SelfAdjointEigenSolver<PoseCovariance> eig(c);
    if (eig.eigenvalues().minCoeff() < -1e-12 * std::max(1e-30, eig.eigenvalues().maxCoeff())) {
      Fail(where, "must be positive semi-definite");
    }
    return c;
  }

  void Settings(const json& s, ApoOptions& options) const {
    Keys(s, "settings",
         {"mode", "contact_distance", "contact_angle_deg", "min_contact_width", "residue_threshold",
          "characteristic_length", "max_iterations", "pose_noise", "false_miss_probability", "min_contact_distance",
          "min_contact_angle_deg"});
    if (s.contains("pose_noise")) options.pose_noise = PoseNoise(s["pose_noise"], "settings.pose_noise");
    if (s.contains("false_miss_probability")) {
      const double p = Positive(s["false_miss_probability"], "settings.false_miss_probability");
      if (!(p < 0.5)) Fail("settings.false_miss_probability", "must be below 0.5");
      options.contact.false_miss_probability = p;
    }
    if (s.contains("min_contact_distance")) {
      options.contact.min_distance = Positive(s["min_contact_distance"], "settings.min_contact_distance");
    }
    if (s.contains("min_contact_angle_deg")) {
      options.contact.min_angle_deg = Positive(s["min_contact_angle_deg"], "settings.min_contact_angle_deg");
      if (options.contact.min_angle_deg >= 90) Fail("settings.min_contact_angle_deg", "must be below 90");
    }
    if (s.contains("mode")) {
      const std::string mode = s["mode"].is_string() ? s["mode"].get<std::string>() : "";
      if (mode == "iterative") {
        options.mode = ApoMode::kIterative;
      } else if (mode == "all-at-once") {
        options.mode = ApoMode::kAllAtOnce;
      } else {
        Fail("settings.mode", "must be \"iterative\" or \"all-at-once\"");
      }
    }
    if (s.contains("contact_distance")) {
      options.contact.distance = Positive(s["contact_distance"], "settings.contact_distance");
    }
    if (s.contains("contact_angle_deg")) {
      options.contact.angle_deg = Positive(s["contact_angle_deg"], "settings.contact_angle_deg");
      if (options.contact.angle_deg >= 90) Fail("settings.contact_angle_deg", "must be below 90");
    }
    if (s.contains("min_contact_width")) {
      options.contact.min_width = Positive(s["min_contact_width"], "settings.min_contact_width");
    }
    if (s.contains("residue_threshold")) {
      options.residue_threshold = Positive(s["residue_threshold"], "settings.residue_threshold");
      options.solver.residue_tolerance = std::min(options.solver.residue_tolerance, options.residue_threshold / 10);
    }
    if (s.contains("characteristic_length")) {
      options.solver.characteristic_length = Positive(s["characteristic_length"], "settings.characteristic_length");
    }
    if (s.contains("max_iterations")) {
      options.solver.max_iterations = Integer(s["max_iterations"], "settings.max_iterations");
      if (options.solver.max_iterations < 1) Fail("settings.max_iterations", "must be at least 1");
    }
  }

 private:
  std::string source_;
};

json PoseJson(const Matrix4d& m) {
  const Vector6d q = DeltaParameters(m);
  return {{"t", {m(0, 3), m(1, 3), m(2, 3)}}, {"rxyz_deg", {q[3] / kDeg, q[4] / kDeg, q[5] / kDeg}}};
}

std::string PoseText(const Matrix4d& m) {
  const Vector6d q = DeltaParameters(m);
  return fmt::format("t ({:.5f}, {:.5f}, {:.5f}) m, rxyz ({:.3f}, {:.3f}, {:.3f}) deg", m(0, 3), m(1, 3), m(2, 3),
                     q[3] / kDeg, q[4] / kDeg, q[5] / kDeg);
}

std::string CorrectionText(const Matrix4d& observed, const Matrix4d& corrected) {
  const Vector6d q = DeltaParameters(RigidInverse(observed) * corrected);
  return fmt::format("Δt ({:+.4f}, {:+.4f}, {:+.4f}) mm, Δrxyz ({:+.4f}, {:+.4f}, {:+.4f}) deg (object frame)",
                     q[0] * 1e3, q[1] * 1e3, q[2] * 1e3, q[3] / kDeg, q[4] / kDeg, q[5] / kDeg);
}

class Writer {
 public:
  Writer(const ApoInput& input, const ApoResult& result) : in_(input), res_(result) {}

  const std::string& Id(int o) const { return in_.observation.objects[o].id; }

  std::string ParamName(int p) const {
    if (p >= res_.stable_count) return fmt::format("T{}", p - res_.stable_count + 1);
    int seen = 0;
    for (const ApoObject& o : in_.observation.objects) {
      if (o.stable && seen++ == p) return fmt::format("T0({})", o.id);
    }
    return "?";
  }

  std::string Chain(const Odl& odl) const {
    std::string s;
    for (const OdlFactor& f : odl)
      s += fmt::format("{}{}{}", s.empty() ? "" : " ", ParamName(f.param), f.inverse ? "^-1" : "");
    return s;
  }

  std::string OpList(const std::vector<int>& ops) const {
    std::string s;
    for (int op : ops) s += fmt::format("{}T{}", s.empty() ? "" : ", ", op + 1);
    return "{" + s + "}";
  }

  std::string RelList(const std::vector<int>& rels) const {
    std::string s;
    for (int r : rels) s += fmt::format("{}R{}", s.empty() ? "" : ", ", r + 1);
    return s.empty() ? "none" : s;
  }

  std::string ActionText(const RobotAction& a) const {
    std::string carry;
    for (int c : a.carries) carry += fmt::format("{}{}", carry.empty() ? " carrying " : ", ", Id(c));
    const std::string mark = a.corrected ? "'" : "";
    switch (a.kind) {
      case RobotAction::Kind::kPlace:
        return fmt::format("step {}: place {}{} at T{}{} ({})", a.operation + 1, Id(a.object), carry, a.operation + 1,
                           mark, PoseText(*a.pose));
      case RobotAction::Kind::kRemove:
        return fmt::format("step {}: remove {}{} from the scene", a.operation + 1, Id(a.object), carry);
      case RobotAction::Kind::kUndoPlace:
        if (!a.pose) return fmt::format("undo step {}: take {}{} away", a.operation + 1, Id(a.object), carry);
        return fmt::format("undo step {}: move {}{} back to {}", a.operation + 1, Id(a.object), carry,
                           PoseText(*a.pose));
      case RobotAction::Kind::kUndoRemove:
        return fmt::format("undo step {}: put {}{} back at {}", a.operation + 1, Id(a.object), carry,
                           PoseText(*a.pose));
    }
    return "?";
  }

  json Action(const RobotAction& a) const {
    static const char* kinds[] = {"place", "remove", "undo_place", "undo_remove"};
    json carries = json::array();
    for (int c : a.carries) carries.push_back(Id(c));
    return {{"action", kinds[static_cast<int>(a.kind)]},
            {"operation", a.operation + 1},
            {"object", Id(a.object)},
            {"carries", carries},
            {"pose", a.pose ? PoseJson(*a.pose) : json(nullptr)},
            {"corrected", a.corrected},
            {"text", ActionText(a)}};
  }

  std::string Json() const {
    json out;
    out["mode"] = res_.mode == ApoMode::kIterative ? "iterative" : "all-at-once";
    out["residue_threshold_m"] = in_.options.residue_threshold;
    json ops = json::array();
    for (size_t i = 0; i < in_.observation.operations.size(); ++i) {
      const ApoOperation& op = in_.observation.operations[i];
      const int p = OperationParam(res_, static_cast<int>(i));
      json carries = json::array();
      for (int c : op.carries) carries.push_back(Id(c));
      json j = {{"index", i + 1},
                {"name", ParamName(p)},
                {"object", Id(op.object)},
                {"carries", carries},
                {"kind", op.kind == ApoOperation::Kind::kPlace ? "place" : "remove"},
                {"changed", res_.changed[i]}};
      if (op.kind == ApoOperation::Kind::kPlace) {
        j["observed"] = PoseJson(res_.observed[p]);
        j["corrected"] = PoseJson(res_.corrected[p]);
        const Vector6d q = DeltaParameters(RigidInverse(res_.observed[p]) * res_.corrected[p]);
        j["correction"] = {{"t", {q[0], q[1], q[2]}}, {"rxyz_deg", {q[3] / kDeg, q[4] / kDeg, q[5] / kDeg}}};
      }
      ops.push_back(j);
    }
    out["operations"] = ops;
    json rels = json::array();
    for (size_t r = 0; r < res_.relations.size(); ++r) {
      const Relation& rel = res_.relations[r];
      json faces = json::array();
      for (const FacePatch& p : rel.patches) {
        json pts = json::array();
        for (const Vector3d& v : p.points) pts.push_back({v.x(), v.y(), v.z()});
        faces.push_back({{"face", p.face}, {"against_face", p.against_face}, {"points", pts}});
      }
      rels.push_back({{"id", fmt::format("R{}", r + 1)},
                      {"formed_by", rel.formed_by + 1},
                      {"object", Id(rel.face_object)},
                      {"against", Id(rel.vertex_object)},
                      {"chain", Chain(rel.chain)},
                      {"given", rel.given},
                      {"disappeared_by", rel.disappeared_by >= 0 ? json(rel.disappeared_by + 1) : json(nullptr)},
                      {"observed_residue_m", rel.observed_residue},
                      {"corrected_residue_m", rel.corrected_residue},
                      {"faces", faces}});
    }
    out["relations"] = rels;
    json steps = json::array();
    for (const ApoStep& s : res_.steps) {
      auto rel_ids = [](const std::vector<int>& v) {
        json a = json::array();
        for (int r : v) a.push_back(fmt::format("R{}", r + 1));
        return a;
      };
      json cands = json::array();
      for (int c : s.candidates) cands.push_back(c + 1);
      json trials = json::array();
      for (const ApoTrial& t : s.trials) {
        json tops = json::array();
        for (int o : t.operations) tops.push_back(o + 1);
        trials.push_back(
            {{"operations", tops},
             {"success", t.success},
             {"status", ToString(t.report.status)},
             {"max_residue_m", t.max_relation_residue},
             {"worst_relation", t.worst_relation >= 0 ? json(fmt::format("R{}", t.worst_relation + 1)) : json(nullptr)},
             {"search_iterations", t.report.search_iterations},
             {"newton_iterations", t.report.newton_iterations},
             {"equations", t.report.equations},
             {"unknowns", t.report.unknowns},
             {"rank", t.report.rank},
             {"null_space_component", t.report.null_space_component},
             {"message", t.report.message}});
      }
      json robot = json::array();
      for (const RobotAction& a : s.robot) robot.push_back(Action(a));
      json corrected = json::array();
      if (s.accepted >= 0) {
        for (int o : s.trials[s.accepted].operations) corrected.push_back(o + 1);
      }
      steps.push_back({{"operation", s.operation >= 0 ? json(s.operation + 1) : json(nullptr)},
                       {"new_relations", rel_ids(s.new_relations)},
                       {"disappeared_relations", rel_ids(s.disappeared_relations)},
                       {"selected_relations", rel_ids(s.selected)},
                       {"candidates", cands},
                       {"trials", trials},
                       {"corrected_operations", corrected},
                       {"robot", robot}});
    }
    out["steps"] = steps;
    json plan = json::array();
    for (const RobotAction& a : res_.plan) plan.push_back(Action(a));
    out["plan"] = plan;
    json finals = json::object();
    const auto poses = FinalPoses(in_.observation, res_, true);
    for (size_t o = 0; o < poses.size(); ++o) {
      if (poses[o]) finals[Id(static_cast<int>(o))] = PoseJson(*poses[o]);
    }
    out["final_poses"] = finals;
    return out.dump(2) + "\n";
  }

  std::string Text() const {
    std::ostringstream out;
    const bool iterative = res_.mode == ApoMode::kIterative;
    out << fmt::format("Assembly plan from observation: {} operations, {} relations, {} mode, threshold {:.2g} m\n",
                       in_.observation.operations.size(), res_.relations.size(),
                       iterative ? "iterative" : "all-at-once", in_.options.residue_threshold);
    out << "\nRelations (face side -> vertex side, ODLs when formed):\n";
    for (size_t r = 0; r < res_.relations.size(); ++r) {
      const Relation& rel = res_.relations[r];
      out << fmt::format(
          "  R{}: {} -> {} by T{}, {} face(s), e = n {} v, residue {:.3g} m observed, {:.2g} m "
          "corrected{}{}\n",
          r + 1, Id(rel.face_object), Id(rel.vertex_object), rel.formed_by + 1, rel.patches.size(), Chain(rel.chain),
          rel.observed_residue, rel.corrected_residue, rel.given ? ", given" : "",
          rel.disappeared_by >= 0 ? fmt::format(", disappeared at T{}", rel.disappeared_by + 1) : "");
    }
    for (const ApoStep& s : res_.steps) {
      if (s.operation >= 0) {
        const ApoOperation& op = in_.observation.operations[s.operation];
        out << fmt::format("\nStep {}: {} {}", s.operation + 1,
                           op.kind == ApoOperation::Kind::kPlace ? "place" : "remove", Id(op.object));
        for (size_t c = 0; c < op.carries.size(); ++c) out << (c == 0 ? " carrying " : ", ") << Id(op.carries[c]);
        out << fmt::format("; new relations {}; disappeared {}\n", RelList(s.new_relations),
                           RelList(s.disappeared_relations));
      } else {
        out << "\nAll operations at once:\n";
      }
      if (s.selected.empty()) {
        out << "  every relation holds within the threshold: nothing to correct\n";
      } else {
        out << "  residues above the threshold: ";
        for (size_t k = 0; k < s.selected.size(); ++k) {
          out << fmt::format("{}R{}", k ? ", " : "", s.selected[k] + 1);
        }
        out << fmt::format("\n  candidate operations (most recent first): {}\n", OpList(s.candidates));
        for (const ApoTrial& t : s.trials) {
          out << fmt::format("  try {}: {}", OpList(t.operations), t.success ? "succeeds" : "fails");
          if (t.success) {
            out << fmt::format(
                " ({} + {} iterations, max residue {:.2g} m, rank {} of {}, null-space component {:.1g})\n",
                t.report.search_iterations, t.report.newton_iterations, t.max_relation_residue, t.report.rank,
                t.report.unknowns, t.report.null_space_component);
          } else {
            out << fmt::format(" ({}; worst R{} at {:.3g} m)\n", t.report.message, t.worst_relation + 1,
                               t.max_relation_residue);
          }
        }
        if (s.accepted >= 0) {
          for (int o : s.trials[s.accepted].operations) {
            const int p = OperationParam(res_, o);
            const Matrix4d& before = s.operation >= 0 ? Before(s, p) : res_.observed[p];
            out << fmt::format("  T{} ({}): {}\n", o + 1, Id(in_.observation.operations[o].object),
                               CorrectionText(before, s.operation >= 0 ? After(s, p) : res_.corrected[p]));
          }
        }
      }
      out << "  robot:\n";
      for (const RobotAction& a : s.robot) out << "    " << ActionText(a) << "\n";
    }
    out << "\nOperations whose motion parameters change: ";
    std::string changed;
    for (size_t i = 0; i < res_.changed.size(); ++i) {
      if (res_.changed[i]) changed += fmt::format("{}T{}", changed.empty() ? "" : ", ", i + 1);
    }
    out << (changed.empty() ? "none" : changed) << "\n";
    out << "Assembly plan (from scratch, corrected parameters):\n";
    for (const RobotAction& a : res_.plan) out << "  " << ActionText(a) << "\n";
    return out.str();
  }

 private:
  // The parameter before and after an iterative step's accepted correction.
  Matrix4d Before(const ApoStep& s, int p) const {
    // Corrections accumulate: the value before this step is the value after the previous accepted step touching p.
    Matrix4d value = res_.observed[p];
    for (const ApoStep& earlier : res_.steps) {
      if (&earlier == &s) break;
      if (earlier.accepted >= 0) value = earlier.trials[earlier.accepted].report.corrected[p];
    }
    return value;
  }
  Matrix4d After(const ApoStep& s, int p) const { return s.trials[s.accepted].report.corrected[p]; }

  const ApoInput& in_;
  const ApoResult& res_;
};

}  // namespace

ApoInput ParseApoObservation(const std::string& text, const std::string& source) { return Parser(source).Parse(text); }

ApoInput LoadApoObservation(const std::string& path) {
  std::ifstream file(path);
  if (!file) throw InputError(path, "", "cannot be read");
  std::stringstream buffer;
  buffer << file.rdbuf();
  return ParseApoObservation(buffer.str(), path);
}

std::string ApoResultJson(const ApoInput& input, const ApoResult& result) { return Writer(input, result).Json(); }

std::string ApoResultText(const ApoInput& input, const ApoResult& result) { return Writer(input, result).Text(); }

}  // namespace visco::face_contact

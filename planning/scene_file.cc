#include "planning/scene_file.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "common/error.h"
#include "common/scene_digest.h"
#include "planning/cspace.h"

namespace visco::planning {

// Defined in the generated embedded_scenes.cc (data/scenes/slot.json compiled in).
extern const char* const kEmbeddedSlotScene;

namespace {

using Json = nlohmann::json;
constexpr double kPi = 3.14159265358979323846;
constexpr double kDegree = kPi / 180.0;

// Reads one scene file; every error names the source and the object.
class Reader {
 public:
  explicit Reader(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void Fail(const std::string& object, const std::string& what) const {
    throw InputError(source_, object, what);
  }

  void CheckKeys(const Json& j, const std::string& object, const std::set<std::string>& required,
                 const std::set<std::string>& optional) const {
    if (!j.is_object()) Fail(object, "expected a JSON object, got " + std::string(j.type_name()));
    for (const auto& [key, value] : j.items()) {
      if (!required.count(key) && !optional.count(key)) {
        std::string allowed;
        for (const auto* set : {&required, &optional}) {
          for (const std::string& k : *set) allowed += (allowed.empty() ? "" : ", ") + k;
        }
        Fail(Join(object, key), "unknown field (allowed: " + allowed + ")");
      }
    }
    for (const std::string& key : required) {
      if (!j.contains(key)) Fail(object.empty() ? key : Join(object, key), "missing field");
    }
  }

  double Number(const Json& j, const std::string& object) const {
    if (!j.is_number()) Fail(object, "expected a number, got " + std::string(j.type_name()));
    const double value = j.get<double>();
    if (!std::isfinite(value)) Fail(object, "not a finite number");
    return value;
  }

  Point ReadPoint(const Json& j, const std::string& object) const {
    if (!j.is_array() || j.size() != 2) Fail(object, "expected a point [x, y]");
    return {Number(j[0], object + "[0]"), Number(j[1], object + "[1]")};
  }

  ScenePolygon ReadPolygon(const Json& j, const std::string& object) const {
    if (!j.is_array()) Fail(object, "expected an array of points [[x, y], ...]");
    std::vector<Point> points;
    for (std::size_t i = 0; i < j.size(); ++i) points.push_back(ReadPoint(j[i], fmt::format("{}[{}]", object, i)));
    // Drop repeated consecutive vertices (cyclically), remembering file positions.
    ScenePolygon result;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (!result.polygon.vertices.empty() && result.polygon.vertices.back() == points[i]) continue;
      result.polygon.vertices.push_back(points[i]);
      result.source_index.push_back(static_cast<int>(i));
    }
    while (result.polygon.size() > 1 && result.polygon.vertices.back() == result.polygon.vertices.front()) {
      result.polygon.vertices.pop_back();
      result.source_index.pop_back();
    }
    std::set<std::pair<double, double>> distinct;
    for (const Point& p : result.polygon.vertices) distinct.insert({p.x(), p.y()});
    if (distinct.size() < 3) {
      Fail(object, fmt::format("a polygon needs at least 3 distinct vertices, got {}", distinct.size()));
    }
    if (!IsSimple(result.polygon)) {
      Fail(object, "the polygon is not simple (it intersects itself, repeats a vertex or has zero area)");
    }
    // The file edge between consecutive kept vertices: the first non-degenerate one after the first's file position.
    const std::size_t n_file = points.size();
    for (const int first : result.source_index) {
      std::size_t k = static_cast<std::size_t>(first);
      while (points[k] == points[(k + 1) % n_file]) k = (k + 1) % n_file;
      result.source_edge.push_back(static_cast<int>(k));
    }
    if (PolygonOrientation(result.polygon) < 0) {
      std::reverse(result.polygon.vertices.begin(), result.polygon.vertices.end());
      std::reverse(result.source_index.begin(), result.source_index.end());
      // Edge i now joins the old vertices n-1-i and n-2-i: the old edge n-2-i.
      std::reverse(result.source_edge.begin(), result.source_edge.end());
      std::rotate(result.source_edge.begin(), result.source_edge.begin() + 1, result.source_edge.end());
    }
    return result;
  }

  // An angle in degrees within [0, 90), returned in radians.
  double ReadConeAngle(const Json& j, const std::string& object) const {
    const double degrees = Number(j, object);
    if (degrees < 0 || degrees >= 90) Fail(object, fmt::format("{} degrees is outside [0, 90)", degrees));
    return degrees * kDegree;
  }

  static std::string Join(const std::string& object, const std::string& key) {
    return object.empty() ? key : object + "." + key;
  }

  const std::string& source() const { return source_; }

 private:
  std::string source_;
};

PinholeCamera ReadPinhole(const Reader& r, const Json& j, const std::string& object) {
  r.CheckKeys(j, object, {"px", "py", "u0", "v0", "width", "height", "wMc"}, {});
  PinholeCamera camera;
  camera.px = r.Number(j["px"], object + ".px");
  camera.py = r.Number(j["py"], object + ".py");
  camera.u0 = r.Number(j["u0"], object + ".u0");
  camera.v0 = r.Number(j["v0"], object + ".v0");
  if (camera.px <= 0 || camera.py <= 0) r.Fail(object, "focal lengths px and py must be positive");
  for (const char* key : {"width", "height"}) {
    const double value = r.Number(j[key], object + "." + key);
    if (value < 1 || value != std::floor(value) || value > 1e6) {
      r.Fail(object + "." + key, "expected a positive whole number of pixels");
    }
    (std::string(key) == "width" ? camera.width : camera.height) = static_cast<int>(value);
  }
  const Json& m = j["wMc"];
  const std::string m_object = object + ".wMc";
  if (!m.is_array() || m.size() != 4) r.Fail(m_object, "expected a 4x4 homogeneous matrix (4 rows of 4 numbers)");
  for (int row = 0; row < 4; ++row) {
    if (!m[row].is_array() || m[row].size() != 4) r.Fail(m_object, "expected 4 rows of 4 numbers");
    for (int col = 0; col < 4; ++col) {
      camera.wMc(row, col) = r.Number(m[row][col], fmt::format("{}[{}][{}]", m_object, row, col));
    }
  }
  const Eigen::Matrix3d rotation = camera.wMc.topLeftCorner<3, 3>();
  if ((rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 ||
      rotation.determinant() < 0) {
    r.Fail(m_object, "the upper-left 3x3 block is not a rotation (orthonormal, determinant +1, within 1e-6)");
  }
  if (camera.wMc.row(3) != Eigen::RowVector4d(0, 0, 0, 1)) r.Fail(m_object, "the last row must be [0, 0, 0, 1]");
  return camera;
}

Camera ReadCamera(const Reader& r, const Json& j) {
  const std::string object = "camera";
  if (j.is_object() && j.contains("pinhole")) {
    r.CheckKeys(j, object, {"pinhole"}, {});
    return DerivePlanarCamera(ReadPinhole(r, j["pinhole"], "camera.pinhole"), r.source(), "camera.pinhole");
  }
  r.CheckKeys(j, object, {"center", "fov_deg"}, {"height"});
  const Point center = r.ReadPoint(j["center"], "camera.center");
  std::optional<double> height;
  if (j.contains("height")) {
    height = r.Number(j["height"], "camera.height");
    if (!(*height > 0)) r.Fail("camera.height", fmt::format("{} m: the camera must be above the plane (> 0)", *height));
  }
  const Json& fov = j["fov_deg"];
  if (!fov.is_array() || fov.size() != 2) r.Fail("camera.fov_deg", "expected two directions [first, second]");
  const double first = r.Number(fov[0], "camera.fov_deg[0]");
  const double second = r.Number(fov[1], "camera.fov_deg[1]");
  const double raw = second - first;
  double span = std::fmod(raw, 360.0);
  if (span < 0) span += 360.0;
  if (raw == 0) r.Fail("camera.fov_deg", "the field of view is empty (both directions are equal)");
  if (span == 0) r.Fail("camera.fov_deg", "the field of view is a full turn; it must be narrower than 180 degrees");
  if (span >= 180) {
    r.Fail("camera.fov_deg",
           fmt::format("the field of view is {} degrees wide (counter-clockwise from the first direction to the "
                       "second); it must be narrower than 180 degrees",
                       span));
  }
  Camera camera = MakePlanarCamera(center, first, span);
  camera.height = height;
  return camera;
}

std::string ObstacleName(std::size_t i, const std::string& id) {
  return id.empty() ? fmt::format("obstacles[{}]", i) : fmt::format("obstacles[{}] ({})", i, id);
}

Scene Parse(const Reader& r, const Json& j, const std::string& default_name) {
  r.CheckKeys(j, "", {"bounds", "robot", "obstacles", "goal", "uncertainty", "friction_cone_deg"},
              {"name", "start", "camera"});
  Scene scene;
  scene.source = r.source();
  if (j.contains("name")) {
    if (!j["name"].is_string()) r.Fail("name", "expected a string");
    scene.name = j["name"].get<std::string>();
  } else {
    scene.name = default_name;
  }

  r.CheckKeys(j["bounds"], "bounds", {"min", "max"}, {});
  scene.bounds.min = r.ReadPoint(j["bounds"]["min"], "bounds.min");
  scene.bounds.max = r.ReadPoint(j["bounds"]["max"], "bounds.max");
  if (!(scene.bounds.min.x() < scene.bounds.max.x() && scene.bounds.min.y() < scene.bounds.max.y())) {
    r.Fail("bounds", "min must be smaller than max in x and in y");
  }

  r.CheckKeys(j["robot"], "robot", {"polygon"}, {});
  scene.robot = r.ReadPolygon(j["robot"]["polygon"], "robot.polygon");

  const Json& obstacles = j["obstacles"];
  if (!obstacles.is_array()) r.Fail("obstacles", "expected an array of obstacles");
  std::map<std::string, std::size_t> ids;
  for (std::size_t i = 0; i < obstacles.size(); ++i) {
    const Json& o = obstacles[i];
    std::string name = ObstacleName(i, "");
    if (o.is_object() && o.contains("id")) {
      if (!o["id"].is_string() || o["id"].get<std::string>().empty()) {
        r.Fail(name + ".id", "expected a non-empty string");
      }
      name = ObstacleName(i, o["id"].get<std::string>());
    }
    r.CheckKeys(o, name, {"id", "polygon"}, {"height"});
    Obstacle obstacle;
    obstacle.id = o["id"].get<std::string>();
    if (o.contains("height")) {
      obstacle.height = r.Number(o["height"], name + ".height");
      if (!(*obstacle.height > 0)) {
        r.Fail(name + ".height", fmt::format("{} m: a prism's height must be positive", *obstacle.height));
      }
    }
    if (!ids.emplace(obstacle.id, i).second) {
      r.Fail(name + ".id", fmt::format("duplicate id (also obstacles[{}])", ids[obstacle.id]));
    }
    obstacle.shape = r.ReadPolygon(o["polygon"], name + ".polygon");
    scene.obstacles.push_back(std::move(obstacle));
  }
  // Obstacles may touch and overlap (scenes are built from parts, e.g. a floor and walls): the obstacle region is
  // their union (docs/semantics.md).

  r.CheckKeys(j["goal"], "goal", {"polygon"}, {});
  scene.goal = r.ReadPolygon(j["goal"]["polygon"], "goal.polygon");
  if (j.contains("start")) {
    r.CheckKeys(j["start"], "start", {"polygon"}, {});
    scene.start = r.ReadPolygon(j["start"]["polygon"], "start.polygon");
  }

  if (j.contains("camera")) {
    scene.camera = ReadCamera(r, j["camera"]);
    for (std::size_t i = 0; i < scene.obstacles.size(); ++i) {
      if (Locate(scene.obstacles[i].shape.polygon, scene.camera->center) == Location::kInside) {
        r.Fail("camera", fmt::format("the camera centre ({}, {}) lies inside {}", scene.camera->center.x(),
                                     scene.camera->center.y(), ObstacleName(i, scene.obstacles[i].id)));
      }
    }
  }

  r.CheckKeys(j["uncertainty"], "uncertainty", {"velocity_cone_deg", "position"}, {"vc_tracking"});
  scene.uncertainty.velocity_cone_rad =
      r.ReadConeAngle(j["uncertainty"]["velocity_cone_deg"], "uncertainty.velocity_cone_deg");
  scene.uncertainty.position = r.Number(j["uncertainty"]["position"], "uncertainty.position");
  if (scene.uncertainty.position < 0) r.Fail("uncertainty.position", "must not be negative");
  if (j["uncertainty"].contains("vc_tracking")) {
    scene.uncertainty.vc_tracking = r.Number(j["uncertainty"]["vc_tracking"], "uncertainty.vc_tracking");
    if (scene.uncertainty.vc_tracking < 0) r.Fail("uncertainty.vc_tracking", "must not be negative");
  }
  scene.friction_cone_rad = r.ReadConeAngle(j["friction_cone_deg"], "friction_cone_deg");

  const CSpace cspace(scene);
  if (!cspace.HasFreePart(scene.goal.polygon)) r.Fail("goal", "the goal region lies entirely inside the C-obstacles");
  if (scene.start && !cspace.HasFreePart(scene.start->polygon)) {
    r.Fail("start", "the start region lies entirely inside the C-obstacles");
  }
  return scene;
}

std::string StemOf(const std::string& path) {
  std::string name = path.substr(path.find_last_of('/') == std::string::npos ? 0 : path.find_last_of('/') + 1);
  return name.substr(0, name.find('.'));
}

}  // namespace

Scene ParseScene(std::string_view json_text, const std::string& source) {
  const Reader reader(source);
  Json j;
  try {
    j = Json::parse(json_text.begin(), json_text.end());
  } catch (const Json::exception& e) {
    // Also catches numbers that overflow a double (JSON has no literal for a non-finite number).
    reader.Fail("", fmt::format("invalid JSON: {}", e.what()));
  }
  const std::string digest = SceneDigest(j.dump());  // before Parse, whose operator[] may add null members
  Scene scene = Parse(reader, j, StemOf(source));
  scene.digest = digest;
  return scene;
}

Scene LoadScene(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "", "cannot open the scene file");
  std::stringstream text;
  text << in.rdbuf();
  return ParseScene(text.str(), path);
}

std::string_view DefaultSceneJson() { return kEmbeddedSlotScene; }

Scene DefaultScene() { return ParseScene(DefaultSceneJson(), "<embedded data/scenes/slot.json>"); }

}  // namespace visco::planning

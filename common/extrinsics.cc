#include "common/extrinsics.h"

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "common/error.h"

namespace visco {

Eigen::Matrix3d RotationFromRpy(double roll, double pitch, double yaw) {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

namespace {

// `stddev.<key>`: a number or [x, y, z], each >= 0 and finite, scaled by `unit`; absent: 0.
Eigen::Vector3d StddevTriple(const std::string& path, const nlohmann::json& sd, const std::string& key, double unit) {
  const std::string field = "wMc.stddev." + key;
  const std::string what = "must be a number >= 0 or an array of 3 numbers >= 0 (per world axis)";
  Eigen::Vector3d out = Eigen::Vector3d::Zero();
  if (!sd.contains(key)) return out;
  const auto& v = sd[key];
  if (v.is_number()) {
    out.setConstant(v.get<double>());
  } else if (v.is_array() && v.size() == 3) {
    for (int i = 0; i < 3; ++i) {
      if (!v[i].is_number()) throw InputError(path, field, what);
      out[i] = v[i].get<double>();
    }
  } else {
    throw InputError(path, field, what);
  }
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(out[i]) || out[i] < 0) throw InputError(path, field, what + ", not " + v.dump());
  }
  return out * unit;
}

}  // namespace

Eigen::Isometry3d LoadExtrinsics(const std::string& path) { return LoadExtrinsicsWithUncertainty(path).wMc; }

Extrinsics LoadExtrinsicsWithUncertainty(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "", "extrinsics file does not exist or cannot be read");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path, "", std::string("not valid JSON: ") + e.what());
  }
  if (!j.is_object() || !j.contains("wMc") || !j["wMc"].is_object()) {
    throw InputError(path, "wMc", "missing (expected {\"wMc\": {\"t\": [x, y, z], \"R\": [[...]x3]}})");
  }
  const auto& m = j["wMc"];
  for (auto it = m.begin(); it != m.end(); ++it) {
    if (it.key() != "t" && it.key() != "R" && it.key() != "rpy_deg" && it.key() != "stddev") {
      throw InputError(path, "wMc." + it.key(), "unknown field");
    }
  }
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (it.key() != "wMc" && it.key() != "camera") throw InputError(path, it.key(), "unknown field");
  }
  Eigen::Isometry3d wMc = Eigen::Isometry3d::Identity();
  if (!m.contains("t") || !m["t"].is_array() || m["t"].size() != 3) {
    throw InputError(path, "wMc.t", "must be an array of 3 numbers (metres)");
  }
  for (int i = 0; i < 3; ++i) {
    if (!m["t"][i].is_number()) throw InputError(path, "wMc.t", "must be an array of 3 numbers (metres)");
    wMc.translation()[i] = m["t"][i].get<double>();
  }
  if (m.contains("R") == m.contains("rpy_deg")) {
    throw InputError(path, "wMc", "give exactly one of \"R\" (3x3 rotation) and \"rpy_deg\"");
  }
  Eigen::Matrix3d r;
  if (m.contains("R")) {
    const auto& jr = m["R"];
    if (!jr.is_array() || jr.size() != 3) throw InputError(path, "wMc.R", "must be a 3x3 array");
    for (int i = 0; i < 3; ++i) {
      if (!jr[i].is_array() || jr[i].size() != 3) throw InputError(path, "wMc.R", "must be a 3x3 array");
      for (int k = 0; k < 3; ++k) {
        if (!jr[i][k].is_number()) throw InputError(path, "wMc.R", "must hold numbers");
        r(i, k) = jr[i][k].get<double>();
      }
    }
    if ((r * r.transpose() - Eigen::Matrix3d::Identity()).norm() > 1e-6 || std::abs(r.determinant() - 1) > 1e-6) {
      throw InputError(path, "wMc.R", "is not a rotation matrix (orthonormal with determinant +1, within 1e-6)");
    }
  } else {
    const auto& a = m["rpy_deg"];
    if (!a.is_array() || a.size() != 3 || !a[0].is_number() || !a[1].is_number() || !a[2].is_number()) {
      throw InputError(path, "wMc.rpy_deg", "must be an array of 3 angles in degrees");
    }
    const double k = M_PI / 180;
    r = RotationFromRpy(a[0].get<double>() * k, a[1].get<double>() * k, a[2].get<double>() * k);
  }
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(wMc.translation()[i])) throw InputError(path, "wMc.t", "is not finite");
  }
  wMc.linear() = r;
  Extrinsics out;
  out.wMc = wMc;
  if (m.contains("stddev")) {
    const auto& sd = m["stddev"];
    if (!sd.is_object()) {
      throw InputError(path, "wMc.stddev", "must be an object {\"position_m\": ..., \"rotation_deg\": ...}");
    }
    for (auto it = sd.begin(); it != sd.end(); ++it) {
      if (it.key() != "position_m" && it.key() != "rotation_deg") {
        throw InputError(path, "wMc.stddev." + it.key(), "unknown field");
      }
    }
    const Eigen::Vector3d rot = StddevTriple(path, sd, "rotation_deg", M_PI / 180);
    const Eigen::Vector3d pos = StddevTriple(path, sd, "position_m", 1);
    out.covariance.diagonal() << rot.cwiseAbs2(), pos.cwiseAbs2();
  }
  return out;
}

}  // namespace visco

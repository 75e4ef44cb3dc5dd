#include "common/robot_frame.h"

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "common/error.h"

namespace visco {
namespace {

Eigen::Matrix2d Rotation(double theta) {
  Eigen::Matrix2d r;
  r << std::cos(theta), -std::sin(theta), std::sin(theta), std::cos(theta);
  return r;
}

// Umeyama's least-squares similarity in 2-D, closed form: with the points centred (a from x, b from y), the rotation
// angle is atan2(sum a x b, sum a . b) and the scale sqrt((sum a . b)^2 + (sum a x b)^2) / sum |a|^2.
// (Eigen::umeyama does the same through an SVD; GCC 12 warns inside its vectorised copies.)
struct Similarity {
  double theta = 0, scale = 1;
  Eigen::Vector2d t = Eigen::Vector2d::Zero();
  double ssr = 0;  // sum of squared residuals
};

Similarity FitSimilarity(const Eigen::Matrix2Xd& x, const Eigen::Matrix2Xd& y, bool with_scale) {
  const Eigen::Vector2d mx = x.rowwise().mean(), my = y.rowwise().mean();
  double dot = 0, cross = 0, norm = 0;
  for (Eigen::Index i = 0; i < x.cols(); ++i) {
    const Eigen::Vector2d a = x.col(i) - mx, b = y.col(i) - my;
    dot += a.dot(b);
    cross += a.x() * b.y() - a.y() * b.x();
    norm += a.squaredNorm();
  }
  Similarity s;
  s.theta = std::atan2(cross, dot);
  s.scale = with_scale ? std::hypot(dot, cross) / norm : 1.0;
  const Eigen::Matrix2d r = Rotation(s.theta);
  s.t = my - s.scale * r * mx;
  for (Eigen::Index i = 0; i < x.cols(); ++i) s.ssr += (y.col(i) - (s.scale * r * x.col(i) + s.t)).squaredNorm();
  return s;
}

// RMS distance of points from their centroid.
double Spread(const Eigen::Matrix2Xd& p) {
  if (p.cols() == 0) return 0;
  const Eigen::Vector2d c = p.rowwise().mean();
  return std::sqrt((p.colwise() - c).squaredNorm() / static_cast<double>(p.cols()));
}

Eigen::Vector2d ReadPoint(const std::string& path, const nlohmann::json& v, const std::string& field) {
  if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number()) {
    throw InputError(path, field, "must be [x, y] (metres)");
  }
  const Eigen::Vector2d p(v[0].get<double>(), v[1].get<double>());
  if (!p.allFinite()) throw InputError(path, field, "must be finite");
  return p;
}

}  // namespace

Eigen::Vector2d RobotFrame::ToWorld(const Eigen::Vector2d& p_r) const { return scale * Rotation(theta) * p_r + t; }

RobotFrame FitRobotFrame(const std::vector<FramePoint>& points, bool with_scale, const std::string& source) {
  const int k = static_cast<int>(points.size());
  Eigen::Matrix2Xd x(2, k), y(2, k);
  for (int i = 0; i < k; ++i) {
    x.col(i) = points[i].commanded;
    y.col(i) = points[i].observed;
  }
  if (!x.allFinite() || !y.allFinite()) throw InputError(source, "points", "a position is not finite");
  // 1 micrometre: far below any robot's repeatability, far above rounding.
  constexpr double kDistinct = 1e-6;
  if (k < 2 || Spread(x) < kDistinct) {
    throw InputError(source, "points",
                     "the commanded positions do not determine the robot frame: give at least 2 distinct positions "
                     "(3 or more to check the fit), got " +
                         std::to_string(k) + (k >= 2 ? " that all coincide" : ""));
  }
  if (Spread(y) < kDistinct) {
    throw InputError(source, "points",
                     "the observed positions all coincide: the robot's rotation in the world is undetermined (did "
                     "vision see the robot move?)");
  }
  RobotFrame f;
  f.with_scale = with_scale;
  const Similarity fit = FitSimilarity(x, y, with_scale);
  f.theta = fit.theta;
  f.scale = fit.scale;
  f.t = fit.t;
  // A proper rotation is fitted. A command frame whose axes are mirrored (left-handed) against the world's fits a
  // reflection far better: say so rather than return the best rotation with large residuals.
  {
    Eigen::Matrix2Xd y_mirror = y;
    y_mirror.row(1) *= -1;
    const double ssr = fit.ssr, ssr_mirror = FitSimilarity(x, y_mirror, with_scale).ssr;
    if (ssr_mirror < 0.01 * ssr && ssr > kDistinct * kDistinct * k) {
      throw InputError(source, "points",
                       "the robot's command axes are mirrored against the world's (a reflection fits " +
                           std::to_string(std::sqrt(ssr_mirror / k)) + " m RMS, a rotation " +
                           std::to_string(std::sqrt(ssr / k)) +
                           " m): a robot frame is a rotation; flip one commanded axis (its sign) first");
    }
  }
  if (with_scale && !(f.scale > 1e-9)) {
    throw InputError(source, "points", "the fitted scale is zero: the observed positions do not follow the commands");
  }
  double ssr = 0;
  for (int i = 0; i < k; ++i) {
    f.residuals.push_back(y.col(i) - f.ToWorld(x.col(i)));
    ssr += f.residuals.back().squaredNorm();
  }
  f.rms_residual_m = std::sqrt(ssr / k);
  const int params = with_scale ? 4 : 3;
  f.dof = 2 * k - params;
  if (f.dof > 0) {
    f.sigma_m = std::sqrt(ssr / f.dof);
    // Gauss-Newton normal matrix of [theta, tx, ty, (scale)] at the fit.
    Eigen::MatrixXd j(2 * k, params);
    const Eigen::Matrix2d r = Rotation(f.theta);
    Eigen::Matrix2d dr;
    dr << -std::sin(f.theta), -std::cos(f.theta), std::cos(f.theta), -std::sin(f.theta);
    for (int i = 0; i < k; ++i) {
      j.block<2, 1>(2 * i, 0) = f.scale * dr * x.col(i);
      j.block<2, 2>(2 * i, 1).setIdentity();
      if (with_scale) j.block<2, 1>(2 * i, 3) = r * x.col(i);
    }
    const Eigen::MatrixXd cov = (j.transpose() * j).inverse() * f.sigma_m * f.sigma_m;
    f.theta_stddev = std::sqrt(cov(0, 0));
    f.t_stddev = Eigen::Vector2d(std::sqrt(cov(1, 1)), std::sqrt(cov(2, 2)));
    if (with_scale) f.scale_stddev = std::sqrt(cov(3, 3));
  }
  return f;
}

namespace {

// The file's JSON, or an InputError naming the file.
nlohmann::json ReadJsonFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "", "file does not exist or cannot be read");
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path, "", std::string("not valid JSON: ") + e.what());
  }
}

}  // namespace

std::vector<FramePoint> LoadFramePoints(const std::string& path) {
  const nlohmann::json j = ReadJsonFile(path);
  if (!j.is_object() || !j.contains("points") || !j["points"].is_array()) {
    throw InputError(path, "points",
                     "missing (expected {\"points\": [{\"commanded\": [x, y], \"observed\": [x, y]}, ...]})");
  }
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (it.key() != "points") throw InputError(path, it.key(), "unknown field");
  }
  std::vector<FramePoint> out;
  for (std::size_t i = 0; i < j["points"].size(); ++i) {
    const auto& p = j["points"][i];
    const std::string at = "points[" + std::to_string(i) + "]";
    if (!p.is_object()) throw InputError(path, at, "must be {\"commanded\": [x, y], \"observed\": [x, y]}");
    for (auto it = p.begin(); it != p.end(); ++it) {
      if (it.key() != "commanded" && it.key() != "observed")
        throw InputError(path, at + "." + it.key(), "unknown field");
    }
    for (const char* key : {"commanded", "observed"}) {
      if (!p.contains(key)) throw InputError(path, at + "." + key, "missing");
    }
    out.push_back(
        {ReadPoint(path, p["commanded"], at + ".commanded"), ReadPoint(path, p["observed"], at + ".observed")});
  }
  return out;
}

void SaveRobotFrame(const RobotFrame& f, const std::string& path) {
  nlohmann::ordered_json j;
  auto& r = j["robot_frame"];
  r["theta_deg"] = f.theta * 180 / M_PI;
  r["scale"] = f.scale;
  r["t"] = {f.t.x(), f.t.y()};
  r["with_scale"] = f.with_scale;
  r["stddev"] = {{"theta_deg", f.theta_stddev * 180 / M_PI}, {"t", {f.t_stddev.x(), f.t_stddev.y()}}};
  if (f.with_scale) r["stddev"]["scale"] = f.scale_stddev;
  r["rms_residual_m"] = f.rms_residual_m;
  r["dof"] = f.dof;
  r["residuals"] = nlohmann::ordered_json::array();
  for (const auto& e : f.residuals) r["residuals"].push_back({e.x(), e.y()});
  std::ofstream out(path);
  if (!out) throw InputError(path, "", "cannot write the robot frame file");
  out << j.dump(2) << "\n";
  if (!out) throw InputError(path, "", "cannot write the robot frame file");
}

RobotFrame LoadRobotFrame(const std::string& path) {
  const nlohmann::json j = ReadJsonFile(path);
  if (!j.is_object() || !j.contains("robot_frame") || !j["robot_frame"].is_object()) {
    throw InputError(path, "robot_frame", "missing (expected {\"robot_frame\": {\"theta_deg\", \"scale\", \"t\"}})");
  }
  const auto& r = j["robot_frame"];
  RobotFrame f;
  for (const char* key : {"theta_deg", "scale"}) {
    if (!r.contains(key) || !r[key].is_number() || !std::isfinite(r[key].get<double>())) {
      throw InputError(path, std::string("robot_frame.") + key, "missing or not a finite number");
    }
  }
  f.theta = r["theta_deg"].get<double>() * M_PI / 180;
  f.scale = r["scale"].get<double>();
  if (!(f.scale > 0)) throw InputError(path, "robot_frame.scale", "must be positive");
  if (!r.contains("t")) throw InputError(path, "robot_frame.t", "missing");
  f.t = ReadPoint(path, r["t"], "robot_frame.t");
  f.with_scale = r.value("with_scale", false);
  return f;
}

}  // namespace visco

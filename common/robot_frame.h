#pragma once
// The robot's command frame in the world: where the robot's own axes (the positions and velocities its controller
// is commanded in) lie on the table that vision measures. A 2-D similarity p_w = s R(theta) p_r + t fitted to
// commanded positions and the positions vision observed there (`visco robot-frame`, docs/camera.md); the file
// (docs/formats.md, "Robot frame") carries it to whatever converts world velocities into robot commands:
// v_r = R(theta)^T v_w / s. Eigen only: a driver can read it without vision.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace visco {

/// One position the robot was commanded to and where vision saw it (metres).
struct FramePoint {
  Eigen::Vector2d commanded = Eigen::Vector2d::Zero();  ///< robot command frame
  Eigen::Vector2d observed = Eigen::Vector2d::Zero();   ///< world frame
};

/// The fitted transform p_w = scale R(theta) p_r + t with its fit statistics.
struct RobotFrame {
  double theta = 0;                             ///< radians, counter-clockwise from the robot's x axis to the world's
  double scale = 1;                             ///< world metres per commanded metre (1 for a rigid fit)
  Eigen::Vector2d t = Eigen::Vector2d::Zero();  ///< the robot frame's origin in the world, metres
  bool with_scale = false;
  std::vector<Eigen::Vector2d> residuals;  ///< observed minus fitted, per point, metres
  double rms_residual_m = 0;
  int dof = 0;         ///< residual degrees of freedom: 2 K - parameters (0: the fit is exact, no check)
  double sigma_m = 0;  ///< position noise from the residuals, sqrt(SSR / dof) (0 when dof is 0)
  double theta_stddev = 0, scale_stddev = 0;  ///< 1 sigma from sigma_m (0 when dof is 0)
  Eigen::Vector2d t_stddev = Eigen::Vector2d::Zero();

  Eigen::Vector2d ToWorld(const Eigen::Vector2d& p_r) const;
};

/// Least-squares fit (Umeyama's closed form in 2-D, then the parameters' covariance from the Jacobian). Refused, with
/// InputError(`source`, "points", ...), when the points do not determine the transform: fewer than two distinct
/// commanded positions, or (with scale) observed positions that all coincide, or non-finite numbers.
RobotFrame FitRobotFrame(const std::vector<FramePoint>& points, bool with_scale, const std::string& source = "points");

/// Reads {"points": [{"commanded": [x, y], "observed": [x, y]}, ...]} (unknown fields refused).
/// @throws InputError naming the file and the entry.
std::vector<FramePoint> LoadFramePoints(const std::string& path);

/// Writes {"robot_frame": {"theta_deg", "scale", "t", "stddev": {...}, "rms_residual_m", "points"}}.
/// @throws InputError if the file cannot be written.
void SaveRobotFrame(const RobotFrame& frame, const std::string& path);

/// Reads what SaveRobotFrame writes (the transform; statistics ignored). @throws InputError naming file and entry.
RobotFrame LoadRobotFrame(const std::string& path);

}  // namespace visco

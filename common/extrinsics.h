#pragma once
// The camera's pose in the world (extrinsics) as a JSON file: read by vision (`visco track`, `visco detect`) and by
// control's calibrated servo camera (`visco run --extrinsics`), which links no vision. One reader for both.

#include <Eigen/Geometry>
#include <string>

namespace visco {

/// A rotation as Rz(yaw) Ry(pitch) Rx(roll), angles in radians.
Eigen::Matrix3d RotationFromRpy(double roll, double pitch, double yaw);

/// Camera extrinsics: the camera pose in the world, wMc.
/// File (JSON): {"camera": "name", "wMc": {"t": [x, y, z], "R": [[...], [...], [...]]}} with metres; or instead of
/// "R", "rpy_deg": [roll, pitch, yaw] (R = Rz(yaw) Ry(pitch) Rx(roll)). R must be a rotation (orthonormal,
/// det +1, within 1e-6). Unknown fields are refused (a misspelt "rpy" is an error, not identity).
/// Optionally "wMc": {..., "stddev": {"position_m": s_t, "rotation_deg": s_r}}: the pose's uncertainty, 1 sigma, each
/// a number (isotropic) or [x, y, z] per world axis; either may be left out (0). See Extrinsics::covariance.
/// @throws InputError naming the file and the entry that is missing or wrong.
Eigen::Isometry3d LoadExtrinsics(const std::string& path);

/// The camera pose and its uncertainty.
struct Extrinsics {
  Eigen::Isometry3d wMc = Eigen::Isometry3d::Identity();
  /// Covariance of wMc in the world frame, visco's pose perturbation (vision::PerturbPose): rotation vector w on the
  /// left, then translation (R' = Exp(w) R, t' = t + v; [w, v], radians and metres). Diagonal from `wMc.stddev`
  /// (rotation first). Zero without it: the pose is taken as exact.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  bool exact() const { return !(covariance.trace() > 0); }
};

/// LoadExtrinsics with the optional uncertainty. @throws InputError as LoadExtrinsics, and for a negative or
/// non-finite stddev.
Extrinsics LoadExtrinsicsWithUncertainty(const std::string& path);

}  // namespace visco

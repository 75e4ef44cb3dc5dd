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
/// @throws InputError naming the file and the entry that is missing or wrong.
Eigen::Isometry3d LoadExtrinsics(const std::string& path);

}  // namespace visco

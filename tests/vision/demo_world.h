// Shared by the vision tests that render the demo world: the synthetic camera (data/vision/synthetic_camera.xml) as
// an undistorted pinhole, and planar object poses on the table.
#pragma once

#include <Eigen/Geometry>

#include "vision/camera.h"

namespace visco::vision::test_world {

inline const CameraModel kDemoCamera = CameraModel::Pinhole(600, 600, 319.5, 239.5, 640, 480);

// An object standing on the table (z = 0) at (x, y), turned by yaw (rad) about the vertical.
inline Eigen::Isometry3d Planar(double x, double y, double yaw) {
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  m.linear() = RotationFromRpy(0, 0, yaw);
  m.translation() = Eigen::Vector3d(x, y, 0);
  return m;
}

}  // namespace visco::vision::test_world

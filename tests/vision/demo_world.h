// Shared by the vision tests that render the demo world: the synthetic camera (data/vision/synthetic_camera.xml) as
// an undistorted pinhole, and planar object poses on the table.
#pragma once

#include <Eigen/Geometry>

#include "vision/camera.h"
#include "vision/object_model.h"
#include "vision/tag_renderer.h"

namespace visco::vision::test_world {

inline const CameraModel kDemoCamera = CameraModel::Pinhole(600, 600, 319.5, 239.5, 640, 480);

// An object standing on the table (z = 0) at (x, y), turned by yaw (rad) about the vertical.
inline Eigen::Isometry3d Planar(double x, double y, double yaw) {
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  m.linear() = RotationFromRpy(0, 0, yaw);
  m.translation() = Eigen::Vector3d(x, y, 0);
  return m;
}

// A camera 42 cm above the table looking down and forward at the objects near the origin (the contact tests' view).
inline Eigen::Isometry3d TiltedCameraPose() {
  Eigen::Isometry3d wMc = Eigen::Isometry3d::Identity();
  wMc.linear() = RotationFromRpy(-2.2, 0, 0.1);
  wMc.translation() = Eigen::Vector3d(0.02, -0.42, 0.42);
  return wMc;
}

// A scene with the grey table (z = 0) and nothing on it yet.
inline RenderScene TableScene() {
  RenderScene scene;
  scene.polygons.push_back({{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, 120});
  return scene;
}

// An object of the models standing at wMo: its prism (grey levels of its top and sides) and its tags.
inline void AddObject(RenderScene& scene, const ObjectModel& m, const Eigen::Isometry3d& wMo, std::uint8_t top,
                      std::uint8_t side) {
  AddPrism(scene, m.polygon, m.height, wMo, top, side);
  for (const auto& t : m.tags) scene.tags.push_back({t.family, t.id, t.size, wMo * t.oMt});
}

}  // namespace visco::vision::test_world

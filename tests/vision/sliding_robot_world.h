// Shared by the tests of `visco track` as a process and of its pictures: the demo world (data/vision/demo_objects.json,
// demo_extrinsics.json) rendered by the synthetic camera, the robot sliding along x past the VC line of the block's
// vertex 0, with the truth of every frame.
#pragma once

#include <Eigen/Geometry>

#include "tests/vision/demo_world.h"
#include "vision/camera.h"
#include "vision/features.h"
#include "vision/object_model.h"
#include "vision/tag_renderer.h"

namespace visco::vision::test_world {

struct SlidingRobotWorld {
  static constexpr int kFrames = 24;
  CameraModel camera = kDemoCamera;  // a test may give it lens distortion
  ObjectModels models = LoadObjectModels("data/vision/demo_objects.json");
  Eigen::Isometry3d wMc = LoadExtrinsics("data/vision/demo_extrinsics.json");
  Eigen::Isometry3d wMo = Planar(0.02, 0.12, 0.3);  // the block
  Eigen::Isometry3d Robot(int i) const { return Planar(-0.16 + 0.01 * i, 0.0, 0.1); }
  /// Frame i; `robot_tag` false leaves the robot's tag out (the robot is there, its tag is not seen).
  GrayImage Render(int i, bool robot_tag = true) const {
    RenderScene scene;
    scene.polygons.push_back({{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, 120});
    const Eigen::Isometry3d wMr = Robot(i);
    AddPrism(scene, models.robot.polygon, models.robot.height, wMr, 70, 60);
    if (robot_tag) scene.tags.push_back({"tag36h11", 0, models.robot.tags[0].size, wMr * models.robot.tags[0].oMt});
    AddPrism(scene, models.obstacles[0].polygon, models.obstacles[0].height, wMo, 160, 140);
    scene.tags.push_back({"tag36h11", 1, models.obstacles[0].tags[0].size, wMo * models.obstacles[0].tags[0].oMt});
    RenderOptions ro;
    ro.noise_stddev = 1;
    ro.blur_sigma = 0.5;
    ro.seed = 300 + i;
    return visco::vision::Render(camera, wMc, scene, ro);
  }
  // The true signed distance (ideal pixels) of block.v0.cm1 in frame i.
  double TrueDistance(int i) const {
    return SignedImageDistance(camera, wMc, models.robot, wMc.inverse() * Robot(i), 1, models.obstacles[0],
                               wMc.inverse() * wMo, 0);
  }
  // First frame at which the true signed distance of block.v0.cm1 has changed sign.
  int TrueCrossing() const {
    double prev = 0;
    for (int i = 0; i < kFrames; ++i) {
      const double d = TrueDistance(i);
      if (i > 0 && (d > 0) != (prev > 0)) return i;
      prev = d;
    }
    return -1;
  }
};

}  // namespace visco::vision::test_world

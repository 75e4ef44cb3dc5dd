// The synthetic camera: tag bitmaps equal the AprilTag library's own, and rendered tags are detected with the right
// ids, corners at the projections of the true corners and poses near the true poses (with and without noise).

#include "vision/tag_renderer.h"

#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <random>

#include "common/error.h"
#include "vision/camera.h"
#include "vision/tag_detector.h"

namespace visco::vision {
namespace {

TEST(TagBitmap, EqualsAprilTagLibraryImages) {
  apriltag_family_t* fam = tag36h11_create();
  for (int id : {0, 1, 7, 42, 586}) {
    image_u8_t* im = apriltag_to_image(fam, id);
    const TagBitmap b = MakeTagBitmap("tag36h11", id);
    ASSERT_EQ(b.total_width, im->width);
    ASSERT_EQ(b.total_width, im->height);
    for (int r = 0; r < im->height; ++r) {
      for (int c = 0; c < im->width; ++c)
        EXPECT_EQ(b.at(c, r), im->buf[r * im->stride + c]) << id << " " << r << " " << c;
    }
    // Debian's libapriltag does not export image_u8_destroy: the image and its buffer are two calloc blocks.
    free(im->buf);
    free(im);
  }
  tag36h11_destroy(fam);
  EXPECT_THROW(MakeTagBitmap("tag36h11", 587), InputError);
}

Eigen::Isometry3d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, const Eigen::Vector3d& up) {
  // Camera frame: z forward, x right, y down.
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d x = z.cross(up).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Isometry3d wMc = Eigen::Isometry3d::Identity();
  wMc.linear().col(0) = x;
  wMc.linear().col(1) = y;
  wMc.linear().col(2) = z;
  wMc.translation() = eye;
  return wMc;
}

// AprilTag's corners are not exact even on noise-free renders: its line fits on ~40 px tags scatter by up to about
// 0.3 px (as on visp-images-data's benchmark set, whose corners sit up to 0.48 px from the projected truth).
struct Case {
  double noise;
  double blur;
  double max_corner_err;
};

TEST(TagRenderer, RenderedTagsAreDetectedAtTheirTrueCornersAndPoses) {
  const CameraModel cam = CameraModel::Pinhole(600, 600, 319.5, 239.5, 640, 480);
  std::mt19937 rng(66);
  std::uniform_real_distribution<double> pos(-0.12, 0.12), ang(-0.6, 0.6), yaw(-3.1, 3.1);
  const Eigen::Isometry3d wMc = LookAt({0.05, -0.35, 0.75}, {0, 0, 0}, {0, 0, 1});
  for (const Case& c : {Case{0, 0, 0.35}, Case{3, 0.8, 0.45}}) {
    double worst_corner = 0, worst_t = 0, worst_r = 0;
    for (int trial = 0; trial < 8; ++trial) {
      RenderScene scene;
      scene.polygons.push_back({{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, 110});
      RenderTag tag;
      tag.id = trial * 7;
      tag.size = 0.06;
      tag.wMt.linear() = RotationFromRpy(ang(rng), ang(rng) * 0.5, yaw(rng));
      tag.wMt.translation() = Eigen::Vector3d(pos(rng), pos(rng), 0.03);
      scene.tags.push_back(tag);
      RenderOptions ro;
      ro.noise_stddev = c.noise;
      ro.blur_sigma = c.blur;
      ro.seed = 100 + trial;
      const GrayImage img = Render(cam, wMc, scene, ro);
      DetectorOptions dopt;
      dopt.quad_sigma = c.noise > 0 ? 0.8f : 0.0f;  // noisy images need the segmentation blur (and it is faster)
      TagDetector det(dopt);
      const auto obs = det.Detect(img.view());
      ASSERT_EQ(obs.size(), 1u) << "trial " << trial;
      EXPECT_EQ(obs[0].id, tag.id);
      const Eigen::Isometry3d cMt = wMc.inverse() * tag.wMt;
      const auto pts = TagCornersInTagFrame(tag.size);
      for (int k = 0; k < 4; ++k) {
        // The AprilTag library's pixel centres are at +0.5 (PoseOptions::corner_offset_px).
        const Eigen::Vector2d truth = cam.Project(cMt * pts[k]) + Eigen::Vector2d(0.5, 0.5);
        const double e = (obs[0].corners[k] - truth).norm();
        worst_corner = std::max(worst_corner, e);
        EXPECT_LT(e, c.max_corner_err) << "trial " << trial << " corner " << k;
      }
      const auto pose = EstimateTagPose(cam, obs[0].corners, tag.size, {}, std::nullopt, std::nullopt);
      ASSERT_TRUE(pose.has_value());
      worst_t = std::max(worst_t, (pose->cMo.translation() - cMt.translation()).norm());
      worst_r = std::max(worst_r, Eigen::AngleAxisd(pose->cMo.linear().transpose() * cMt.linear()).angle());
    }
    std::printf("noise %.1f blur %.1f: worst corner error %.3f px, translation %.4f m, rotation %.4f rad\n", c.noise,
                c.blur, worst_corner, worst_t, worst_r);
    EXPECT_LT(worst_t, 0.01);
    EXPECT_LT(worst_r, 0.03);
  }
}

}  // namespace
}  // namespace visco::vision

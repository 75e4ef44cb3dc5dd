// Tracking on sequences no one here made (visp-images-data mire-2: 501 frames of a dot target, vpDot2; cube: 80
// frames, KLT) with losses reported, and tag tracking (ROI detection, KLT corners) on a rendered moving tag against
// ground truth.

#include "vision/tracking.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "vision/image.h"
#include "vision/tag_renderer.h"

namespace visco::vision {
namespace {

const std::string kImages = "/usr/share/visp-images-data/ViSP-images/";

std::string Frame(const std::string& dir, int i) {
  char name[64];
  std::snprintf(name, sizeof(name), "image.%04d.pgm", i);
  return kImages + dir + "/" + name;
}

TEST(Mire2, DotsTrackedThroughAll501Frames) {
  const GrayImage first = ReadGrayImage(Frame("mire-2", 1));
  // The target's white dots: four small ones and the big central one.
  const auto seeds = FindBlobs(first.view(), true, 30, 5000, 0.75);
  ASSERT_GE(seeds.size(), 4u);
  DotTracker tracker;
  tracker.Init(first.view(), seeds);
  int alive_start = 0;
  for (bool a : tracker.alive()) alive_start += a ? 1 : 0;
  int frames = 1, min_alive = alive_start, first_loss = -1;
  double max_step = 0;
  auto prev = tracker.centers();
  for (int i = 2; i <= 501; ++i) {
    const GrayImage img = ReadGrayImage(Frame("mire-2", i));
    const int n = tracker.Track(img.view());
    if (n < min_alive && first_loss < 0) first_loss = i;
    min_alive = std::min(min_alive, n);
    for (std::size_t k = 0; k < prev.size(); ++k) {
      if (tracker.alive()[k]) max_step = std::max(max_step, (tracker.centers()[k] - prev[k]).norm());
    }
    prev = tracker.centers();
    ++frames;
  }
  std::printf(
      "mire-2: %d frames, %zu blobs found, %d dots tracked at start, %d at the end (first loss at frame %d), "
      "largest frame-to-frame motion %.1f px\n",
      frames, seeds.size(), alive_start, min_alive, first_loss, max_step);
  EXPECT_EQ(frames, 501);
  EXPECT_GE(alive_start, 5);
  EXPECT_EQ(min_alive, alive_start) << "a dot was lost at frame " << first_loss;
}

TEST(Cube, KltFeaturesThroughTheSequence) {
  GrayImage img = ReadGrayImage(Frame("cube", 0));
  KltTracker klt;
  klt.InitAuto(img.view());
  const int start = static_cast<int>(klt.points().size());
  int n = start, frames = 1;
  for (int i = 1; i < 80; ++i) {
    img = ReadGrayImage(Frame("cube", i));
    n = klt.Track(img.view());
    ++frames;
  }
  std::printf("cube: %d frames, %d KLT features at start, %d still tracked at the end (%d lost)\n", frames, start, n,
              start - n);
  EXPECT_EQ(frames, 80);
  EXPECT_GE(start, 100);
  EXPECT_GE(n, start * 2 / 5);  // the camera moves: features leave the view or are occluded (loss reported)
}

Eigen::Isometry3d LookDown(double height) {
  Eigen::Isometry3d wMc = Eigen::Isometry3d::Identity();
  wMc.linear() = RotationFromRpy(M_PI + 0.3, 0, 0);
  wMc.translation() = Eigen::Vector3d(0, -0.15, height);
  return wMc;
}

class TagTracking : public ::testing::TestWithParam<TagTrackingMode> {};

TEST_P(TagTracking, FollowsAMovingTagAgainstGroundTruth) {
  const CameraModel cam = CameraModel::Pinhole(600, 600, 319.5, 239.5, 640, 480);
  const Eigen::Isometry3d wMc = LookDown(0.6);
  TagTrackerOptions to;
  to.mode = GetParam();
  to.full_detection_every = 1000;
  DetectorOptions dopt;
  dopt.quad_sigma = 0.8f;
  TagTracker tracker(dopt, to);
  int full = 0, lost = 0;
  double worst = 0;
  for (int i = 0; i < 25; ++i) {
    RenderScene scene;
    scene.polygons.push_back({{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, 120});
    RenderTag tag;
    tag.id = 3;
    tag.size = 0.05;
    tag.wMt.linear() = RotationFromRpy(0, 0, 0.02 * i);
    tag.wMt.translation() = Eigen::Vector3d(-0.1 + 0.008 * i, 0.05, 0.01);
    scene.tags.push_back(tag);
    RenderOptions ro;
    ro.noise_stddev = 1.5;
    ro.blur_sigma = 0.5;
    ro.seed = 500 + i;
    const GrayImage img = Render(cam, wMc, scene, ro);
    bool was_full = false;
    const auto obs = tracker.Process(img.view(), &was_full);
    full += was_full ? 1 : 0;
    lost += static_cast<int>(tracker.lost_last().size());
    ASSERT_EQ(obs.size(), 1u) << "frame " << i;
    const auto pts = TagCornersInTagFrame(tag.size);
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector2d truth = cam.Project(wMc.inverse() * tag.wMt * pts[k]) + Eigen::Vector2d(0.5, 0.5);
      worst = std::max(worst, (obs[0].corners[k] - truth).norm());
    }
  }
  std::printf("mode %d: 25 frames, %d full detections, %d losses, worst corner error %.3f px\n",
              static_cast<int>(GetParam()), full, lost, worst);
  EXPECT_EQ(lost, 0);
  // KLT on the corners drifts (an L-junction slides along its edges; measured ~2 px over 25 frames) while ROI
  // detection keeps the detector's accuracy: the reason ROI detection is the default mode.
  EXPECT_LT(worst, GetParam() == TagTrackingMode::kKltCorners ? 3.0 : 0.5);
  if (GetParam() != TagTrackingMode::kDetectEveryFrame) {
    EXPECT_EQ(full, 1);
  }
}

INSTANTIATE_TEST_SUITE_P(Modes, TagTracking,
                         ::testing::Values(TagTrackingMode::kDetectEveryFrame, TagTrackingMode::kRoiDetection,
                                           TagTrackingMode::kKltCorners));

}  // namespace
}  // namespace visco::vision

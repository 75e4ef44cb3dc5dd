// Features and visual events against ground truth: the signed image distance's sign against a plain world-geometry
// reference (which side of the VC ray the CM vertex's foot lies), the hysteresis thresholds from the noise model,
// and a rendered sequence (noise and blur) of the robot crossing a VC ray: distances, uncertainty, one clean
// crossing event at the true frame, robot positions within their stated uncertainty.

#include "vision/features.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <random>

#include "common/error.h"
#include "tests/vision/demo_world.h"
#include "vision/camera.h"
#include "vision/object_model.h"
#include "vision/tag_detector.h"
#include "vision/tag_renderer.h"

namespace visco::vision {
namespace {

const CameraModel& kCam = test_world::kDemoCamera;

using test_world::Planar;

TEST(Hysteresis, ThresholdsFollowFromTheNoiseModel) {
  const Thresholds k = HysteresisThresholds(NoiseModel{});
  EXPECT_NEAR(k.k_hi, 3.2905, 1e-3);           // Phi^-1(1 - 0.0005)
  EXPECT_NEAR(k.k_lo, 3.2905 - 3.0902, 1e-3);  // minus Phi^-1(1 - 0.001)
  EXPECT_THROW(HysteresisThresholds(NoiseModel{0.3, true, 0.05, 0.02, 0, 0.1}), InputError);
  // On the line with unit noise: declared off it about alpha of the time; one step past k_hi never falls back.
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0, 1);
  int off = 0;
  const int trials = 200000;
  for (int i = 0; i < trials; ++i) off += NextSideState(SideState::kOnLine, n(rng), 1, k) != SideState::kOnLine;
  EXPECT_NEAR(static_cast<double>(off) / trials, 1e-3, 4e-4);
  int fell = 0;
  for (int i = 0; i < trials; ++i)
    fell += NextSideState(SideState::kPositive, k.k_hi + n(rng), 1, k) != SideState::kPositive;
  EXPECT_NEAR(static_cast<double>(fell) / trials, 1e-3, 4e-4);
}

TEST(SignedImageDistance, SignMatchesWorldSideOfTheVcRay) {
  const ObjectModels m = LoadObjectModels("data/vision/demo_objects.json");
  const Eigen::Isometry3d wMc = LoadExtrinsics("data/vision/demo_extrinsics.json");
  const Eigen::Isometry3d cMw = wMc.inverse();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> x(-0.25, 0.25), y(-0.1, 0.3), yaw(-3, 3);
  int checked = 0;
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Isometry3d wMr = Planar(x(rng), y(rng), yaw(rng));
    const Eigen::Isometry3d wMo = Planar(x(rng), y(rng), yaw(rng));
    const int v = i % 4, c = (i / 4) % 4;
    const double d = SignedImageDistance(kCam, wMc, m.robot, cMw * wMr, c, m.obstacles[0], cMw * wMo, v);
    // Reference: the foot of the robot's vertex relative to the ray from the obstacle vertex to the camera foot.
    const Eigen::Vector2d b =
        (wMo * Eigen::Vector3d(m.obstacles[0].polygon[v].x(), m.obstacles[0].polygon[v].y(), 0)).head<2>();
    const Eigen::Vector2d a = (wMr * Eigen::Vector3d(m.robot.polygon[c].x(), m.robot.polygon[c].y(), 0)).head<2>();
    const Eigen::Vector2d p = wMc.translation().head<2>();
    const Eigen::Vector2d r = p - b, s = a - b;
    const double cross = r.x() * s.y() - r.y() * s.x();
    if (std::abs(cross) / r.norm() < 1e-4) continue;  // on the ray within rounding
    ++checked;
    EXPECT_EQ(d > 0, cross > 0) << i;
  }
  EXPECT_GT(checked, 1900);
}

TEST(ObjectModels, RejectsBadFilesWithPreciseMessages) {
  auto msg = [](const std::string& text) {
    try {
      ParseObjectModels(text, "m.json");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string tag = R"("tags": [{"id": 0, "size": 0.05, "t": [0, 0, 0.03]}])";
  EXPECT_NE(msg("{").find("m.json: not valid JSON"), std::string::npos);
  EXPECT_NE(
      msg(R"({"robot": {"polygon": [[0,0],[1,0]], "height": 1, )" + tag + "}}").find("robot.polygon: needs at least 3"),
      std::string::npos);
  EXPECT_NE(
      msg(R"({"robot": {"polygon": [[0,0],[1,0],[0,1]], "height": 1, "tags": [{"id": 0, "size": -1, "t": [0,0,0]}]}})")
          .find("robot.tags[0].size: must be positive"),
      std::string::npos);
  EXPECT_NE(msg(R"({"robot": {"polygon": [[0,0],[1,0],[0,1]], "height": 1, )" + tag + R"(}, "obstacle": []})")
                .find("obstacle: unknown field"),
            std::string::npos);
  EXPECT_NE(msg(R"({"robot": {"polygon": [[0,0],[1,0],[0,1]], "height": 1, )" + tag +
                R"(}, "obstacles": [{"id": "b", "polygon": [[0,0],[1,0],[0,1]], "height": 1, )" + tag + "}]}")
                .find("is used twice"),
            std::string::npos);
  EXPECT_NE(msg(R"({"robot": {"polygon": [[0,0],[1,0],[0,1]], "height": 1, )" + tag +
                R"(}, "events": [{"obstacle": "x", "vertex": 0, "cm_vertex": 0}]})")
                .find("events[0].obstacle: no obstacle with id 'x'"),
            std::string::npos);
  const ObjectModels all = LoadObjectModels("data/vision/demo_objects.json");
  EXPECT_EQ(all.events.size(), 2u);
  EXPECT_EQ(all.events[1].cvc_ray, "block.v3.cm2");
}

TEST(Features, RenderedCrossingSequenceAgainstGroundTruth) {
  const ObjectModels m = LoadObjectModels("data/vision/demo_objects.json");
  const Eigen::Isometry3d wMc = LoadExtrinsics("data/vision/demo_extrinsics.json");
  const Eigen::Isometry3d cMw = wMc.inverse();
  const Eigen::Isometry3d wMo = Planar(0.02, 0.12, 0.3);
  DetectorOptions dopt;
  dopt.quad_sigma = 0.8f;
  TagDetector detector(dopt);
  FeatureEstimator estimator(kCam, wMc, m);
  const int frames = 40;
  int crossings = 0, crossing_frame = -1, true_crossing_frame = -1, within = 0, valid = 0, state_changes = 0;
  double prev_truth = 0, max_pos_err = 0, max_pos_sigma = 0, max_sigma_d = 0;
  SideState prev_state = SideState::kUnknown;
  for (int i = 0; i < frames; ++i) {
    // The robot slides along x past the VC ray of the block's vertex 0.
    const Eigen::Isometry3d wMr = Planar(-0.16 + 0.006 * i, 0.0, 0.1);
    RenderScene scene;
    scene.polygons.push_back({{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, 120});
    AddPrism(scene, m.robot.polygon, m.robot.height, wMr, 70, 60);
    AddPrism(scene, m.obstacles[0].polygon, m.obstacles[0].height, wMo, 160, 140);
    scene.tags.push_back({"tag36h11", 0, m.robot.tags[0].size, wMr * m.robot.tags[0].oMt});
    scene.tags.push_back({"tag36h11", 1, m.obstacles[0].tags[0].size, wMo * m.obstacles[0].tags[0].oMt});
    RenderOptions ro;
    ro.noise_stddev = 2;
    ro.blur_sigma = 0.6;
    ro.seed = 1000 + i;
    const GrayImage img = Render(kCam, wMc, scene, ro);
    if (i == 0 && std::getenv("VISCO_DUMP")) WriteGrayImage(img.view(), "/tmp/features_frame0.png");
    const FrameFeatures& f = estimator.Update(detector.Detect(img.view()));
    ASSERT_TRUE(f.robot.valid) << "frame " << i;
    ASSERT_EQ(f.pairs.size(), 2u);
    const PairMeasurement& pm = f.pairs[0];
    ASSERT_TRUE(pm.valid);
    const double truth = SignedImageDistance(kCam, wMc, m.robot, cMw * wMr, 1, m.obstacles[0], cMw * wMo, 0);
    if (i > 0 && (truth > 0) != (prev_truth > 0)) true_crossing_frame = i;
    prev_truth = truth;
    ++valid;
    within += std::abs(pm.signed_distance_px - truth) < 3 * pm.stddev_px ? 1 : 0;
    max_sigma_d = std::max(max_sigma_d, pm.stddev_px);
    if (pm.crossed) {
      ++crossings;
      if (pm.state != SideState::kOnLine && crossing_frame < 0) crossing_frame = i;
    }
    if (prev_state != SideState::kUnknown && pm.state != prev_state) ++state_changes;
    prev_state = pm.state;
    // Clear cases must be classified right.
    const double k = estimator.thresholds().k_hi;
    if (truth > (k + 3) * pm.stddev_px) {
      EXPECT_EQ(pm.state, SideState::kPositive) << i;
    }
    if (truth < -(k + 3) * pm.stddev_px) {
      EXPECT_EQ(pm.state, SideState::kNegative) << i;
    }
    const double pos_err = (f.robot.position - wMr.translation().head<2>()).norm();
    max_pos_err = std::max(max_pos_err, pos_err);
    max_pos_sigma = std::max(max_pos_sigma, f.robot.position_stddev);
    EXPECT_LT(pos_err, 4 * f.robot.position_stddev + 1e-3) << i;
  }
  std::printf(
      "frames %d: |d - truth| < 3 sigma in %d; sigma_d max %.3f px; corner sigma %.3f px; crossing at %d "
      "(truth %d), %d state changes; robot position error max %.4f m (stddev max %.4f m)\n",
      valid, within, max_sigma_d, estimator.corner_sigma_px(), crossing_frame, true_crossing_frame, state_changes,
      max_pos_err, max_pos_sigma);
  EXPECT_GE(within, valid * 9 / 10);
  ASSERT_GT(true_crossing_frame, 0);
  EXPECT_GE(crossing_frame, true_crossing_frame - 1);
  EXPECT_LE(crossing_frame, true_crossing_frame + 3);
  EXPECT_LE(state_changes, 2);  // negative -> on the line -> positive, no chatter
  EXPECT_LT(max_pos_err, 0.01);
}

}  // namespace
}  // namespace visco::vision

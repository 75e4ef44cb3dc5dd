// The noise model's promise checked on rendered sequences through the whole per-frame path: rendered
// images (noise, blur) of the robot flush against a block on the table, the AprilTag detector, FeatureEstimator with
// the online corner-noise estimate (pose fits, contact refinement, d, sigma_d). Per pair, the stated sigma_d against
// the empirical stddev of d - truth over the frames, and the hysteresis' two rates against d - truth: a vertex on the
// line declared off it (|d - truth| > k_hi sigma_d, promised alpha) and one that has just entered a side at
// k_hi sigma_d falling back (d - truth < -(k_hi - k_lo) sigma_d, promised beta). docs/vision.md, "Noise model and
// hysteresis".

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "tests/vision/demo_world.h"
#include "tests/vision/sanitized_count.h"
#include "vision/camera.h"
#include "vision/features.h"
#include "vision/tag_detector.h"
#include "vision/tag_renderer.h"

namespace visco::vision {
namespace {

using test_world::Planar;

// Small images (320 x 240, the demo camera's field of view) keep rendering and detection cheap.
const CameraModel kCam = CameraModel::Pinhole(300, 300, 159.5, 119.5, 320, 240);

ObjectModels Models() {
  ObjectModels m = ParseObjectModels(R"({
    "robot": {"id": "robot", "polygon": [[-0.04, -0.04], [0.04, -0.04], [0.04, 0.04], [-0.04, 0.04]], "height": 0.03,
              "tags": [{"family": "tag36h11", "id": 0, "size": 0.06, "t": [0, 0, 0.03], "rpy_deg": [0, 0, 0]}]},
    "obstacles": [
      {"id": "block", "polygon": [[0, 0], [0.1, 0], [0.1, 0.1], [0, 0.1]], "height": 0.05,
       "tags": [{"family": "tag36h11", "id": 1, "size": 0.08, "t": [0.05, 0.05, 0.05], "rpy_deg": [0, 0, 0]}]}
    ]})",
                                     "test models");
  m.events.clear();
  for (int c = 0; c < 4; ++c) {
    for (int v = 0; v < 4; ++v) m.events.push_back({"pair", 0, v, c});
  }
  return m;
}

// Seeded frames of the robot flush against the block's -x side, both on the table (16 pairs: every robot vertex with
// every block vertex). The pair is placed anew in every
// frame (a few mm and degrees), so that the detector's corner bias, which depends on where the tags' edges fall on
// the pixel grid, is sampled rather than frozen into one offset. The first `warm_up` frames let the online sigma_c
// settle (it starts at 0.3 px) and are not counted. Checked: both rates within 3 times their promise plus the
// binomial slack, and no pair's sigma_d below 0.85 of the empirical stddev of d - truth. Printed beside them: the
// ratio's mean and worst and the mean error in units of sigma_d (the rendering's bias, which the stddev leaves out
// and the rates include); measured, these are not the noise model's ideal (docs/vision.md, "The noise model on
// rendered frames").
TEST(RenderedHysteresis, StatedSigmaAndRatesHoldThroughThePipeline) {
  const ObjectModels m = Models();
  const Eigen::Isometry3d wMc = test_world::TiltedCameraPose();
  const Eigen::Isometry3d cMw = wMc.inverse();
  DetectorOptions dopt;
  dopt.quad_sigma = 0.8f;
  TagDetector detector(dopt);
  NoiseModel noise;  // online sigma_c (the default)
  FeatureEstimator estimator(kCam, wMc, m, noise);
  const Thresholds k = estimator.thresholds();
  const int warm_up = 30;
  const int frames = std::getenv("VISCO_MC_FRAMES") != nullptr ? std::atoi(std::getenv("VISCO_MC_FRAMES"))
                                                               : test_world::SanitizedCount(400, 60);
  const std::size_t pairs = m.events.size();
  std::vector<double> sum(pairs, 0), sum2(pairs, 0), stated(pairs, 0), bias_in_sigma(pairs, 0);
  int off_line = 0, fall_back = 0, draws = 0, counted = 0, missed = 0, refined = 0;
  double sigma_c = 0;
  std::mt19937 rng(16);
  std::uniform_real_distribution<double> jitter(-1, 1);
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < warm_up + frames; ++i) {
    const Eigen::Isometry3d wMb = Planar(-0.03 + 0.005 * jitter(rng), 0.005 * jitter(rng), -0.2 + 0.05 * jitter(rng));
    const Eigen::Isometry3d wMr = wMb * Planar(-0.04, 0.04 + 0.005 * jitter(rng), 0);
    RenderScene scene = test_world::TableScene();
    test_world::AddObject(scene, m.robot, wMr, 70, 60);
    test_world::AddObject(scene, m.obstacles[0], wMb, 160, 140);
    RenderOptions ro;
    ro.noise_stddev = 2;
    ro.blur_sigma = 0.6;
    ro.seed = 9000 + static_cast<std::uint32_t>(i);
    const GrayImage img = Render(kCam, wMc, scene, ro);
    const FrameFeatures& f = estimator.Update(detector.Detect(img.view()));
    if (i < warm_up) continue;
    if (!f.robot_pose.valid || !f.obstacle_poses[0].valid) {
      ++missed;
      continue;
    }
    ++counted;
    refined += f.contact.ok && f.contact.covariance_propagated ? 1 : 0;
    sigma_c += f.corner_sigma_px;
    for (std::size_t e = 0; e < pairs; ++e) {
      const EventPair& ev = m.events[e];
      const PairMeasurement& pm = f.pairs[e];
      ASSERT_TRUE(pm.valid);
      const double truth =
          SignedImageDistance(kCam, wMc, m.robot, cMw * wMr, ev.cm_vertex, m.obstacles[0], cMw * wMb, ev.vertex);
      const double err = pm.signed_distance_px - truth;
      sum[e] += err;
      sum2[e] += err * err;
      stated[e] += pm.stddev_px * pm.stddev_px;
      bias_in_sigma[e] += err / pm.stddev_px;
      off_line += std::abs(err) > k.k_hi * pm.stddev_px ? 1 : 0;
      fall_back += err < -(k.k_hi - k.k_lo) * pm.stddev_px ? 1 : 0;
      ++draws;
    }
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_GT(counted, 0);
  EXPECT_EQ(missed, 0);
  EXPECT_EQ(refined, counted);
  const double n = counted;
  double worst = 1, mean_ratio = 0, worst_bias = 0;
  for (std::size_t e = 0; e < pairs; ++e) {
    const double mean = sum[e] / n;
    const double emp = std::sqrt((sum2[e] - n * mean * mean) / (n - 1));
    const double ratio = std::sqrt(stated[e] / n) / emp;
    if (std::abs(ratio - 1) > std::abs(worst - 1)) worst = ratio;
    mean_ratio += ratio / static_cast<double>(pairs);
    if (std::abs(bias_in_sigma[e] / n) > std::abs(worst_bias)) worst_bias = bias_in_sigma[e] / n;
    // Measured: the stated sigma_d is conservative for the random part (mean 2.7, see docs/vision.md); it must never
    // understate it.
    EXPECT_GT(ratio, 0.85) << "pair cm" << m.events[e].cm_vertex << ".v" << m.events[e].vertex << ": stated sigma_d "
                           << std::sqrt(stated[e] / n) << " px, empirical " << emp << " px, mean error " << mean
                           << " px";
  }
  // The rates over the pair-frames against 3 times the promise plus 3 binomial standard deviations of that count (the
  // 16 pairs of a frame share the frame's two poses, so the count is more dispersed than a binomial's).
  auto bound = [&](double p) { return 3 * p * draws + 3 * std::sqrt(3 * p * draws); };
  std::printf(
      "rendered %dx%d, noise 2 grey levels, blur 0.6 px; %d frames after %d warm-up (%d missed), %zu pairs: online "
      "sigma_c %.3f px; sigma_d stated / empirical stddev of d - truth: mean %.3f, worst %.3f; mean (d - truth) / "
      "sigma_d, worst pair %.3f; |d - truth| > k_hi sigma_d in %d of %d (%.2g, promise alpha %.2g, bound %.0f); "
      "d - truth < -(k_hi - k_lo) sigma_d in %d of %d (%.2g, promise beta %.2g, bound %.0f); %.1f ms per frame\n",
      kCam.width, kCam.height, counted, warm_up, missed, pairs, sigma_c / n, mean_ratio, worst, worst_bias, off_line,
      draws, static_cast<double>(off_line) / draws, noise.false_alarm, bound(noise.false_alarm), fall_back, draws,
      static_cast<double>(fall_back) / draws, noise.fall_back, bound(noise.fall_back),
      1e3 * seconds / (warm_up + frames));
  EXPECT_LE(off_line, bound(noise.false_alarm));
  EXPECT_LE(fall_back, bound(noise.fall_back));
}

}  // namespace
}  // namespace visco::vision

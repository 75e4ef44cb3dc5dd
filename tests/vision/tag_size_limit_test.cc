// VisibilityOptions::min_cell_px measured against the detector: the pipeline expects a tag only when its shortest
// projected side spans at least that many pixels per cell (vision/visibility.h), and a tag it expects but cannot
// detect sends it back to full detection in every frame. Tags of tag36h11 rendered from face-on to grazing angles
// (70 degrees), spun in the image, with blur and noise, at sizes from 0.8 to 2.6 px per cell; each detected or not by
// the pipeline's full-resolution detector. The threshold is where detection becomes reliable.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "tests/vision/sanitized_count.h"
#include "vision/camera.h"
#include "vision/object_model.h"
#include "vision/tag_detector.h"
#include "vision/tag_renderer.h"
#include "vision/visibility.h"

namespace visco::vision {
namespace {

// A small image keeps the rendering cheap; the tags near the limit are 8-25 px wide.
const CameraModel kCam = CameraModel::Pinhole(600, 600, 160, 120, 320, 240);
constexpr int kCells = 8;  // tag36h11: cells across the black border
constexpr double kSize = 0.05;

struct Sample {
  double cell_px = 0;  // shortest projected side / cells, as PredictTagVisibility measures it
  bool detected = false;
};

TEST(TagSizeLimit, MinCellPxIsWhereTheDetectorBecomesReliable) {
  std::mt19937 rng(71);
  std::uniform_real_distribution<double> spin(-M_PI, M_PI), shift(-0.3, 0.3), jitter(-0.05, 0.05);
  const double tilts_deg[] = {0, 45, 60, 70};
  const int trials = test_world::SanitizedCount(6, 2);
  TagDetector detector;  // the pipeline's full detection: decimation 1, margin 15, at most 1 corrected bit
  std::vector<Sample> samples;
  for (double tilt_deg : tilts_deg) {
    const double tilt = tilt_deg * M_PI / 180;
    for (int level = 0; level <= 18; ++level) {
      const double target = 0.8 + 0.1 * level;
      for (int t = 0; t < trials; ++t) {
        Eigen::Isometry3d cMt = Eigen::Isometry3d::Identity();
        cMt.linear() = RotationFromRpy(M_PI + tilt, 0, spin(rng));
        // The foreshortened side spans about f size cos(tilt) / z: the distance for the wanted cell size.
        const double z = kCam.px * kSize * std::cos(tilt) / (kCells * (target + jitter(rng)));
        cMt.translation() = Eigen::Vector3d(shift(rng) * z * 160 / 600, shift(rng) * z * 120 / 600, z);
        TagMount mount;
        mount.size = kSize;
        VisibilityOptions none;
        none.min_cell_px = 0;
        if (PredictTagVisibility(kCam, Eigen::Isometry3d::Identity(), mount, kCells, cMt, {}, none) !=
            TagVisibility::kVisible) {
          continue;  // outside the image
        }
        double side = 1e300;
        const auto corners = TagCornersInTagFrame(kSize);
        for (int k = 0; k < 4; ++k) {
          side = std::min(side, (kCam.Project(cMt * corners[(k + 1) % 4]) - kCam.Project(cMt * corners[k])).norm());
        }
        RenderScene scene;
        scene.tags.push_back({"tag36h11", 0, kSize, cMt});
        RenderOptions ro;
        ro.blur_sigma = 0.5;
        ro.noise_stddev = 2;
        ro.seed = static_cast<std::uint32_t>(samples.size() + 1);
        const GrayImage image = Render(kCam, Eigen::Isometry3d::Identity(), scene, ro);
        bool found = false;
        for (const auto& obs : detector.Detect(image.view())) found = found || obs.id == 0;
        samples.push_back({side / kCells, found});
      }
    }
  }
  ASSERT_GT(samples.size(), 100u);
  // Detection rate per 0.2 px bin, and the smallest size from which every larger tag was detected.
  double reliable_from = 0;
  for (const auto& s : samples) {
    if (!s.detected) reliable_from = std::max(reliable_from, s.cell_px);
  }
  std::printf("px per cell | tags | detected\n");
  for (double lo = 0.6; lo < 2.8; lo += 0.2) {
    int n = 0, d = 0;
    for (const auto& s : samples) {
      if (s.cell_px >= lo && s.cell_px < lo + 0.2) {
        ++n;
        d += s.detected ? 1 : 0;
      }
    }
    if (n > 0) std::printf("%.1f-%.1f | %d | %d\n", lo, lo + 0.2, n, d);
  }
  const double min_cell_px = VisibilityOptions{}.min_cell_px;
  int expected = 0, expected_missed = 0, too_small = 0, too_small_detected = 0;
  for (const auto& s : samples) {
    if (s.cell_px >= min_cell_px) {
      ++expected;
      expected_missed += s.detected ? 0 : 1;
    } else {
      ++too_small;
      too_small_detected += s.detected ? 1 : 0;
    }
  }
  std::printf(
      "every tag detected from %.2f px per cell; min_cell_px %.2f: %d expected (%d missed), %d too small "
      "(%d of them detected)\n",
      reliable_from, min_cell_px, expected, expected_missed, too_small, too_small_detected);
  // A tag the pipeline expects is detected: the threshold sits above the largest miss.
  EXPECT_EQ(expected_missed, 0);
  EXPECT_GE(min_cell_px, reliable_from);
  // And not far above it: tags that can be tracked are not given up (within 0.3 px per cell of the measured limit).
  EXPECT_LE(min_cell_px, reliable_from + 0.3);
  // The sizes sampled straddle the limit: small tags are missed.
  EXPECT_GT(too_small - too_small_detected, 0);
}

}  // namespace
}  // namespace visco::vision

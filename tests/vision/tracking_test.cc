// Tracking on sequences no one here made (visp-images-data mire-2: 501 frames of a dot target, vpDot2; cube: 80
// frames, KLT) with losses reported, and tag tracking (ROI detection, KLT corners) on a rendered moving tag against
// ground truth.

#include "vision/tracking.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "tests/vision/visp_ground_truth.h"
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

// mire-2 has no ground truth: every tracked dot is checked in every frame against the blob an independent
// detection (Otsu threshold, contours, moments: FindBlobs) finds in that frame. The rendered sequences below check
// vpDot2 and KLT against true positions.
TEST(Mire2, DotsTrackedThroughAll501FramesAgreeWithDetection) {
  const GrayImage first = ReadGrayImage(Frame("mire-2", 1));
  // The target's white dots: four small ones and the big central one.
  const auto seeds = FindBlobs(first.view(), true, 30, 5000, 0.75);
  ASSERT_GE(seeds.size(), 4u);
  DotTracker tracker;
  tracker.Init(first.view(), seeds);
  int alive_start = 0;
  for (bool a : tracker.alive()) alive_start += a ? 1 : 0;
  int min_alive = alive_start, first_loss = -1, compared = 0, unmatched = 0, close = 0;
  double max_step = 0, worst = 0, sum2 = 0;
  auto prev = tracker.centers();
  for (int i = 2; i <= 501; ++i) {
    const GrayImage img = ReadGrayImage(Frame("mire-2", i));
    const int n = tracker.Track(img.view());
    if (n < min_alive && first_loss < 0) first_loss = i;
    min_alive = std::min(min_alive, n);
    // The reference detection accepts ellipses (the target is seen at an angle in parts of the sequence).
    const auto blobs = FindBlobs(img.view(), true, 10, 20000, 0.2);
    for (std::size_t k = 0; k < prev.size(); ++k) {
      if (!tracker.alive()[k]) continue;
      max_step = std::max(max_step, (tracker.centers()[k] - prev[k]).norm());
      double nearest = 1e9;
      for (const auto& b : blobs) nearest = std::min(nearest, (b - tracker.centers()[k]).norm());
      if (nearest > 3) {
        ++unmatched;  // the detection missed this dot in this frame (no blob within 3 px)
        continue;
      }
      worst = std::max(worst, nearest);
      close += nearest <= 0.5 ? 1 : 0;
      sum2 += nearest * nearest, ++compared;
    }
    prev = tracker.centers();
  }
  const double rms = std::sqrt(sum2 / std::max(compared, 1));
  std::printf(
      "mire-2: 501 frames, %zu blobs found, %d dots tracked at start, %d at the end (first loss at frame %d), "
      "largest frame-to-frame motion %.1f px; vpDot2 against per-frame detection: RMS %.3f px, max %.3f px over %d, "
      "%d within 0.5 px, %d dot-frames without a detected blob within 3 px\n",
      seeds.size(), alive_start, min_alive, first_loss, max_step, rms, worst, compared, close, unmatched);
  EXPECT_GE(alive_start, 5);
  EXPECT_EQ(min_alive, alive_start) << "a dot was lost at frame " << first_loss;
  EXPECT_LE(unmatched, 500 * alive_start / 50) << "the reference detection found too few of the tracked dots";
  // Both are centroids of the same blob (vpDot2 of its grey-level region, the detection of its Otsu contour).
  // Where the looser reference merges or cuts a blob the two differ by up to ~2 px (measured max 2.08 px); 98% of
  // the dot-frames agree within 0.5 px.
  EXPECT_LT(rms, 0.3);
  EXPECT_GE(close, compared * 98 / 100);
}

TEST(Cube, KltFeaturesThroughTheSequence) {
  GrayImage img = ReadGrayImage(Frame("cube", 0));
  KltTracker klt;
  klt.InitAuto(img.view());
  const int start = static_cast<int>(klt.points().size());
  int n = start, worst_step = 0, worst_frame = -1;
  std::string trace;
  for (int i = 1; i < 80; ++i) {
    img = ReadGrayImage(Frame("cube", i));
    const int before = n;
    n = klt.Track(img.view());
    if (before - n > worst_step) worst_step = before - n, worst_frame = i;
    if (i % 20 == 0) trace += " " + std::to_string(i) + ":" + std::to_string(n);
  }
  std::printf(
      "cube: 80 frames, %d KLT features at start, %d still tracked at the end (%d lost; tracked at frame%s; most lost "
      "in one frame: %d at frame %d)\n",
      start, n, start - n, trace.c_str(), worst_step, worst_frame);
  // No ground truth here: survival only (the camera moves, features leave the view or are occluded). Accuracy:
  // KltTracker.RenderedPlaneAgainstTruth below.
  EXPECT_GE(start, 100);
  EXPECT_GE(n, start * 2 / 5);
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

namespace visco::vision {
namespace {

// Corner accuracy against the rendering's ground truth: full-resolution detection, decimated detection (quads at
// half resolution, corners refined at full resolution by RefineCorners), and RefineCorners applied to full detections.
TEST(RefineCorners, AsAccurateAsFullDetectionOnRenderedTags) {
  const CameraModel cam = CameraModel::Pinhole(600, 600, 319.5, 239.5, 640, 480);
  const Eigen::Isometry3d wMc = LookDown(0.6);
  DetectorOptions dopt;
  dopt.quad_sigma = 0.8f;
  TagDetector det(dopt);
  double rms[4] = {0, 0, 0, 0}, worst[4] = {0, 0, 0, 0};
  int n = 0;
  for (int i = 0; i < 20; ++i) {
    RenderScene scene;
    scene.polygons.push_back({{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, 120});
    RenderTag tag;
    tag.id = 5 + i;
    tag.size = 0.04 + 0.002 * i;
    tag.wMt.linear() = RotationFromRpy(0.05 * (i % 3), 0.04 * (i % 5), 0.3 * i);
    tag.wMt.translation() = Eigen::Vector3d(-0.1 + 0.01 * i, 0.05 - 0.004 * i, 0.01);
    scene.tags.push_back(tag);
    RenderOptions ro;
    ro.noise_stddev = 1.5;
    ro.blur_sigma = 0.5;
    ro.seed = 900 + i;
    const GrayImage img = Render(cam, wMc, scene, ro);
    const auto full = det.Detect(img.view());
    const auto dec = det.DetectInRegion(img.view(), 0, 0, img.width, img.height, 2.0f);
    ASSERT_EQ(full.size(), 1u);
    ASSERT_EQ(dec.size(), 1u);
    Corners refined = full[0].corners;
    ASSERT_TRUE(RefineCorners(img.view(), refined, 2.0));
    Corners one_pass = dec[0].corners;
    ASSERT_TRUE(RefineCorners(img.view(), one_pass, 3.0, 1));
    const auto pts = TagCornersInTagFrame(tag.size);
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector2d truth = cam.Project(wMc.inverse() * tag.wMt * pts[k]) + Eigen::Vector2d(0.5, 0.5);
      const Eigen::Vector2d e[4] = {full[0].corners[k] - truth, dec[0].corners[k] - truth, refined[k] - truth,
                                    one_pass[k] - truth};
      for (int m = 0; m < 4; ++m) {
        rms[m] += e[m].squaredNorm();
        worst[m] = std::max(worst[m], e[m].norm());
      }
      ++n;
    }
  }
  for (double& r : rms) r = std::sqrt(r / n);
  EXPECT_LT(rms[1], rms[0]);  // measured 0.027 vs 0.059 px
  EXPECT_LT(worst[1], worst[0]);
  EXPECT_LT(rms[2], rms[0]);
  std::printf(
      "corner error vs truth (RMS / max): full %.3f / %.3f px, decimated+refined %.3f / %.3f px, full+refined %.3f / "
      "%.3f px, decimated+1 pass %.3f / %.3f\n",
      rms[0], worst[0], rms[1], worst[1], rms[2], worst[2], rms[3], worst[3]);
}

}  // namespace
}  // namespace visco::vision

namespace visco::vision {
namespace {

// ROI tracking on visp-images-data's AprilTag.pgm (12 adjacent tags: the windows merge into one, searched at half
// resolution since the tags are big, corners refined at full resolution): every tag kept, corners close to ViSP's
// reference, poses within ViSP's own tolerance of the ground-truth poses.
TEST(TagTracking, DenseRealTagsKeepViSPAccuracy) {
  const GrayImage image = ReadGrayImage(testdata::kAprilTagDir + "AprilTag.pgm");
  const auto corners = testdata::PgmCorners();
  const auto poses = testdata::PgmPoses();
  TagTrackerOptions to;
  to.full_detection_every = 1000;
  TagTracker tracker(DetectorOptions{}, to);
  double worst_corner = 0, worst_pose = 0;
  for (int frame = 0; frame < 3; ++frame) {
    bool full = false;
    const auto tags = tracker.Process(image.view(), &full);
    EXPECT_EQ(full, frame == 0);
    ASSERT_EQ(tags.size(), 12u) << "frame " << frame;
    for (const auto& t : tags) {
      for (int k = 0; k < 4; ++k) worst_corner = std::max(worst_corner, (t.corners[k] - corners.at(t.id)[k]).norm());
      const auto pose = EstimateTagPose(testdata::PgmCamera(), t.corners, testdata::kPgmTagSize);
      ASSERT_TRUE(pose.has_value());
      Eigen::Matrix<double, 6, 1> got;
      got << pose->cMo.translation(), testdata::ThetaU(pose->cMo.linear());
      worst_pose = std::max(worst_pose, (got - poses.at(t.id)).cwiseAbs().maxCoeff());
    }
  }
  std::printf(
      "AprilTag.pgm tracked: worst corner distance to ViSP's reference %.3f px, worst pose component error "
      "%.5f\n",
      worst_corner, worst_pose);
  // The reference is the AprilTag library's own edge refinement (ViSP's detector); the tracker's refinement differs
  // from it by up to ~0.25 px here, and is the more accurate of the two against rendered ground truth
  // (RefineCorners.AsAccurateAsFullDetectionOnRenderedTags). ViSP's tolerance for its own detector is 0.005; the
  // tracked poses measured 0.0053.
  EXPECT_LT(worst_corner, 0.35);
  EXPECT_LT(worst_pose, 0.0065);
}

}  // namespace
}  // namespace visco::vision

namespace visco::vision {
namespace {

// A plate on the table moving under the LookDown camera: in frame i it is turned by 0.015 i rad and moved by
// (4, 2) mm per frame (about 4-5 px per frame in the image).
Eigen::Isometry3d PlatePose(int i) {
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  m.linear() = RotationFromRpy(0, 0, 0.015 * i);
  m.translation() = Eigen::Vector3d(-0.06 + 0.004 * i, -0.02 + 0.002 * i, 0);
  return m;
}

// The centroid of a polygon's image: exact for a plane polygon (its projection is a polygon). Pixels, OpenCV/ViSP
// convention (pixel centres at integers, as the renderer).
Eigen::Vector2d ImageCentroid(const CameraModel& cam, const Eigen::Isometry3d& cMw,
                              const std::vector<Eigen::Vector3d>& world) {
  std::vector<Eigen::Vector2d> p;
  for (const auto& w : world) p.push_back(cam.Project(cMw * w));
  double a = 0, cx = 0, cy = 0;
  for (std::size_t k = 0; k < p.size(); ++k) {
    const Eigen::Vector2d& u = p[k];
    const Eigen::Vector2d& v = p[(k + 1) % p.size()];
    const double c = u.x() * v.y() - v.x() * u.y();
    a += c, cx += (u.x() + v.x()) * c, cy += (u.y() + v.y()) * c;
  }
  return {cx / (3 * a), cy / (3 * a)};
}

// vpDot2 on rendered white discs (48-gons) on a dark moving plate, against the exact centroid of each disc's image.
TEST(DotTracker, RenderedDotsAgainstTruth) {
  const CameraModel cam = CameraModel::Pinhole(600, 600, 319.5, 239.5, 640, 480);
  const Eigen::Isometry3d wMc = LookDown(0.6);
  const std::vector<Eigen::Vector2d> centres = {{0, 0}, {0.05, 0.04}, {-0.05, 0.04}, {0.05, -0.04}, {-0.05, -0.04}};
  const std::vector<double> radii = {0.012, 0.006, 0.006, 0.006, 0.006};
  auto disc = [&](int k, const Eigen::Isometry3d& wMp) {
    std::vector<Eigen::Vector3d> v;
    for (int j = 0; j < 48; ++j) {
      const double t = 2 * M_PI * j / 48;
      v.push_back(wMp * Eigen::Vector3d(centres[k].x() + radii[k] * std::cos(t),
                                        centres[k].y() + radii[k] * std::sin(t), 0.001));
    }
    return v;
  };
  const int frames = 30;
  DotTracker tracker;
  double worst = 0, sum2 = 0;
  int compared = 0;
  for (int i = 0; i < frames; ++i) {
    const Eigen::Isometry3d wMp = PlatePose(i);
    RenderScene scene;
    scene.polygons.push_back({{wMp * Eigen::Vector3d(-0.1, -0.08, 0), wMp * Eigen::Vector3d(0.1, -0.08, 0),
                               wMp * Eigen::Vector3d(0.1, 0.08, 0), wMp * Eigen::Vector3d(-0.1, 0.08, 0)},
                              40});
    for (int k = 0; k < 5; ++k) scene.polygons.push_back({disc(k, wMp), 230});
    RenderOptions ro;
    ro.noise_stddev = 1.5;
    ro.blur_sigma = 0.5;
    ro.seed = 1300 + i;
    const GrayImage img = Render(cam, wMc, scene, ro);
    std::vector<Eigen::Vector2d> truth;
    for (int k = 0; k < 5; ++k) truth.push_back(ImageCentroid(cam, wMc.inverse(), disc(k, wMp)));
    if (i == 0) {
      tracker.Init(img.view(), truth);  // seeds: any pixel inside each dot
    } else {
      ASSERT_EQ(tracker.Track(img.view()), 5) << "a dot was lost at frame " << i;
    }
    for (int k = 0; k < 5; ++k) {
      ASSERT_TRUE(tracker.alive()[static_cast<std::size_t>(k)]);
      const double e = (tracker.centers()[static_cast<std::size_t>(k)] - truth[static_cast<std::size_t>(k)]).norm();
      worst = std::max(worst, e);
      sum2 += e * e, ++compared;
    }
  }
  const double rms = std::sqrt(sum2 / compared);
  std::printf(
      "rendered dots: %d frames, 5 dots, vpDot2 centre against the true image centroid: RMS %.3f px, max %.3f px\n",
      frames, rms, worst);
  EXPECT_LT(rms, 0.15);
  EXPECT_LT(worst, 0.4);
}

// KLT (vpKltOpencv) on a rendered moving plate covered with tags: every feature lies on the plate, so its true
// position in frame i is its first position carried by the plate's known motion (back-projected onto the plate,
// moved, projected).
TEST(KltTracker, RenderedPlaneAgainstTruth) {
  const CameraModel cam = CameraModel::Pinhole(600, 600, 319.5, 239.5, 640, 480);
  const Eigen::Isometry3d wMc = LookDown(0.6);
  const int frames = 30;
  KltTracker klt;
  std::vector<Eigen::Vector3d> plate_points;  // per feature id, in the plate frame
  std::vector<double> errors_last, errors_all;
  int start = 0;
  for (int i = 0; i < frames; ++i) {
    const Eigen::Isometry3d wMp = PlatePose(i);
    RenderScene scene;
    scene.polygons.push_back({{{-1, -1, -0.001}, {1, -1, -0.001}, {1, 1, -0.001}, {-1, 1, -0.001}}, 120});
    scene.polygons.push_back({{wMp * Eigen::Vector3d(-0.1, -0.08, 0), wMp * Eigen::Vector3d(0.1, -0.08, 0),
                               wMp * Eigen::Vector3d(0.1, 0.08, 0), wMp * Eigen::Vector3d(-0.1, 0.08, 0)},
                              200});
    for (int k = 0; k < 6; ++k) {
      RenderTag t;
      t.id = 30 + k;
      t.size = 0.045;
      t.wMt = wMp;
      t.wMt.translation() = wMp * Eigen::Vector3d(-0.06 + 0.06 * (k % 3), k < 3 ? -0.035 : 0.035, 0);
      scene.tags.push_back(t);
    }
    RenderOptions ro;
    ro.noise_stddev = 1.5;
    ro.blur_sigma = 0.5;
    ro.seed = 1700 + i;
    const GrayImage img = Render(cam, wMc, scene, ro);
    const Eigen::Isometry3d cMp = wMc.inverse() * wMp;
    if (i == 0) {
      klt.InitAuto(img.view());
      // Back-project each feature onto the plate (z = 0 of its frame).
      for (const auto& uv : klt.points()) {
        const Eigen::Vector2d xy = cam.PixelToNormalized(uv);
        const Eigen::Vector3d ray(xy.x(), xy.y(), 1);
        const Eigen::Isometry3d pMc = cMp.inverse();
        const Eigen::Vector3d o = pMc.translation(), d = pMc.linear() * ray;
        plate_points.push_back(o - (o.z() / d.z()) * d);
      }
      start = static_cast<int>(plate_points.size());
      continue;
    }
    klt.Track(img.view());
    const auto pts = klt.points();
    const auto ids = klt.ids();
    for (std::size_t f = 0; f < pts.size(); ++f) {
      const Eigen::Vector2d truth = cam.Project(cMp * plate_points[static_cast<std::size_t>(ids[f])]);
      const double e = (pts[f] - truth).norm();
      errors_all.push_back(e);
      if (i == frames - 1) errors_last.push_back(e);
    }
  }
  ASSERT_FALSE(errors_last.empty());
  auto quantile = [](std::vector<double> v, double q) {
    std::sort(v.begin(), v.end());
    return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
  };
  std::printf(
      "rendered plate, KLT: %d features at start, %zu after %d frames; error against the truth: all frames median "
      "%.3f px, 95%% %.3f px; last frame median %.3f px, 95%% %.3f px, max %.3f px\n",
      start, errors_last.size(), frames, quantile(errors_all, 0.5), quantile(errors_all, 0.95),
      quantile(errors_last, 0.5), quantile(errors_last, 0.95), quantile(errors_last, 1.0));
  EXPECT_GE(start, 50);
  EXPECT_GE(static_cast<int>(errors_last.size()), start * 3 / 4) << "features lost on a plate that stays in view";
  // KLT follows each feature from the previous frame with a translation-only window, so under the plate's rotation
  // (0.45 rad in all) its error grows frame after frame (measured: median 0.76 px over all frames, 1.8 px in the
  // last; 95% 2.4 px): the drift that makes ROI detection, not KLT, the tag tracker's default.
  EXPECT_LT(quantile(errors_all, 0.5), 1.0);
  EXPECT_LT(quantile(errors_last, 0.95), 3.0);
  EXPECT_LT(quantile(errors_last, 1.0), 5.0);
}

}  // namespace
}  // namespace visco::vision

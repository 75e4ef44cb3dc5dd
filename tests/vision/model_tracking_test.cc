// The robot's model-based tracker (TagTrackingMode::kModelBased: ViSP's vpMbGenericTracker on the robot prism's
// edges, started from the tags' pose) against ROI re-detection (kRoiDetection), on rendered sequences with ground
// truth: motion blur at demo speeds, the robot's tag partly hidden by an obstacle, tags at grazing angles,
// a lighting change, the robot sliding along an obstacle. Per mode: CM-vertex image error, event timing (frames
// between the true and the reported crossing) and signed-distance error, loss rate, latency. The table is printed;
// the checks are on the model-based mode's accuracy against the truth. docs/vision.md, "Model-based tracking of the
// robot".

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "tests/vision/demo_world.h"
#include "tests/vision/sanitized_count.h"
#include "vision/camera.h"
#include "vision/features.h"
#include "vision/model_tracker.h"
#include "vision/object_model.h"
#include "vision/pipeline.h"
#include "vision/tag_renderer.h"

namespace visco::vision {
namespace {

using test_world::Planar;

// A rendered sequence and its truth.
struct Sequence {
  std::string name;
  CameraModel camera = test_world::kDemoCamera;
  Eigen::Isometry3d wMc = Eigen::Isometry3d::Identity();
  ObjectModels models;
  std::vector<Eigen::Isometry3d> wMo;              // obstacles (they stand still)
  std::function<Eigen::Isometry3d(double)> robot;  // robot pose at (fractional) frame t
  int frames = 0;
  double blur = 0.6, noise = 1.5;
  double exposure = 0;                        // motion blur: the shutter is open for this fraction of a frame
  std::function<double(int)> gain = nullptr;  // lighting: grey levels scaled by gain(i)
  std::vector<GrayImage> images;
};

GrayImage RenderAt(const Sequence& s, const Eigen::Isometry3d& wMr, int supersample) {
  RenderScene scene = test_world::TableScene();
  test_world::AddObject(scene, s.models.robot, wMr, 70, 60);
  for (std::size_t k = 0; k < s.models.obstacles.size(); ++k) {
    test_world::AddObject(scene, s.models.obstacles[k], s.wMo[k], 160, 140);
  }
  RenderOptions ro;
  ro.blur_sigma = s.blur;
  ro.noise_stddev = 0;  // added below, after the motion blur and the lighting
  ro.supersample = supersample;
  return Render(s.camera, s.wMc, scene, ro);
}

void RenderSequence(Sequence& s) {
  for (int i = 0; i < s.frames; ++i) {
    std::vector<double> acc;
    const int sub = s.exposure > 0 ? 4 : 1;  // poses across the exposure, centred on the frame's time
    for (int k = 0; k < sub; ++k) {
      const double t = i + (sub > 1 ? s.exposure * (static_cast<double>(k) / (sub - 1) - 0.5) : 0.0);
      const GrayImage im = RenderAt(s, s.robot(t), sub > 1 ? 2 : 4);
      if (acc.empty()) acc.assign(im.pixels.size(), 0.0);
      for (std::size_t p = 0; p < acc.size(); ++p) acc[p] += im.pixels[p];
    }
    std::mt19937 rng(9000 + static_cast<unsigned>(i) + 100 * static_cast<unsigned>(s.name.size()));
    std::normal_distribution<double> noise(0, s.noise);
    const double g = s.gain ? s.gain(i) : 1.0;
    GrayImage out(s.camera.width, s.camera.height);
    for (std::size_t p = 0; p < acc.size(); ++p) {
      out.pixels[p] = static_cast<std::uint8_t>(std::clamp(std::lround(g * acc[p] / sub + noise(rng)), 0L, 255L));
    }
    s.images.push_back(std::move(out));
  }
}

// Per mode, over a sequence.
struct Figures {
  int frames = 0, estimates = 0, wrong = 0, model_used = 0;
  double cm_sum = 0, cm_max = 0;
  int cm_n = 0;
  double d_abs_sum = 0;
  int d_n = 0;
  std::vector<int> crossing_error;  // per event pair with a true crossing: reported - true (frames); 1000: none
  double ms_sum = 0, ms_max = 0;
  // Is the stated uncertainty right? In frames whose measured pose is the model-based tracker's (`tracked`) and in
  // the others (`tags`): the pose's normalised error e^T C^-1 e against the truth (6 degrees of freedom: mean 6, above
  // 16.8 in 1 % of the frames if C is right), and the signed distances' errors in units of their stated stddev.
  struct Consistency {
    int poses = 0, poses_over = 0, d_n = 0, d_over = 0;
    double nees_sum = 0, nees_max = 0, z_max = 0;
    double nees_mean() const { return poses > 0 ? nees_sum / poses : 0; }
  } tracked, tags;
  double cm_mean() const { return cm_n > 0 ? cm_sum / cm_n : 0; }
  double d_mean() const { return d_n > 0 ? d_abs_sum / d_n : 0; }
};

constexpr double kWrongPx = 2.0;  // a CM vertex farther than this from the truth counts as a wrong estimate

// A mode as the test runs it.
struct Config {
  const char* name;
  TagTrackingMode mode;
  bool gated;  // kModelBased: the tracked pose must pass ModelTrackerOptions' gates (the default); false: always used
};

Figures RunMode(const Sequence& s, const Config& c) {
  PipelineOptions o;
  o.detector.quad_sigma = 0.8f;
  o.tracker.mode = c.mode;
  if (!c.gated) {
    o.model_tracker.max_rms_px = 1e9;
    o.model_tracker.tag_gate_px = 1e9;
  }
  VisionPipeline pipeline(s.camera, s.wMc, s.models, o);
  Figures r;
  const std::size_t pairs = s.models.events.size();
  std::vector<int> reported(pairs, -1);
  std::vector<std::vector<double>> true_d(pairs);
  for (int i = 0; i < s.frames; ++i) {
    Frame f;
    f.seq = i;
    f.utime = 1'000'000 + static_cast<std::int64_t>(i) * 33'333;
    f.image = s.images[static_cast<std::size_t>(i)];
    const auto t0 = std::chrono::steady_clock::now();
    const PipelineOutput out = pipeline.Process(f, f.utime);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    r.ms_sum += ms;
    r.ms_max = std::max(r.ms_max, ms);
    ++r.frames;
    const Eigen::Isometry3d wMr = s.robot(i);
    const Eigen::Isometry3d cMr = s.wMc.inverse() * wMr;
    for (std::size_t k = 0; k < pairs; ++k) {
      const EventPair& ev = s.models.events[k];
      true_d[k].push_back(SignedImageDistance(s.camera, s.wMc, s.models.robot, cMr, ev.cm_vertex,
                                              s.models.obstacles[ev.obstacle], s.wMc.inverse() * s.wMo[ev.obstacle],
                                              ev.vertex));
    }
    const FrameFeatures& ff = pipeline.features().last();
    r.model_used += out.model.used ? 1 : 0;
    // The bus says whose pose it is (object_pose_t.model_tracked): the robot's entry comes first.
    if (ff.robot_pose.valid) {
      EXPECT_FALSE(out.poses.poses.empty());
      if (!out.poses.poses.empty()) {
        EXPECT_EQ(out.poses.poses[0].model_tracked != 0, out.model.used) << i;
      }
    }
    Figures::Consistency& cons = ff.robot_pose.model_tracked ? r.tracked : r.tags;
    if (ff.robot_pose.valid) {
      // The error as cov_cMo parametrises it: R_measured = Exp(w) R_true, t_measured = t_true + v.
      const Eigen::AngleAxisd w(ff.robot_pose.cMo_measured.linear() * cMr.linear().transpose());
      Eigen::Matrix<double, 6, 1> e;
      e << w.angle() * w.axis(), ff.robot_pose.cMo_measured.translation() - cMr.translation();
      const double nees = e.dot(ff.robot_pose.cov_cMo_measured.ldlt().solve(e));
      ++cons.poses;
      cons.nees_sum += nees;
      cons.nees_max = std::max(cons.nees_max, nees);
      cons.poses_over += nees > 16.81 ? 1 : 0;
    }
    for (std::size_t k = 0; k < pairs && k < ff.pairs.size(); ++k) {
      if (!ff.pairs[k].valid || ff.pairs[k].stddev_px <= 0) continue;
      const double z = std::abs(ff.pairs[k].signed_distance_px - true_d[k].back()) / ff.pairs[k].stddev_px;
      ++cons.d_n;
      cons.d_over += z > 3 ? 1 : 0;
      cons.z_max = std::max(cons.z_max, z);
    }
    if (!ff.robot.valid || ff.cm_images.size() != s.models.robot.polygon.size()) continue;
    ++r.estimates;
    double worst = 0;
    for (std::size_t k = 0; k < s.models.robot.polygon.size(); ++k) {
      const Eigen::Vector2d& v = s.models.robot.polygon[k];
      const double e =
          (ff.cm_images[k] - s.camera.ProjectIdeal(cMr * Eigen::Vector3d(v.x(), v.y(), s.models.robot.height))).norm();
      r.cm_sum += e, ++r.cm_n;
      worst = std::max(worst, e);
    }
    r.cm_max = std::max(r.cm_max, worst);
    r.wrong += worst > kWrongPx ? 1 : 0;
    for (std::size_t k = 0; k < pairs && k < ff.pairs.size(); ++k) {
      if (!ff.pairs[k].valid) continue;
      r.d_abs_sum += std::abs(ff.pairs[k].signed_distance_px - true_d[k].back()), ++r.d_n;
      const auto& e = out.events.events[k];
      if (e.crossed && e.state != visco::visual_event_t::STATE_ON_LINE && reported[k] < 0) {
        reported[k] = i;
      }
    }
  }
  for (std::size_t k = 0; k < pairs; ++k) {
    int truth = -1;
    for (int i = 1; i < s.frames; ++i) {
      if ((true_d[k][i] > 0) != (true_d[k][i - 1] > 0)) truth = i;
    }
    if (truth > 0) r.crossing_error.push_back(reported[k] >= 0 ? reported[k] - truth : 1000);
  }
  return r;
}

// The demo world (data/vision/demo_objects.json, demo_extrinsics.json).
Sequence DemoWorld(const std::string& name) {
  Sequence s;
  s.name = name;
  s.models = LoadObjectModels("data/vision/demo_objects.json");
  s.wMc = LoadExtrinsics("data/vision/demo_extrinsics.json");
  s.wMo = {Planar(0.02, 0.12, 0.3)};
  return s;
}

// The path of TrackingWithMotion (tests/vision/tracking_motion_test.cc): 4.8 mm and 3.8 mrad per frame, about 6 px
// per frame in the image (twice the demo's), across the VC lines of the block's vertices 0 and 3.
Eigen::Isometry3d DemoPath(double t) {
  const double step = 0.3 / 63;
  return Planar(-0.16 + step * t, 0.01 * std::sin(0.1 * t), 0.1 + 0.8 * step * t);
}

std::vector<Sequence> Sequences() {
  std::vector<Sequence> out;
  {
    // Motion blur: the shutter open for the whole frame (about 6 px of blur), on the demo path around the crossings.
    Sequence s = DemoWorld("motion blur");
    s.frames = test_world::SanitizedCount(30, 12);
    const int n = s.frames;  // the last frames of the path up to just past the crossings (frames 26 and 27)
    s.robot = [n](double t) { return DemoPath(t + 30 - n); };
    s.exposure = 1.0;
    out.push_back(std::move(s));
  }
  {
    // A pillar (an obstacle of the models, with its tag) in front of the robot's path hides part of its tag.
    Sequence s = DemoWorld("tag partly occluded");
    ObjectModel pillar;
    pillar.id = "pillar";
    pillar.polygon = {{-0.0125, -0.01}, {0.0125, -0.01}, {0.0125, 0.01}, {-0.0125, 0.01}};
    pillar.height = 0.13;
    TagMount tag;
    tag.id = 2;
    tag.size = 0.018;
    tag.oMt.translation() = Eigen::Vector3d(0, 0, pillar.height);
    pillar.tags = {tag};
    s.models.obstacles.push_back(pillar);
    s.wMo.push_back(Planar(0.0, -0.07, 0));
    s.frames = test_world::SanitizedCount(24, 12);
    const double step = 0.24 / (s.frames - 1);
    s.robot = [step](double t) { return Planar(-0.12 + step * t, 0.0, 0.1 + 0.002 * t); };
    out.push_back(std::move(s));
  }
  {
    // A low camera (18 cm above the table): the robot drives away from it, its top tag seen ever more obliquely
    // (elevation 20 -> 13 degrees, about 2.9 -> 1.2 px per cell), its sides nearly face-on.
    Sequence s = DemoWorld("grazing tags");
    const Eigen::Vector3d f = Eigen::Vector3d(0, 1, -0.28).normalized(), r(1, 0, 0);
    s.wMc.linear().col(0) = r;
    s.wMc.linear().col(1) = f.cross(r);
    s.wMc.linear().col(2) = f;
    s.wMc.translation() = Eigen::Vector3d(0.0, -0.5, 0.18);
    s.wMo = {Planar(0.12, 0.05, 0.0)};
    s.frames = test_world::SanitizedCount(24, 12);
    const double step = 0.3 / (s.frames - 1);
    s.robot = [step](double t) { return Planar(-0.05 + 0.2 * step * t, step * t, 0.3 + 0.5 * step * t); };
    out.push_back(std::move(s));
  }
  {
    // The light dims: grey levels scaled from 1 to 0.3 over the sequence (the demo path).
    Sequence s = DemoWorld("lighting change");
    s.frames = test_world::SanitizedCount(24, 12);
    const int n = s.frames;
    s.robot = [n](double t) { return DemoPath(t + 34 - n); };
    s.gain = [n](int i) { return 1.0 - 0.7 * i / (n - 1); };
    out.push_back(std::move(s));
  }
  {
    // The robot slides along the block's front face (in contact), across the VC line of its vertex 0.
    Sequence s = DemoWorld("sliding along obstacle");
    s.wMo = {Planar(0.0, 0.05, 0.0)};
    s.frames = test_world::SanitizedCount(24, 12);
    const double step = 0.15 / (s.frames - 1);
    s.robot = [step](double t) { return Planar(-0.1 + step * t, 0.01, 0.0); };
    out.push_back(std::move(s));
  }
  return out;
}

std::string Crossings(const Figures& r) {
  std::string s;
  for (int e : r.crossing_error) s += (s.empty() ? "" : ", ") + (e == 1000 ? std::string("none") : std::to_string(e));
  return s.empty() ? "-" : s;
}

// The comparison table (docs/vision.md): ROI re-detection, the model-based mode as configured by default (its pose
// used only where it passes the gates), and the model-based tracker's pose used whenever it has one (its own
// accuracy). Checked against the truth: the model-based mode never makes the CM vertices worse than the gates allow,
// and the tracker's own pose is as accurate as measured (ViSP 3.5's moving edges on this small prism: about 2 px).
TEST(ModelTracking, AgainstRoiDetectionOnRenderedSequences) {
  const auto t_start = std::chrono::steady_clock::now();
  std::vector<Sequence> seqs = Sequences();
  for (auto& s : seqs) RenderSequence(s);
  const double render_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  std::printf("rendered %zu sequences in %.1f s\n", seqs.size(), render_s);
  std::printf(
      "| sequence | mode | frames | no estimate | wrong (> %.0f px) | CM vertex error mean / max (px) | |d| error "
      "mean (px) | crossing (frames late) | latency mean / max (ms) | frames with the edges' pose |\n",
      kWrongPx);
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  const Config configs[] = {{"roi (default)", TagTrackingMode::kRoiDetection, true},
                            {"mbt", TagTrackingMode::kModelBased, true},
                            {"mbt, ungated", TagTrackingMode::kModelBased, false}};
  for (const auto& s : seqs) {
    std::vector<Figures> figs;
    for (const Config& c : configs) {
      figs.push_back(RunMode(s, c));
      const Figures& r = figs.back();
      std::printf("| %s | %s | %d | %d | %d | %.3f / %.3f | %.3f | %s | %.1f / %.1f | %d |\n", s.name.c_str(), c.name,
                  r.frames, r.frames - r.estimates, r.wrong, r.cm_mean(), r.cm_max, r.d_mean(), Crossings(r).c_str(),
                  r.ms_sum / r.frames, r.ms_max, r.model_used);
    }
    for (size_t c = 0; c < figs.size(); ++c) {
      for (const auto* cons : {&figs[c].tags, &figs[c].tracked}) {
        if (cons->poses == 0) continue;
        std::printf(
            "  %s, %s, poses from %s: %d, NEES mean %.1f max %.1f, over chi2(6, 0.99) %d; pairs %d, |d error| "
            "> 3 stddev %d, max %.1f stddev\n",
            s.name.c_str(), configs[c].name, cons == &figs[c].tags ? "the tags" : "the edges", cons->poses,
            cons->nees_mean(), cons->nees_max, cons->poses_over, cons->d_n, cons->d_over, cons->z_max);
      }
    }
    const Figures &roi = figs[0], &mbt = figs[1], &own = figs[2];
    // The model-based mode: with the tags in view the edges' pose is used only within tag_gate_px (2 px) of the
    // tags' at the vertices, so the CM vertices are never much worse than ROI's; it never loses the robot where ROI
    // has it. Without tags (grazing, occluded) it goes on alone while its residual RMS stays below 1 px: measured, 2
    // such frames of the grazing sequence, both wrong (1.3 / 12.9 px), none in the occlusion.
    EXPECT_LE(mbt.frames - mbt.estimates, roi.frames - roi.estimates) << s.name;
    if (roi.estimates == roi.frames) {
      EXPECT_LT(mbt.cm_mean(), roi.cm_mean() + 0.5) << s.name;
      EXPECT_LT(mbt.cm_max, std::max(roi.cm_max, 0.5) + 2.5) << s.name;
    } else {
      EXPECT_LE(mbt.wrong, 4) << s.name;
    }
    // The tracker's own pose, started from the tags' pose in every frame that has one. Measured: mean CM vertex
    // error 1.3-1.9 px with the tags in view (motion blur, lighting, sliding), 25-110 times ROI's.
    if (roi.estimates == roi.frames) {
      EXPECT_EQ(own.estimates, own.frames) << s.name;
      EXPECT_LT(own.cm_mean(), 3.5) << s.name;
      EXPECT_LT(own.cm_max, 12.0) << s.name;
    }
    // Where the tags are lost it goes on alone (at most max_frames_without_tags frames): more estimates than ROI.
    EXPECT_GE(own.estimates, roi.estimates) << s.name;
    // The stated covariance of the edges' pose (ViSP's plus ModelTrackerOptions::vertex_stddev_px at the vertices)
    // holds where the mode uses it, and for the tracker's own pose while the tags are in view: no normalised pose
    // error beyond chi2(6) at 1 %. (ViSP's covariance alone: NEES 5e4-4e5.) Measured: gated 0.5 and 5.7 in the two
    // frames where the edges' pose was used; ungated with the tags in view, mean 2.7-3.2. Without the tags
    // (grazing: up to 16 frames of drift) the linear growth is too optimistic: mean 16, 7 of 24 beyond (docs).
    EXPECT_EQ(mbt.tracked.poses_over, 0) << s.name;
    if (roi.estimates == roi.frames) {
      EXPECT_EQ(own.tracked.poses_over, 0) << s.name;
    }
    // The tags' own covariance, for comparison (and as a check of it on these sequences).
    EXPECT_EQ(roi.tags.poses_over, 0) << s.name;
  }
}

// The generated CAD model and the tracker on their own: the robot's prism without its tag, seen face-on, tracked from
// a start 2 mm off: its top vertices within 1 px of the truth (measured 0.54 px).
TEST(ModelTracking, PrismWithoutTagFromAnOffsetStart) {
  Sequence s = DemoWorld("prism");
  s.models.robot.tags.clear();
  s.models.obstacles.clear();
  s.wMo.clear();
  const Eigen::Isometry3d wMr = Planar(0.0, 0.0, 0.0);
  const GrayImage im = RenderAt(s, wMr, 4);
  PrismModelTracker tracker(s.camera, s.models.robot);
  const Eigen::Isometry3d cMr = s.wMc.inverse() * wMr;
  Eigen::Isometry3d start = cMr;
  start.translation().x() += 0.002;
  const ModelTrackResult r = tracker.Track(im.view(), start);
  ASSERT_TRUE(r.valid) << r.failure;
  double worst = 0;
  for (const auto& v : s.models.robot.polygon) {
    const Eigen::Vector3d p(v.x(), v.y(), s.models.robot.height);
    worst = std::max(worst, (s.camera.ProjectIdeal(r.cMo * p) - s.camera.ProjectIdeal(cMr * p)).norm());
  }
  std::printf("prism alone: %d moving edges, RMS %.3f px, worst top vertex error %.3f px\n", r.edge_features, r.rms_px,
              worst);
  EXPECT_GT(r.edge_features, 60);
  EXPECT_LT(worst, 1.0);
  // The covariance is positive definite.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> es(r.cov_cMo);
  EXPECT_GT(es.eigenvalues().minCoeff(), 0);
  // The model: 8 points, the top and base and 4 sides, each face counter-clockwise seen from outside.
  const std::string cao = PrismCao(s.models.robot);
  EXPECT_NE(cao.find("\n4 4 5 6 7\n"), std::string::npos) << cao;
  EXPECT_NE(cao.find("4 3 2 1 0"), std::string::npos) << cao;
  EXPECT_NE(cao.find("4 0 1 5 4"), std::string::npos) << cao;
}

}  // namespace
}  // namespace visco::vision

// Objects with several tags (BM_TagPoses, BM_ObjectPoseFit, BM_ObjectPose): the joint fit per solver against the
// baseline of the object's tags' own poses, on a rendered box with 4 tags (tests/vision/multi_tag_pose_test.cc).
//
// Per-frame cost on 640x480 frames: full AprilTag detection (the baseline) against tracking between detections (ROI
// detection around the predicted corners; KLT on the corners), measured in the same run and on the same frames, with
// the ratio as a counter (goal: tracked frames cost <= 0.3x a full detection) and the accuracy of the tracked corners
// (against the full detection of the same frame, and against the data set's ground truth); the AprilTag C library
// against ViSP's vpDetectorAprilTag (time, corner and pose accuracy); and the event latency from frame arrival to the
// visual events being ready for publication.
//
// Frames (all 640x480):
//   0  visp-images-data AprilTag/AprilTag.pgm: 12 adjacent tags, real camera, ground-truth corners and poses;
//   1  a rendered scene: robot and obstacle tags moving (16 positions played back and forth), noise 1 grey level;
//   2  visp-images-data AprilTag/benchmark/640x480/tag36_11_640x480.png: 5 rendered tags, reference corners
//      (corners_tag36_11.txt, the AprilTag library's output) and true poses (cMo_<id>.txt).
// Counters ref_err_px: worst corner distance to the data set's reference corners (for AprilTag.pgm and the benchmark
// image those are the AprilTag library's own detections, made by ViSP).
// Run from the repository root (the rendered scene reads data/vision/).

#include <benchmark/benchmark.h>
#include <visp3/core/vpCameraParameters.h>
#include <visp3/core/vpHomogeneousMatrix.h>
#include <visp3/core/vpImage.h>
#include <visp3/detection/vpDetectorAprilTag.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <ctime>
#include <map>
#include <stdexcept>

#include "tests/vision/visp_ground_truth.h"
#include "vision/camera.h"
#include "vision/image.h"
#include "vision/multi_tag_pose.h"
#include "vision/object_model.h"
#include "vision/pipeline.h"
#include "vision/tag_renderer.h"
#include "vision/tracking.h"

namespace visco::vision {
namespace {

const CameraModel kCam = CameraModel::Pinhole(600, 600, 319.5, 239.5, 640, 480);
constexpr int kRendered = 16;

struct Frames {
  GrayImage pgm, bench;
  std::vector<GrayImage> rendered;  // kRendered consecutive positions
  ObjectModels models;
  Eigen::Isometry3d wMc;
  std::map<int, Corners> pgm_truth = testdata::PgmCorners();
  std::map<int, Corners> bench_truth = testdata::BenchmarkCorners();
  Frames() {
    pgm = ReadGrayImage(testdata::kAprilTagDir + "AprilTag.pgm");
    bench = ReadGrayImage(testdata::kBenchmarkDir + "tag36_11_640x480.png");
    models = LoadObjectModels("data/vision/demo_objects.json");
    wMc = LoadExtrinsics("data/vision/demo_extrinsics.json");
    for (int i = 0; i < kRendered; ++i) {
      RenderScene scene;
      scene.polygons.push_back({{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, 120});
      Eigen::Isometry3d wMr = Eigen::Isometry3d::Identity(), wMo = Eigen::Isometry3d::Identity();
      wMr.translation() = Eigen::Vector3d(-0.1 + 0.004 * i, 0, 0);
      wMo.translation() = Eigen::Vector3d(0.02, 0.12, 0);
      AddPrism(scene, models.robot.polygon, models.robot.height, wMr, 70, 60);
      AddPrism(scene, models.obstacles[0].polygon, models.obstacles[0].height, wMo, 160, 140);
      scene.tags.push_back({"tag36h11", 0, models.robot.tags[0].size, wMr * models.robot.tags[0].oMt});
      scene.tags.push_back({"tag36h11", 1, models.obstacles[0].tags[0].size, wMo * models.obstacles[0].tags[0].oMt});
      RenderOptions ro;
      ro.noise_stddev = 1;
      ro.seed = 3 + i;
      rendered.push_back(Render(kCam, wMc, scene, ro));
    }
  }
};

const Frames& GetFrames() {
  static const Frames f;
  return f;
}

DetectorOptions Detector(int which) {
  DetectorOptions d;
  d.quad_sigma = which == 1 ? 0.8f : 0.0f;  // the rendered frames carry pixel noise
  return d;
}

// Frame i of a set; the rendered positions are played back and forth (a smooth motion).
const GrayImage& Pick(int which, int i) {
  const Frames& f = GetFrames();
  if (which == 0) return f.pgm;
  if (which == 2) return f.bench;
  const int period = 2 * (kRendered - 1), k = i % period;
  return f.rendered[static_cast<std::size_t>(k < kRendered ? k : period - k)];
}

const std::map<int, Corners>* Truth(int which) {
  return which == 0 ? &GetFrames().pgm_truth : which == 2 ? &GetFrames().bench_truth : nullptr;
}

const char* SetName(int which) { return which == 0 ? "AprilTag.pgm" : which == 1 ? "rendered" : "bench36h11"; }

// CPU time of this thread: the machine is shared, wall time would count other processes.
double ThreadCpuSeconds() {
  timespec t;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// Largest corner distance of `tags` to `reference` (same id), and the number of reference tags found.
double MaxCornerError(const std::vector<TagObservation>& tags, const std::map<int, Corners>& reference, int* found) {
  double worst = 0;
  *found = 0;
  for (const auto& t : tags) {
    const auto it = reference.find(t.id);
    if (it == reference.end()) continue;
    ++*found;
    for (int k = 0; k < 4; ++k) worst = std::max(worst, (t.corners[k] - it->second[k]).norm());
  }
  return worst;
}

std::map<int, Corners> ById(const std::vector<TagObservation>& tags) {
  std::map<int, Corners> out;
  for (const auto& t : tags) out[t.id] = t.corners;
  return out;
}

void BM_FullDetection(benchmark::State& state) {
  const int which = static_cast<int>(state.range(0));
  TagDetector det(Detector(which));
  int i = 0, found = 0;
  double err = 0;
  for (auto _ : state) {
    const auto tags = det.Detect(Pick(which, i++).view());
    if (Truth(which) != nullptr) err = std::max(err, MaxCornerError(tags, *Truth(which), &found));
    benchmark::DoNotOptimize(tags);
  }
  if (Truth(which) != nullptr) {
    state.counters["ref_err_px"] = err;
    state.counters["found"] = found;
  }
  state.SetLabel(std::string(SetName(which)) + " apriltag-c");
}
BENCHMARK(BM_FullDetection)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

// ViSP's vpDetectorAprilTag on the same frames and with the same settings (quad_decimate 1, quad_sigma, sharpening
// 0.25, refined edges); its time includes nothing but detect() (the vpImage is filled outside the timing).
void BM_ViSPDetection(benchmark::State& state) {
  const int which = static_cast<int>(state.range(0));
  const DetectorOptions o = Detector(which);
  vpDetectorAprilTag det(vpDetectorAprilTag::TAG_36h11);
  det.setAprilTagQuadDecimate(o.quad_decimate);
  det.setAprilTagQuadSigma(o.quad_sigma);
  det.setAprilTagDecodeSharpening(o.decode_sharpening);
  det.setAprilTagNbThreads(1);
  vpImage<unsigned char> image;
  int i = 0, found = 0;
  double err = 0;
  for (auto _ : state) {
    state.PauseTiming();
    const GrayImage& g = Pick(which, i++);
    image.resize(static_cast<unsigned>(g.height), static_cast<unsigned>(g.width));
    std::memcpy(image.bitmap, g.pixels.data(), g.pixels.size());
    state.ResumeTiming();
    det.detect(image);
    if (Truth(which) != nullptr) {
      state.PauseTiming();
      std::vector<TagObservation> tags;
      const auto corners = det.getTagsCorners();
      const auto ids = det.getTagsId();
      for (std::size_t t = 0; t < ids.size(); ++t) {
        TagObservation obs;
        obs.id = ids[t];
        for (int k = 0; k < 4; ++k) obs.corners[k] = {corners[t][k].get_u(), corners[t][k].get_v()};
        tags.push_back(obs);
      }
      err = std::max(err, MaxCornerError(tags, *Truth(which), &found));
      state.ResumeTiming();
    }
  }
  if (Truth(which) != nullptr) {
    state.counters["ref_err_px"] = err;
    state.counters["found"] = found;
  }
  state.SetLabel(std::string(SetName(which)) + " vpDetectorAprilTag");
}
BENCHMARK(BM_ViSPDetection)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

// Pose accuracy against the benchmark image's true cMo: ours (IPPE + LM on the corners, AprilTag pixel convention
// corrected) against ViSP's getPose (homography + virtual visual servoing, its default), both on the corners of one
// detection. Counters: worst translation (m) and rotation (rad) error over the 5 tags; time per image for all poses.
void BM_PoseAccuracy(benchmark::State& state) {
  const bool visp = state.range(0) == 1;
  const CameraModel cam = testdata::BenchmarkCamera();
  vpCameraParameters vcam(cam.px, cam.py, cam.u0, cam.v0);
  vpDetectorAprilTag det(vpDetectorAprilTag::TAG_36h11);
  vpImage<unsigned char> image(static_cast<unsigned>(GetFrames().bench.height),
                               static_cast<unsigned>(GetFrames().bench.width));
  std::memcpy(image.bitmap, GetFrames().bench.pixels.data(), GetFrames().bench.pixels.size());
  det.detect(image);
  const auto ids = det.getTagsId();
  const auto corners = det.getTagsCorners();
  double et = 0, er = 0;
  for (auto _ : state) {
    for (std::size_t t = 0; t < ids.size(); ++t) {
      Eigen::Isometry3d cMo = Eigen::Isometry3d::Identity();
      const double size = testdata::BenchmarkTagSize(ids[t]);
      if (visp) {
        vpHomogeneousMatrix m;
        det.getPose(t, size, vcam, m);
        for (int r = 0; r < 4; ++r) {
          for (int c = 0; c < 4; ++c) cMo.matrix()(r, c) = m[static_cast<unsigned>(r)][static_cast<unsigned>(c)];
        }
      } else {
        Corners c;
        for (int k = 0; k < 4; ++k) c[k] = {corners[t][k].get_u(), corners[t][k].get_v()};
        const auto pose = EstimateTagPose(cam, c, size);
        if (pose) cMo = pose->cMo;
      }
      const Eigen::Isometry3d truth = testdata::BenchmarkCmo(ids[t]);
      et = std::max(et, (cMo.translation() - truth.translation()).norm());
      er = std::max(er, Eigen::AngleAxisd(cMo.linear().transpose() * truth.linear()).angle());
    }
  }
  state.counters["max_t_err_m"] = et;
  state.counters["max_r_err_rad"] = er;
  state.counters["tags"] = static_cast<double>(ids.size());
  state.SetLabel(visp ? "bench36h11 vpDetectorAprilTag::getPose" : "bench36h11 EstimateTagPose");
}
BENCHMARK(BM_PoseAccuracy)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// Full detection and tracking interleaved in one benchmark (thread CPU time), so the ratio compares like with like on
// a shared machine. Args: frame set, mode, ROI variant (0 one window per tag at full resolution, 1 merged windows,
// 2 merged windows decimated for big tags: the default). Counters: the ratio, the worst tracked corner's distance to
// the same frame's full detection (diff_px) and to the ground truth (truth_err_px), tags lost.
void BM_TrackedToFullRatio(benchmark::State& state) {
  const int which = static_cast<int>(state.range(0)), variant = static_cast<int>(state.range(2));
  TagDetector det(Detector(which));
  TagTrackerOptions o;
  o.mode = static_cast<TagTrackingMode>(state.range(1));
  o.full_detection_every = 1 << 30;
  o.merge_windows = variant >= 1;
  if (variant < 2) o.decimate_min_side_px = 0;
  TagTracker tracker(Detector(which), o);
  tracker.Process(Pick(which, 0).view());
  double full = 0, tracked = 0, diff = 0, truth_err = 0;
  int i = 1, full_detections = 0, lost = 0, found = 0;
  for (auto _ : state) {
    const double t0 = ThreadCpuSeconds();
    const auto reference = det.Detect(Pick(which, i).view());
    const double t1 = ThreadCpuSeconds();
    bool was_full = false;
    const auto tags = tracker.Process(Pick(which, i).view(), &was_full);
    const double t2 = ThreadCpuSeconds();
    full += t1 - t0;
    tracked += t2 - t1;
    full_detections += was_full ? 1 : 0;
    lost += static_cast<int>(tracker.lost_last().size());
    diff = std::max(diff, MaxCornerError(tags, ById(reference), &found));
    if (Truth(which) != nullptr) truth_err = std::max(truth_err, MaxCornerError(tags, *Truth(which), &found));
    ++i;
  }
  state.counters["full_detections"] = full_detections;
  state.counters["lost"] = lost;
  const double n = static_cast<double>(state.iterations());
  state.counters["full_ms"] = full * 1e3 / n;
  state.counters["tracked_ms"] = tracked * 1e3 / n;
  state.counters["ratio"] = tracked / full;
  state.counters["diff_px"] = diff;
  if (Truth(which) != nullptr) state.counters["ref_err_px"] = truth_err;
  if (which == 2) {  // pose accuracy of the last frame's tracked tags against the true cMo
    double et = 0, er = 0;
    for (const auto& t : tracker.Process(Pick(which, i).view())) {
      const auto pose = EstimateTagPose(testdata::BenchmarkCamera(), t.corners, testdata::BenchmarkTagSize(t.id));
      if (!pose) continue;
      const Eigen::Isometry3d truth = testdata::BenchmarkCmo(t.id);
      et = std::max(et, (pose->cMo.translation() - truth.translation()).norm());
      er = std::max(er, Eigen::AngleAxisd(pose->cMo.linear().transpose() * truth.linear()).angle());
    }
    state.counters["pose_err_mm"] = 1e3 * et;
    state.counters["pose_err_mrad"] = 1e3 * er;
  }
  const char* mode = o.mode == TagTrackingMode::kKltCorners ? " klt"
                     : variant == 0                         ? " roi per-tag"
                     : variant == 1                         ? " roi merged"
                                                            : " roi merged+decimated";
  state.SetLabel(std::string(SetName(which)) + mode);
}
constexpr int kRoi = static_cast<int>(TagTrackingMode::kRoiDetection);
constexpr int kKlt = static_cast<int>(TagTrackingMode::kKltCorners);
BENCHMARK(BM_TrackedToFullRatio)
    ->Args({0, kRoi, 0})
    ->Args({0, kRoi, 1})
    ->Args({0, kRoi, 2})
    ->Args({0, kKlt, 0})
    ->Args({1, kRoi, 0})
    ->Args({1, kRoi, 2})
    ->Args({1, kKlt, 0})
    ->Args({2, kRoi, 0})
    ->Args({2, kRoi, 2})
    ->Unit(benchmark::kMillisecond);

// Frame arrival to visual events ready (tracking + poses + features + messages), per frame.
void BM_EventLatency(benchmark::State& state) {
  const Frames& f = GetFrames();
  PipelineOptions po;
  po.detector = Detector(1);
  po.tracker.mode = static_cast<TagTrackingMode>(state.range(0));
  VisionPipeline pipeline(kCam, f.wMc, f.models, po);
  std::int64_t seq = 0;
  double latency = 0;
  Frame frame;
  for (auto _ : state) {
    state.PauseTiming();
    frame.seq = seq;
    frame.utime = 1'000'000 + 33'333 * seq;
    frame.image = Pick(1, static_cast<int>(seq));
    state.ResumeTiming();
    const PipelineOutput out = pipeline.Process(frame, NowUtime());
    latency += out.events.latency_s;
    ++seq;
  }
  state.counters["latency_ms"] = latency * 1e3 / static_cast<double>(state.iterations());
  state.SetLabel(std::string("rendered") + (po.tracker.mode == TagTrackingMode::kRoiDetection ? " roi" : " full"));
}
BENCHMARK(BM_EventLatency)
    ->Arg(static_cast<int>(TagTrackingMode::kDetectEveryFrame))
    ->Arg(static_cast<int>(TagTrackingMode::kRoiDetection))
    ->Unit(benchmark::kMillisecond);

// A box with four tags (two on top, one on each side face seen), rendered once; its tags' own poses.
struct BoxTags {
  CameraModel cam = kCam;
  std::vector<ObjectTagObservation> tags;
  BoxTags() {
    const ObjectModels m = ParseObjectModels(R"({
      "robot": {"id": "box", "polygon": [[-0.06, -0.06], [0.06, -0.06], [0.06, 0.06], [-0.06, 0.06]], "height": 0.08,
                "tags": [{"id": 10, "size": 0.04, "t": [-0.03, -0.025, 0.08], "rpy_deg": [0, 0, 0]},
                         {"id": 11, "size": 0.04, "t": [0.03, 0.03, 0.08], "rpy_deg": [0, 0, 30]},
                         {"id": 12, "size": 0.05, "t": [0, -0.06, 0.04], "rpy_deg": [90, 0, 0]},
                         {"id": 13, "size": 0.05, "t": [0.06, 0, 0.04], "rpy_deg": [90, 0, 90]}]}})",
                                             "box");
    const Eigen::Isometry3d wMc = LoadExtrinsics("data/vision/demo_extrinsics.json");
    Eigen::Isometry3d wMo = Eigen::Isometry3d::Identity();
    wMo.linear() = RotationFromRpy(0, 0, -0.75);
    wMo.translation() = Eigen::Vector3d(0.03, 0.08, 0);
    RenderScene scene;
    scene.polygons.push_back({{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, 120});
    AddPrism(scene, m.robot.polygon, m.robot.height, wMo, 200, 170);
    for (const auto& t : m.robot.tags) scene.tags.push_back({t.family, t.id, t.size, wMo * t.oMt});
    RenderOptions ro;
    ro.noise_stddev = 2;
    ro.blur_sigma = 0.6;
    TagDetector detector;
    const auto seen = detector.Detect(Render(kCam, wMc, scene, ro).view());
    for (const auto& t : m.robot.tags) {
      for (const auto& o : seen) {
        if (o.id != t.id) continue;
        ObjectTagObservation ot;
        ot.id = t.id;
        ot.corners = o.corners;
        ot.size = t.size;
        ot.oMt = t.oMt;
        ot.pose = *EstimateTagPose(kCam, o.corners, t.size);
        tags.push_back(ot);
      }
    }
    if (tags.size() != 4) throw std::runtime_error("the benchmark box: not all 4 tags detected");
  }
};

const BoxTags& GetBox() {
  static const BoxTags b;
  return b;
}

const char* SolverName(int s) { return s == 0 ? "OpenCV ITERATIVE" : s == 1 ? "OpenCV SQPNP" : "ViSP VIRTUAL_VS"; }

// Baseline: the four tags' own poses (what every frame computes anyway).
void BM_TagPoses(benchmark::State& state) {
  const BoxTags& b = GetBox();
  for (auto _ : state) {
    for (const auto& t : b.tags) benchmark::DoNotOptimize(EstimateTagPose(b.cam, t.corners, t.size));
  }
  state.SetLabel(std::to_string(b.tags.size()) + " tags");
}
BENCHMARK(BM_TagPoses)->Unit(benchmark::kMicrosecond);

// One joint fit over all four tags' corners from the first tag's pose.
void BM_ObjectPoseFit(benchmark::State& state) {
  const BoxTags& b = GetBox();
  const auto solver = static_cast<JointPoseSolver>(state.range(0));
  const std::vector<int> all{0, 1, 2, 3};
  const Eigen::Isometry3d start = b.tags[0].pose.cMo * b.tags[0].oMt.inverse();
  double rms = 0;
  for (auto _ : state) {
    Eigen::Isometry3d cMo = start;
    rms = FitObjectPose(b.cam, b.tags, all, solver, cMo);
    benchmark::DoNotOptimize(cMo);
  }
  state.counters["rms_px"] = rms;
  state.SetLabel(SolverName(static_cast<int>(state.range(0))));
}
BENCHMARK(BM_ObjectPoseFit)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

// The whole object pose: consensus over the tags' solutions, ambiguity rule, covariance.
void BM_ObjectPose(benchmark::State& state) {
  const BoxTags& b = GetBox();
  PoseOptions o;
  o.joint_solver = static_cast<JointPoseSolver>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(EstimateObjectPose(b.cam, b.tags, o, 0.1));
  state.SetLabel(SolverName(static_cast<int>(state.range(0))));
}
BENCHMARK(BM_ObjectPose)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace visco::vision

int main(int argc, char** argv) {
  visco::vision::GetFrames();  // read and render the frames before any timing
  visco::vision::GetBox();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

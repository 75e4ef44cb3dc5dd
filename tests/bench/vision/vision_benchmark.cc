// Per-frame cost on 640x480 frames: full AprilTag detection (the baseline) against tracking between detections (ROI
// detection around the last corners; KLT on the corners), measured in the same run, with the ratio as a counter
// (goal: tracked frames cost <= 0.3x a full detection); and the event latency from frame arrival to the visual
// events being ready for publication.
//
// Frames: visp-images-data's AprilTag.pgm (12 tags, real camera) and a rendered scene (robot + obstacle tags,
// noise 1 grey level).

#include <benchmark/benchmark.h>

#include <chrono>
#include <ctime>

#include "vision/camera.h"
#include "vision/image.h"
#include "vision/object_model.h"
#include "vision/pipeline.h"
#include "vision/tag_renderer.h"
#include "vision/tracking.h"

namespace visco::vision {
namespace {

const CameraModel kCam = CameraModel::Pinhole(600, 600, 319.5, 239.5, 640, 480);

struct Frames {
  GrayImage real;
  GrayImage synthetic[2];  // two consecutive positions, so that trackers have motion to follow
  ObjectModels models;
  Eigen::Isometry3d wMc;
  Frames() {
    real = ReadGrayImage("/usr/share/visp-images-data/ViSP-images/AprilTag/AprilTag.pgm");
    models = LoadObjectModels("data/vision/demo_objects.json");
    wMc = LoadExtrinsics("data/vision/demo_extrinsics.json");
    for (int i = 0; i < 2; ++i) {
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
      synthetic[i] = Render(kCam, wMc, scene, ro);
    }
  }
};

const Frames& GetFrames() {
  static const Frames f;
  return f;
}

DetectorOptions Detector(bool noisy) {
  DetectorOptions d;
  d.quad_sigma = noisy ? 0.8f : 0.0f;
  return d;
}

// CPU time of this thread: the machine is shared, wall time would count other processes.
double ThreadCpuSeconds() {
  timespec t;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

const GrayImage& Pick(int which, int i) { return which == 0 ? GetFrames().real : GetFrames().synthetic[i & 1]; }

std::string Label(int which, TagTrackingMode mode) {
  return std::string(which == 0 ? "AprilTag.pgm" : "rendered") + (mode == TagTrackingMode::kRoiDetection ? " roi"
                                                                  : mode == TagTrackingMode::kKltCorners ? " klt"
                                                                                                         : "");
}

void BM_FullDetection(benchmark::State& state) {
  const int which = static_cast<int>(state.range(0));
  TagDetector det(Detector(which == 1));
  int i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(det.Detect(Pick(which, i++).view()));
  state.SetLabel(Label(which, TagTrackingMode::kDetectEveryFrame));
}
BENCHMARK(BM_FullDetection)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Full detection and tracking interleaved in one benchmark (thread CPU time), so the ratio compares like with like on
// a shared machine.
void BM_TrackedToFullRatio(benchmark::State& state) {
  const int which = static_cast<int>(state.range(0));
  TagDetector det(Detector(which == 1));
  TagTrackerOptions o;
  o.mode = static_cast<TagTrackingMode>(state.range(1));
  o.full_detection_every = 1 << 30;
  TagTracker tracker(Detector(which == 1), o);
  tracker.Process(Pick(which, 0).view());
  double full = 0, tracked = 0;
  int i = 1, full_detections = 0;
  for (auto _ : state) {
    const double t0 = ThreadCpuSeconds();
    benchmark::DoNotOptimize(det.Detect(Pick(which, i).view()));
    const double t1 = ThreadCpuSeconds();
    bool was_full = false;
    benchmark::DoNotOptimize(tracker.Process(Pick(which, i).view(), &was_full));
    const double t2 = ThreadCpuSeconds();
    full += t1 - t0;
    tracked += t2 - t1;
    full_detections += was_full ? 1 : 0;
    ++i;
  }
  state.counters["full_detections"] = benchmark::Counter(full_detections);
  const double n = static_cast<double>(state.iterations());
  state.counters["full_ms"] = benchmark::Counter(full * 1e3 / n);
  state.counters["tracked_ms"] = benchmark::Counter(tracked * 1e3 / n);
  state.counters["ratio"] = benchmark::Counter(tracked / full);
  state.SetLabel(Label(which, o.mode));
}
BENCHMARK(BM_TrackedToFullRatio)
    ->Args({0, static_cast<int>(TagTrackingMode::kRoiDetection)})
    ->Args({0, static_cast<int>(TagTrackingMode::kKltCorners)})
    ->Args({1, static_cast<int>(TagTrackingMode::kRoiDetection)})
    ->Args({1, static_cast<int>(TagTrackingMode::kKltCorners)})
    ->Unit(benchmark::kMillisecond);

// Frame arrival to visual events ready (tracking + poses + features + messages), per frame.
void BM_EventLatency(benchmark::State& state) {
  const Frames& f = GetFrames();
  PipelineOptions po;
  po.detector = Detector(true);
  po.tracker.mode = static_cast<TagTrackingMode>(state.range(0));
  VisionPipeline pipeline(kCam, f.wMc, f.models, po);
  std::int64_t seq = 0;
  double latency = 0;
  Frame frame;
  for (auto _ : state) {
    state.PauseTiming();
    frame.seq = seq;
    frame.utime = 1'000'000 + 33'333 * seq;
    frame.image = f.synthetic[seq & 1];
    state.ResumeTiming();
    const PipelineOutput out = pipeline.Process(frame, NowUtime());
    latency += out.events.latency_s;
    ++seq;
  }
  state.counters["latency_ms"] = benchmark::Counter(latency * 1e3 / static_cast<double>(state.iterations()));
  state.SetLabel(Label(1, po.tracker.mode));
}
BENCHMARK(BM_EventLatency)
    ->Arg(static_cast<int>(TagTrackingMode::kDetectEveryFrame))
    ->Arg(static_cast<int>(TagTrackingMode::kRoiDetection))
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace visco::vision

BENCHMARK_MAIN();

// The simulated camera's rendering per 640x480 frame: Render() (the reference: every ray of every frame) against
// CachedRenderer (the fixed part rendered once; each frame re-casts only around the robot), on the default scene's
// world (data/sim/slot_*: the table, two obstacles and the robot, each with a tag), the robot moving 4 cm per frame
// near the goal as in `visco demo --slow-machine 8`. BM_CachedToReference times both on the same frames in the same
// run: counters ref_ms, cached_ms, their ratio, and identical = 1 when every frame was equal byte for byte.
// Arguments: supersample, effects (1: the demo's image noise 2 and blur 0.5 px; 0: neither).
// Run from the repository root (reads data/sim/); also run in the V4L2 VM, for the emulated CPU's figures.

#include <benchmark/benchmark.h>

#include <chrono>

#include "vision/camera.h"
#include "vision/object_model.h"
#include "vision/tag_renderer.h"

namespace visco::vision {
namespace {

struct World {
  CameraModel camera = LoadCamera("data/sim/slot_camera.xml");
  Eigen::Isometry3d wMc = LoadExtrinsics("data/sim/slot_extrinsics.json");
  ObjectModels models = LoadObjectModels("data/sim/slot_objects.json");
  RenderScene fixed;

  static void Add(RenderScene& scene, const ObjectModel& o, const Eigen::Isometry3d& wMo, std::uint8_t top,
                  std::uint8_t side) {
    AddPrism(scene, o.polygon, o.height, wMo, top, side);
    for (const auto& t : o.tags) scene.tags.push_back({t.family, t.id, t.size, wMo * t.oMt});
  }

  // The simulated camera's world (app/sim/camera.cc): the table under everything, then the obstacles.
  World() {
    fixed.polygons.push_back({{{-30, -30, 0}, {40, -30, 0}, {40, 40, 0}, {-30, 40, 0}}, 150});
    for (const auto& o : models.obstacles) Add(fixed, o, Eigen::Isometry3d::Identity(), 110, 70);
  }

  // Frame k: the robot 4 cm further along its way to the goal.
  RenderScene Robot(int k) const {
    RenderScene moving;
    Eigen::Isometry3d wMr = Eigen::Isometry3d::Identity();
    wMr.translation() = Eigen::Vector3d(4.1 + 0.04 * (k % 25), 1.8 - 0.02 * (k % 25), 0);
    Add(moving, models.robot, wMr, 190, 160);
    return moving;
  }

  static RenderScene Union(const RenderScene& a, const RenderScene& b) {
    RenderScene u = a;
    u.polygons.insert(u.polygons.end(), b.polygons.begin(), b.polygons.end());
    u.tags.insert(u.tags.end(), b.tags.begin(), b.tags.end());
    return u;
  }
};

RenderOptions Options(const benchmark::State& state, int k) {
  RenderOptions o;
  o.supersample = static_cast<int>(state.range(0));
  if (state.range(1) != 0) o.noise_stddev = 2, o.blur_sigma = 0.5;
  o.seed = static_cast<std::uint32_t>(k + 1);
  return o;
}

void BM_RenderReference(benchmark::State& state) {
  const World w;
  int k = 0;
  for (auto _ : state) {
    const GrayImage image = Render(w.camera, w.wMc, World::Union(w.fixed, w.Robot(k)), Options(state, k));
    benchmark::DoNotOptimize(image.pixels.data());
    ++k;
  }
}
BENCHMARK(BM_RenderReference)->Args({1, 1})->Args({2, 1})->Args({1, 0})->Unit(benchmark::kMillisecond);

void BM_RenderCached(benchmark::State& state) {
  const World w;
  CachedRenderer renderer(w.camera, w.fixed);
  renderer.Render(w.wMc, w.Robot(0), Options(state, 0));  // the fixed part, once
  int k = 1;
  for (auto _ : state) {
    const GrayImage image = renderer.Render(w.wMc, w.Robot(k), Options(state, k));
    benchmark::DoNotOptimize(image.pixels.data());
    ++k;
  }
}
BENCHMARK(BM_RenderCached)->Args({1, 1})->Args({2, 1})->Args({1, 0})->Unit(benchmark::kMillisecond);

// Both on the same frames, alternately: the ratio is measured under the same load.
void BM_CachedToReference(benchmark::State& state) {
  using Clock = std::chrono::steady_clock;
  const World w;
  CachedRenderer renderer(w.camera, w.fixed);
  renderer.Render(w.wMc, w.Robot(0), Options(state, 0));
  double ref = 0, cached = 0;
  bool identical = true;
  int k = 1;
  for (auto _ : state) {
    const RenderOptions o = Options(state, k);
    const RenderScene robot = w.Robot(k);
    const auto t0 = Clock::now();
    const GrayImage want = Render(w.camera, w.wMc, World::Union(w.fixed, robot), o);
    const auto t1 = Clock::now();
    const GrayImage got = renderer.Render(w.wMc, robot, o);
    const auto t2 = Clock::now();
    ref += std::chrono::duration<double>(t1 - t0).count();
    cached += std::chrono::duration<double>(t2 - t1).count();
    identical = identical && want.pixels == got.pixels;
    ++k;
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["ref_ms"] = 1e3 * ref / n;
  state.counters["cached_ms"] = 1e3 * cached / n;
  state.counters["ratio"] = cached / ref;
  state.counters["identical"] = identical ? 1 : 0;
}
BENCHMARK(BM_CachedToReference)->Args({1, 1})->Args({2, 1})->Args({1, 0})->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace visco::vision

BENCHMARK_MAIN();

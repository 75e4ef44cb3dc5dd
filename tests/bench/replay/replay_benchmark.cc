// Replay throughput: the checked-in log of a rendered closed-loop run (tests/replay/data/slot_run.lcmlog, 640x480
// frames at 15 Hz) read, decoded and put through the vision pipeline as fast as possible, with --check's field by
// field comparison on. Counters: frames/s of replay and the log's own frame rate, measured in the same run, and their
// ratio (x_real_time; the goal is >= 5 for 640x480 at 30 Hz on the 2-core machine, i.e. >= 150 frames/s).
// A second benchmark reads the log only (the event log reader's share).

#include <benchmark/benchmark.h>

#include "replay/event_log.h"
#include "replay/replayer.h"

namespace {

const char* kFixture = "tests/replay/data/slot_run.lcmlog";

visco::replay::ReplayOptions Options(bool check) {
  visco::replay::ReplayOptions o;
  o.log_path = kFixture;
  o.pipeline.camera = "data/sim/slot_camera.xml";
  o.pipeline.extrinsics = "data/sim/slot_extrinsics.json";
  o.pipeline.objects = "data/sim/slot_objects.json";
  o.fast = true;
  o.publish = false;
  o.check = check;
  return o;
}

void BM_ReplayThroughVision(benchmark::State& state) {
  const visco::replay::ReplayOptions o = Options(state.range(0) != 0);
  double frames = 0, wall = 0, logged_hz = 0;
  bool identical = true;
  for (auto _ : state) {
    const visco::replay::ReplaySummary s = visco::replay::RunReplay(o);
    frames += static_cast<double>(s.frames + s.bad_frames);
    wall += s.wall_s;
    logged_hz = s.log_frame_rate_hz;
    identical = identical && (!o.check || s.identical());
  }
  if (!identical) state.SkipWithError("replay --check found a difference");
  state.counters["frames_per_s"] = frames / wall;
  state.counters["logged_hz"] = logged_hz;
  state.counters["x_real_time"] = frames / wall / logged_hz;
}
BENCHMARK(BM_ReplayThroughVision)->Arg(0)->Arg(1)->ArgName("check")->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ReadLog(benchmark::State& state) {
  std::int64_t bytes = 0;
  for (auto _ : state) {
    visco::replay::EventLogReader reader(kFixture);
    visco::replay::LogEvent e;
    while (reader.Next(e)) benchmark::DoNotOptimize(e.data.data());
    bytes += reader.report().file_bytes;
  }
  state.SetBytesProcessed(bytes);
}
BENCHMARK(BM_ReadLog)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();

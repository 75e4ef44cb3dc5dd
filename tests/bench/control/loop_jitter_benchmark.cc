// Wake-up latency of the control loop against baselines measured in the same run, at the same period and
// priority: `cyclictest` (Debian rt-tests, the standard measure of a machine's scheduling latency) and a bare
// clock_nanosleep(TIMER_ABSTIME) loop with no work. The control loop runs the real Executor on a visual-guarded
// step against an in-process driver thread (LoopbackLink) and a camera feeding the LatestValue hand-off.
// Counters are microseconds of wake-up latency (actual wake - scheduled wake): min, mean, max, and p99 where the
// histogram allows. Cycles per run: VISCO_JITTER_CYCLES (default 1000; use 20000+ for figures).
//   build/bin/control_loop_jitter_benchmark --benchmark_counters_tabular=true

#include <benchmark/benchmark.h>
#include <time.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "control/control_loop.h"
#include "control/loopback_link.h"
#include "control/synthetic_camera.h"

namespace visco::control {
namespace {

int Cycles() {
  const char* env = std::getenv("VISCO_JITTER_CYCLES");
  return env != nullptr ? std::max(100, std::atoi(env)) : 1000;
}
constexpr int kPriority = 80;

void Report(benchmark::State& state, const std::vector<std::int64_t>& latencies_ns, std::int64_t overruns) {
  std::vector<std::int64_t> sorted = latencies_ns;
  std::sort(sorted.begin(), sorted.end());
  double sum = 0;
  for (std::int64_t v : sorted) sum += static_cast<double>(v);
  state.counters["min_us"] = static_cast<double>(sorted.front()) / 1e3;
  state.counters["mean_us"] = sum / static_cast<double>(sorted.size()) / 1e3;
  state.counters["p99_us"] = static_cast<double>(sorted[sorted.size() * 99 / 100]) / 1e3;
  state.counters["max_us"] = static_cast<double>(sorted.back()) / 1e3;
  state.counters["overruns"] = static_cast<double>(overruns);
  state.counters["cycles"] = static_cast<double>(sorted.size());
}

// Baseline 1: cyclictest, one thread, same interval, priority and memory locking.
void BM_Cyclictest(benchmark::State& state) {
  const int period_us = static_cast<int>(state.range(0));
  const int cycles = Cycles();
  for (auto _ : state) {
    const std::string command = "cyclictest -q -m -t1 -p" + std::to_string(kPriority) + " -i" +
                                std::to_string(period_us) + " -l" + std::to_string(cycles) + " 2>/dev/null";
    FILE* pipe = popen(command.c_str(), "r");
    if (pipe == nullptr) {
      state.SkipWithError("cannot start cyclictest (Debian package rt-tests)");
      return;
    }
    char line[512];
    double min = -1, avg = -1, max = -1;
    while (std::fgets(line, sizeof(line), pipe) != nullptr) {
      const char* p = std::strstr(line, "Min:");
      if (p != nullptr) std::sscanf(p, "Min: %lf Act: %*f Avg: %lf Max: %lf", &min, &avg, &max);
    }
    const int status = pclose(pipe);
    if (status != 0 || min < 0) {
      state.SkipWithError("cyclictest failed or printed no summary (is rt-tests installed?)");
      return;
    }
    state.counters["min_us"] = min;
    state.counters["mean_us"] = avg;
    state.counters["max_us"] = max;
    state.counters["cycles"] = cycles;
  }
}

// Baseline 2: the same absolute-deadline sleep with no work at all.
void BM_BareNanosleepLoop(benchmark::State& state) {
  const std::int64_t period_ns = state.range(0) * 1000;
  const int cycles = Cycles();
  std::vector<std::int64_t> latencies(static_cast<std::size_t>(cycles));
  for (auto _ : state) {
    std::thread t([&] {
      ConfigureRealtime(kPriority, true);
      std::int64_t next = MonotonicNs() + period_ns;
      for (int i = 0; i < cycles; ++i) {
        timespec ts{static_cast<time_t>(next / 1'000'000'000), static_cast<long>(next % 1'000'000'000)};
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
        latencies[static_cast<std::size_t>(i)] = MonotonicNs() - next;
        next += period_ns;
      }
    });
    t.join();
  }
  Report(state, latencies, 0);
}

// The control loop: Executor + safety + LoopbackLink + LatestValue inputs, with a driver thread at 1 kHz and a
// 30 Hz camera thread running beside it.
void BM_ControlLoop(benchmark::State& state) {
  const double period_s = static_cast<double>(state.range(0)) * 1e-6;
  const int cycles = Cycles();
  Task task;
  CvcRay ray;
  ray.id = "vc0.cm0";
  ray.cm_vertex = 0;
  ray.from = {100.0, 0.0};
  ray.to = {100.0, 5.0};
  ray.direction = {0.0, 1.0};
  ray.has_cm_offset = true;
  task.rays.push_back(ray);
  task.ray_index[ray.id] = 0;
  Step step;  // a visual guarded motion towards a line it never reaches
  step.terminate = TerminateKind::kVisualGuarded;
  step.terminate_ray = 0;
  step.active_rays = {};
  task.steps.push_back(step);
  ExecutorConfig config;
  config.period_s = period_s;
  config.max_vision_age_s = 0.2;
  for (auto _ : state) {
    Executor executor(task, config);
    LoopbackLink link;
    LatestValue<VisualFrame> frames;
    Outbox outbox;
    LoopConfig loop_config;
    loop_config.period_s = period_s;
    LoopSources sources{&link, &frames, nullptr, nullptr};
    ControlLoop loop(executor, sources, loop_config, outbox);
    std::atomic<bool> running{true};
    std::thread driver([&] {
      LoopbackLink::Sent sent;
      Vec2 position{1.0, 1.0};
      auto next = std::chrono::steady_clock::now();
      std::uint32_t seq = 0;
      while (running) {
        next += std::chrono::milliseconds(1);
        std::this_thread::sleep_until(next);
        link.RobotTakeCommand(sent);
        position = position + 0.001 * Vec2{sent.command.velocity[0], sent.command.velocity[1]};
        drivers::RobotStatus status;
        status.position[0] = position.x;
        status.position[1] = position.y;
        status.seq = ++seq;
        status.state = drivers::RobotState::kReady;
        link.RobotPublishStatus(status);
        if (seq % 100 == 0) link.RobotHeartbeat();
      }
    });
    std::thread camera([&] {
      SyntheticCamera cam(task, {}, 1);
      std::int64_t seq = 0;
      while (running) {
        std::this_thread::sleep_for(std::chrono::microseconds(33333));
        VisualFrame frame;
        cam.Observe({1.0, 1.0}, ++seq, MonotonicNs(), frame);
        frames.Publish(frame);
      }
    });
    std::thread consumer([&] {  // the publisher side, draining as the LCM thread would
      TelemetrySnapshot t;
      FaultEvent f;
      while (running) {
        outbox.Wait(0.05);
        while (outbox.telemetry.TryPop(t)) {
        }
        while (outbox.faults.TryPop(f)) {
        }
      }
    });
    std::vector<std::int64_t> latencies;
    std::int64_t overruns = 0;
    std::thread rt([&] {
      ConfigureRealtime(kPriority, true);
      executor.Start(MonotonicNs());
      std::atomic<bool> stop{false};
      loop.Run(stop, cycles);
      overruns = loop.overruns();
    });
    rt.join();
    running = false;
    driver.join();
    camera.join();
    outbox.Notify();
    consumer.join();
    // The loop keeps a histogram of 2^i us bins: p99_upper_us is the upper edge of the bin holding the 99th percentile.
    const JitterStats& j = loop.total_jitter();
    state.counters["min_us"] = static_cast<double>(j.min_ns) / 1e3;
    state.counters["mean_us"] = j.mean_ns() / 1e3;
    state.counters["max_us"] = static_cast<double>(j.max_ns) / 1e3;
    std::int64_t below = 0;
    double p99_edge = 0;
    for (int i = 0; i < kJitterBins; ++i) {
      below += j.histogram[i];
      if (below >= j.count * 99 / 100) {
        p99_edge = i == kJitterBins - 1 ? static_cast<double>(j.max_ns) / 1e3 : static_cast<double>(2 << i);
        break;
      }
    }
    state.counters["p99_upper_us"] = p99_edge;
    state.counters["overruns"] = static_cast<double>(overruns);
    state.counters["cycles"] = static_cast<double>(j.count);
    if (executor.finished()) state.SkipWithError(executor.stop_reason());
  }
}

BENCHMARK(BM_Cyclictest)->Arg(2000)->Arg(1000)->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BareNanosleepLoop)->Arg(2000)->Arg(1000)->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ControlLoop)->Arg(2000)->Arg(1000)->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace visco::control

BENCHMARK_MAIN();

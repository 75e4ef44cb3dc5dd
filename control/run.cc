#include "control/run.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>

#include "common/error.h"
#include "control/control_loop.h"
#include "control/lcm_bridge.h"
#include "drivers/robot_link.h"
#include "lcmtypes/channels.h"
#include "visco/motion_strategy_t.hpp"

namespace visco::control {
namespace {

class StrategyWaiter {
 public:
  void Handle(const lcm::ReceiveBuffer*, const std::string&, const motion_strategy_t* m) {
    if (!received) {
      message = *m;
      received = true;
    }
  }
  bool received = false;
  motion_strategy_t message;
};

void CheckOptions(const RunOptions& o) {
  if (!(o.rate_hz >= 10 && o.rate_hz <= 2000)) {
    throw InputError("command line", "--rate", "must be in [10, 2000] Hz");
  }
  if (!(o.telemetry_hz > 0 && o.telemetry_hz <= o.rate_hz)) {
    throw InputError("command line", "--telemetry-hz", "must be in (0, rate]");
  }
  if (!(o.heartbeat_timeout_s > 0)) throw InputError("command line", "--heartbeat-timeout-ms", "must be positive");
  const ExecutorConfig& e = o.executor;
  if (!(e.limits.max_speed > 0)) throw InputError("command line", "--max-speed", "must be positive");
  if (!(e.limits.max_accel > 0)) throw InputError("command line", "--max-accel", "must be positive");
  if (!(e.servo.gain > 0)) throw InputError("command line", "--gain", "must be positive");
  if (!(e.servo.focal_px > 0)) throw InputError("command line", "--focal-px", "must be positive");
  if (!(e.max_vision_age_s > 0)) throw InputError("command line", "--max-vision-age-ms", "must be positive");
  if (!(e.heartbeat_timeout_s > 0)) throw InputError("command line", "--status-timeout-ms", "must be positive");
  if (!(e.default_step_timeout_s > 0)) throw InputError("command line", "--step-timeout", "must be positive");
  if (o.node_id < 1 || o.node_id > 127) throw InputError("command line", "--node", "must be in 1..127");
}

}  // namespace

void LogToStderr() {
  auto logger = spdlog::get("visco");
  if (!logger) logger = spdlog::stderr_color_mt("visco");
  spdlog::set_default_logger(logger);
  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ %v");
}

std::string RunResult::ToJson() const {
  nlohmann::json j;
  j["result"] = mode == Mode::kDone ? "done" : (mode == Mode::kStopped ? "stopped" : ToString(mode));
  j["reason"] = reason;
  j["stop_code"] = static_cast<int>(stop_code);
  j["steps_completed"] = steps_completed;
  j["num_steps"] = num_steps;
  j["cycles"] = cycles;
  j["overruns"] = overruns;
  j["jitter_us"] = {{"min", jitter_min_us}, {"mean", jitter_mean_us}, {"max", jitter_max_us}};
  j["jitter_histogram"] = std::vector<int>(std::begin(jitter_histogram), std::end(jitter_histogram));
  j["realtime"] = realtime_setup;
  j["faults_published"] = faults_published;
  j["visual_frames"] = frames_received;
  j["estimates"] = estimates_received;
  j["commands_sent"] = commands_sent;
  j["statuses_received"] = statuses_received;
  return j.dump();
}

Task LoadTask(const RunOptions& o) {
  std::vector<CvcRay> rays;
  if (!o.rays_path.empty()) rays = LoadRays(o.rays_path);
  Task task;
  std::string source = o.strategy_path;
  if (!o.strategy_path.empty()) {
    task = LoadStrategyFile(o.strategy_path, rays);
  } else {
    source = channels::kStrategy;
    lcm::LCM lcm(o.lcm_url);
    if (!lcm.good()) throw JobFailed("LCM: cannot initialise provider '" + o.lcm_url + "'");
    StrategyWaiter waiter;
    lcm.subscribe(channels::kStrategy, &StrategyWaiter::Handle, &waiter);
    spdlog::info("run: waiting up to {:.1f} s for a strategy on {}", o.strategy_wait_s, channels::kStrategy);
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(o.strategy_wait_s);
    while (!waiter.received && std::chrono::steady_clock::now() < end) lcm.handleTimeout(50);
    if (!waiter.received) {
      throw JobFailed(std::string("no strategy received on ") + channels::kStrategy + " within " +
                      std::to_string(o.strategy_wait_s) + " s");
    }
    task = FromLcm(waiter.message, rays);
  }
  if (!o.scene_path.empty()) AttachScene(task, LoadScene(o.scene_path), o.scene_path);
  ValidateTask(task, source);
  return task;
}

RunResult RunTask(const Task& task, const RunOptions& options, const std::atomic<bool>& stop) {
  CheckOptions(options);
  RunOptions o = options;
  o.executor.period_s = 1.0 / o.rate_hz;
  Executor executor(task, o.executor);

  drivers::RobotLinkConfig link_config;
  link_config.node_id = o.node_id;
  link_config.heartbeat_timeout_us = static_cast<std::int64_t>(o.heartbeat_timeout_s * 1e6);
  link_config.can_interface = o.can_interface;
  link_config.lcm_url = o.lcm_url;
  std::unique_ptr<drivers::RobotLink> link =
      o.can_interface.empty() ? drivers::MakeLcmRobotLink(link_config) : drivers::MakeSocketCanRobotLink(link_config);
  lcm::LCM lcm(o.lcm_url);
  if (!lcm.good()) throw JobFailed("LCM: cannot initialise provider '" + o.lcm_url + "'");
  Outbox outbox;
  ControllerBridge bridge(lcm, task, outbox);

  LoopConfig loop_config;
  loop_config.period_s = 1.0 / o.rate_hz;
  loop_config.telemetry_every = std::max(1, static_cast<int>(std::lround(o.rate_hz / o.telemetry_hz)));
  loop_config.realtime = o.realtime;
  loop_config.priority = o.priority;
  LoopSources sources{link.get(), &bridge.frames(), &bridge.estimates(), &bridge.estop()};
  ControlLoop loop(executor, sources, loop_config, outbox);

  spdlog::info("run: {} step(s), {} CVC ray(s), {:.0f} Hz, robot node {} on {}", task.steps.size(), task.rays.size(),
               o.rate_hz, o.node_id, o.can_interface.empty() ? "LCM" : "CAN " + o.can_interface);
  bridge.Start();
  RunResult result;
  std::atomic<bool> loop_stop{false};
  std::atomic<bool> setup_done{false};
  // The loop thread owns the executor: this thread learns that the run is over from this flag, never by reading the
  // executor while the loop writes it (a data race, found by ThreadSanitizer).
  std::atomic<bool> loop_done{false};
  std::thread rt([&] {
    if (o.realtime) {
      result.realtime_setup = ConfigureRealtime(o.priority, true).message;
    } else {
      result.realtime_setup = "real-time setup: disabled (--no-realtime): default scheduler, memory not locked";
    }
    setup_done.store(true, std::memory_order_release);
    executor.Start(MonotonicNs());
    loop.Run(loop_stop);
    loop_done.store(true, std::memory_order_release);
  });
  // The real-time thread logs nothing itself; say how it was set up once it has tried.
  const auto start = std::chrono::steady_clock::now();
  while (!setup_done.load(std::memory_order_acquire)) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  if (result.realtime_setup.find("not permitted") != std::string::npos ||
      result.realtime_setup.find("failed") != std::string::npos) {
    spdlog::warn("run: {}", result.realtime_setup);
  } else {
    spdlog::info("run: {}", result.realtime_setup);
  }
  bool estop_sent = false;
  while (!loop_done.load(std::memory_order_acquire)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    if (stop.load() && !estop_sent) {
      spdlog::warn("run: stop requested (signal): e-stop");
      bridge.estop().store(true);
      estop_sent = true;
    }
    if (o.max_duration_s > 0 && !estop_sent &&
        std::chrono::steady_clock::now() - start > std::chrono::duration<double>(o.max_duration_s)) {
      spdlog::warn("run: --duration {:.1f} s reached: e-stop", o.max_duration_s);
      bridge.estop().store(true);
      estop_sent = true;
    }
  }
  rt.join();  // the loop lingers a few cycles after the end so the final zero command goes out
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  bridge.Stop();

  result.mode = executor.mode();
  result.stop_code = executor.stop_code();
  result.reason = executor.stop_reason();
  result.num_steps = static_cast<int>(task.steps.size());
  result.steps_completed = executor.mode() == Mode::kDone ? result.num_steps : std::max(0, executor.step_index());
  result.cycles = loop.cycles();
  result.overruns = loop.overruns();
  const JitterStats& jitter = loop.total_jitter();
  result.jitter_min_us = jitter.count > 0 ? static_cast<double>(jitter.min_ns) / 1e3 : 0.0;
  result.jitter_mean_us = jitter.mean_ns() / 1e3;
  result.jitter_max_us = static_cast<double>(jitter.max_ns) / 1e3;
  std::copy(std::begin(jitter.histogram), std::end(jitter.histogram), result.jitter_histogram);
  result.faults_published = bridge.counters().faults.load();
  result.frames_received = bridge.counters().frames.load();
  result.estimates_received = bridge.counters().estimates.load();
  const drivers::LinkCounters counters = link->counters();
  result.commands_sent = counters.commands_sent;
  result.statuses_received = counters.statuses_received;
  if (result.mode == Mode::kDone) {
    spdlog::info("run: {}", result.reason);
  } else {
    spdlog::error("run: stopped: {}", result.reason);
  }
  return result;
}

}  // namespace visco::control

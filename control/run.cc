#include "control/run.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>
#include <vector>

#include "common/error.h"
#include "control/control_loop.h"
#include "control/cycle_message.h"
#include "control/lcm_bridge.h"
#include "drivers/robot_link.h"
#include "lcmtypes/channels.h"
#include "visco/controller_cycle_t.hpp"
#include "visco/log_annotation_t.hpp"
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

template <class M>
void WriteToLog(EventLogTap& log, const char* channel, std::int64_t utime, const M& m) {
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  log.Write(channel, utime, bytes.data(), bytes.size());
}

}  // namespace

std::string ExecutorConfigToJson(const ExecutorConfig& c) {
  nlohmann::json j;
  j["period_s"] = c.period_s;
  j["default_speed"] = c.default_speed;
  j["default_step_timeout_s"] = c.default_step_timeout_s;
  j["max_vision_age_s"] = c.max_vision_age_s;
  j["max_hold_s"] = c.max_hold_s;
  j["heartbeat_timeout_s"] = c.heartbeat_timeout_s;
  j["startup_timeout_s"] = c.startup_timeout_s;
  j["contact_speed"] = c.contact_speed;
  j["contact_dwell_s"] = c.contact_dwell_s;
  j["contact_min_step_s"] = c.contact_min_step_s;
  j["goal_from_odometry"] = c.goal_from_odometry;
  j["approach_tolerance_m"] = c.approach_tolerance_m;
  j["stuck_s"] = c.stuck_s;
  j["stuck_distance"] = c.stuck_distance;
  j["servo"] = {{"gain", c.servo.gain},
                {"focal_px", c.servo.focal_px},
                {"nominal_range_m", c.servo.nominal_range_m},
                {"min_range_m", c.servo.min_range_m},
                {"max_normal_speed", c.servo.max_normal_speed}};
  if (c.servo.camera.valid) {
    const ServoCamera& k = c.servo.camera;
    nlohmann::json r = nlohmann::json::array();
    for (const auto& row : k.cRw) r.push_back({row[0], row[1], row[2]});
    j["servo"]["camera"] = {{"px", k.px},
                            {"py", k.py},
                            {"u0", k.u0},
                            {"v0", k.v0},
                            {"cRw", r},
                            {"ctw", {k.ctw[0], k.ctw[1], k.ctw[2]}},
                            {"point_height_m", k.point_height_m}};
  }
  j["limits"] = {
      {"max_speed", c.limits.max_speed}, {"max_accel", c.limits.max_accel}, {"bounds_margin", c.limits.bounds_margin}};
  // Doubles as JSON numbers round-trip exactly (nlohmann prints the shortest exact representation).
  return j.dump();
}

ExecutorConfig ExecutorConfigFromJson(const std::string& text, const std::string& source) {
  try {
    const nlohmann::json j = nlohmann::json::parse(text);
    ExecutorConfig c;
    c.period_s = j.at("period_s").get<double>();
    c.default_speed = j.at("default_speed").get<double>();
    c.default_step_timeout_s = j.at("default_step_timeout_s").get<double>();
    c.max_vision_age_s = j.at("max_vision_age_s").get<double>();
    c.max_hold_s = j.at("max_hold_s").get<double>();
    c.heartbeat_timeout_s = j.at("heartbeat_timeout_s").get<double>();
    c.startup_timeout_s = j.at("startup_timeout_s").get<double>();
    c.contact_speed = j.at("contact_speed").get<double>();
    c.contact_dwell_s = j.at("contact_dwell_s").get<double>();
    c.contact_min_step_s = j.at("contact_min_step_s").get<double>();
    c.goal_from_odometry = j.at("goal_from_odometry").get<bool>();
    c.approach_tolerance_m = j.value("approach_tolerance_m", 0.0);  // logs from before it existed: full speed
    c.stuck_s = j.value("stuck_s", 0.0);                            // ... and: no stuck detection
    c.stuck_distance = j.value("stuck_distance", 0.001);
    const auto& s = j.at("servo");
    c.servo.gain = s.at("gain").get<double>();
    c.servo.focal_px = s.at("focal_px").get<double>();
    c.servo.nominal_range_m = s.at("nominal_range_m").get<double>();
    c.servo.min_range_m = s.at("min_range_m").get<double>();
    c.servo.max_normal_speed = s.at("max_normal_speed").get<double>();
    if (s.contains("camera")) {  // logs from before the calibrated camera: the planar model
      const auto& k = s.at("camera");
      ServoCamera& cam = c.servo.camera;
      cam.valid = true;
      cam.px = k.at("px").get<double>(), cam.py = k.at("py").get<double>();
      cam.u0 = k.at("u0").get<double>(), cam.v0 = k.at("v0").get<double>();
      for (int i = 0; i < 3; ++i) {
        for (int m = 0; m < 3; ++m) cam.cRw[i][m] = k.at("cRw").at(i).at(m).get<double>();
        cam.ctw[i] = k.at("ctw").at(i).get<double>();
      }
      cam.point_height_m = k.at("point_height_m").get<double>();
    }
    const auto& l = j.at("limits");
    c.limits.max_speed = l.at("max_speed").get<double>();
    c.limits.max_accel = l.at("max_accel").get<double>();
    c.limits.bounds_margin = l.at("bounds_margin").get<double>();
    return c;
  } catch (const nlohmann::json::exception& e) {
    throw InputError(source, "executor", std::string("bad controller configuration: ") + e.what());
  }
}

log_annotation_t ControllerConfigAnnotation(const RunOptions& o, const ExecutorConfig& executor, std::int64_t start_ns,
                                            std::int64_t cycles, std::int64_t records_written,
                                            std::int64_t records_dropped, std::int64_t utime) {
  nlohmann::json note;
  note["executor"] = nlohmann::json::parse(ExecutorConfigToJson(executor));
  note["start_ns"] = start_ns;
  auto absolute = [](const std::string& p) { return p.empty() ? p : std::filesystem::absolute(p).string(); };
  note["strategy"] = absolute(o.strategy_path);
  note["scene"] = absolute(o.scene_path);
  note["rays"] = absolute(o.rays_path);
  note["cycles"] = cycles;
  note["records_written"] = records_written;
  note["records_dropped"] = records_dropped;
  log_annotation_t a;
  a.utime = utime;
  a.source = "run";
  a.kind = "controller_config";
  a.text = note.dump();
  return a;
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
  // Every file must belong to the one scene: a strategy planned for another scene drives the robot where that scene
  // has free space (docs/formats.md, "scene_digest").
  std::optional<SceneInfo> scene;
  if (!o.scene_path.empty()) scene = LoadScene(o.scene_path);
  SceneIdentity rays_for;
  std::vector<CvcRay> rays;
  if (!o.rays_path.empty()) {
    rays_for = ReadSceneIdentity(o.rays_path);
    if (scene) CheckMadeFor(rays_for, "rays", o.rays_path, *scene, o.scene_path);
    rays = LoadRays(o.rays_path);
  }
  const bool rays_given = !o.rays_path.empty();
  Task task;
  std::string source = o.strategy_path;
  if (!o.strategy_path.empty()) {
    const SceneIdentity strategy_for = ReadSceneIdentity(o.strategy_path);
    if (scene) CheckMadeFor(strategy_for, "strategy", o.strategy_path, *scene, o.scene_path);
    if (rays_given) CheckSameScene(strategy_for, o.strategy_path, rays_for, o.rays_path);
    task = LoadStrategyFile(o.strategy_path, rays, rays_given);
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
    // The message names its scene but carries no digest: the names are compared.
    if (scene) CheckMadeFor({waiter.message.scene, ""}, "strategy", source, *scene, o.scene_path);
    task = FromLcm(waiter.message, rays, rays_given);
  }
  if (scene) AttachScene(task, *scene, o.scene_path);
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
  // With an event log, every period's record leaves the loop through an SPSC queue; this thread writes them.
  std::unique_ptr<CycleRecordQueue> records;
  std::thread recorder;
  std::atomic<bool> recording{false};
  std::int64_t records_written = 0;
  if (o.log != nullptr) {
    records = std::make_unique<CycleRecordQueue>();
    sources.records = records.get();
  }
  ControlLoop loop(executor, sources, loop_config, outbox);  // may throw: before any thread starts
  if (o.log != nullptr) {
    recording = true;
    recorder = std::thread([&] {
      CycleRecord r;
      for (;;) {
        const bool last = !recording.load(std::memory_order_acquire);
        while (records->TryPop(r)) {
          WriteToLog(*o.log, kCycleChannel, r.input.now_utime, ToCycleMessage(r));
          ++records_written;
        }
        if (last) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
      }
    });
  }

  spdlog::info("run: {} step(s), {} CVC ray(s), {:.0f} Hz, robot node {} on {}", task.steps.size(), task.rays.size(),
               o.rate_hz, o.node_id, o.can_interface.empty() ? "LCM" : "CAN " + o.can_interface);
  bridge.Start();
  RunResult result;
  std::atomic<bool> loop_stop{false};
  std::atomic<bool> setup_done{false};
  // The loop thread owns the executor: this thread learns that the run is over from this flag, never by reading the
  // executor while the loop writes it (a data race, found by ThreadSanitizer).
  std::atomic<bool> loop_done{false};
  std::atomic<std::int64_t> start_ns{0};
  std::thread rt([&] {
    if (o.realtime) {
      result.realtime_setup = ConfigureRealtime(o.priority, true).message;
    } else {
      result.realtime_setup = "real-time setup: disabled (--no-realtime): default scheduler, memory not locked";
    }
    setup_done.store(true, std::memory_order_release);
    start_ns.store(MonotonicNs(), std::memory_order_relaxed);
    executor.Start(start_ns.load(std::memory_order_relaxed));
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
  if (o.log != nullptr) {
    recording.store(false, std::memory_order_release);
    recorder.join();
    // The run's configuration, for `visco replay` to run the same executor (docs/replay.md).
    const log_annotation_t a = ControllerConfigAnnotation(o, o.executor, start_ns.load(), loop.cycles(),
                                                          records_written, records->dropped(), WallUtime());
    WriteToLog(*o.log, kAnnotationChannel, a.utime, a);
    if (records->dropped() > 0) {
      spdlog::warn("run: {} of {} period records dropped from the event log (queue full)", records->dropped(),
                   loop.cycles());
    }
  }

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

#pragma once
// `visco run`: load a strategy, connect to the robot (SocketCAN or LCM) and vision (LCM), and execute it in the
// real-time loop. Not real-time safe itself: it sets up, starts the loop thread, waits, and reports.

#include <atomic>
#include <cstdint>
#include <string>

#include "common/event_log.h"
#include "control/control_loop.h"
#include "control/executor.h"
#include "control/task.h"
#include "drivers/commands.h"
#include "visco/log_annotation_t.hpp"

namespace visco::control {

struct RunOptions {
  std::string strategy_path;    // contract JSON; empty: wait for VISCO_STRATEGY on LCM
  double strategy_wait_s = 10;  // how long to wait for the LCM strategy
  std::string scene_path;       // optional: goal, bounds, ε_p, robot vertex offsets
  std::string rays_path;        // optional: `visco vcrays` output (needed for visual compliant steps)
  std::string lcm_url;          // "" = LCM's default
  std::string can_interface;    // non-empty: the robot is on SocketCAN, else on LCM
  int node_id = 1;
  double rate_hz = 500;
  double heartbeat_timeout_s = 0.25;  // the link's heartbeat time-out (driver heartbeats every 100 ms)
  bool realtime = true;
  int priority = 80;
  double telemetry_hz = 50;
  double max_duration_s = 0;  // 0: until the strategy ends
  ExecutorConfig executor;
  EventLogTap* log = nullptr;  // optional: every period's inputs and command go into this log (docs/replay.md)
};

/// The channel of the per-period records (controller_cycle_t) and of the run's configuration (log_annotation_t,
/// kind "controller_config") in an event log. Neither is published on the bus.
inline constexpr char kCycleChannel[] = "VISCO_CONTROLLER_CYCLE";
inline constexpr char kAnnotationChannel[] = "VISCO_LOG_ANNOTATION";

/// The executor's configuration as JSON and back (for the event log's annotation). FromJson @throws InputError.
std::string ExecutorConfigToJson(const ExecutorConfig& config);
ExecutorConfig ExecutorConfigFromJson(const std::string& json, const std::string& source);

/// The run's configuration as the log's VISCO_LOG_ANNOTATION message (kind "controller_config", what `visco replay`
/// reads to run the same executor): the executor's configuration, the executor's start time, the strategy, scene and
/// rays files (made absolute) and the period records' counts. `utime` stamps it.
log_annotation_t ControllerConfigAnnotation(const RunOptions& options, const ExecutorConfig& executor,
                                            std::int64_t start_ns, std::int64_t cycles, std::int64_t records_written,
                                            std::int64_t records_dropped, std::int64_t utime);

struct RunResult {
  Mode mode = Mode::kIdle;
  FaultCode stop_code = FaultCode::kNone;
  std::string reason;
  int steps_completed = 0;
  int num_steps = 0;
  std::int64_t cycles = 0;
  std::int64_t overruns = 0;
  double jitter_min_us = 0, jitter_mean_us = 0, jitter_max_us = 0;
  std::int32_t jitter_histogram[16] = {};
  std::string realtime_setup;
  std::uint64_t faults_published = 0;
  std::uint64_t frames_received = 0;
  std::uint64_t estimates_received = 0;
  std::uint64_t commands_sent = 0;
  std::uint64_t statuses_received = 0;

  /// The summary `visco run` prints (one JSON object).
  std::string ToJson() const;
};

/// Sends spdlog's default logger to stderr (drivers/commands.h; the commands print their JSON summary alone on
/// stdout).
using drivers::LogToStderr;

/// Loads the task named by the options (strategy file or LCM message, rays, scene). @throws InputError, JobFailed.
Task LoadTask(const RunOptions& options);

/// Runs `task` to the end (done, stopped, `stop` set, or max duration). `stop` requests an e-stop (e.g. SIGINT).
/// @throws JobFailed if the robot link or LCM cannot be opened; InputError for invalid options.
RunResult RunTask(const Task& task, const RunOptions& options, const std::atomic<bool>& stop);

}  // namespace visco::control

#pragma once
// The fixed-rate control loop (ros2_control style): read -> update -> write, then sleep to the absolute next
// period with clock_nanosleep(TIMER_ABSTIME), counting overruns and recording wake-up latency. Telemetry and faults
// leave through SPSC queues to a non-real-time publisher; vision arrives through visco::LatestValue; the robot is
// reached through drivers::RobotLink (SocketCAN, LCM, or the in-process LoopbackLink).

#include <semaphore.h>

#include <atomic>
#include <cstdint>
#include <string>

#include "common/latest_value.h"
#include "control/executor.h"
#include "control/jitter_stats.h"
#include "control/spsc_queue.h"
#include "drivers/robot_link.h"

namespace visco::control {

/// One telemetry sample (controller_telemetry_t without the strings' allocation).
struct TelemetrySnapshot {
  std::int64_t utime = 0;
  std::int32_t step_index = -1;
  Mode mode = Mode::kIdle;
  bool holding = false;
  char stop_reason[128] = {};
  char step_reason[128] = {};  // why the previous step ended
  Vec2 command;
  Vec2 estimate;
  double estimate_age_s = 0.0;
  double period_s = 0.0;
  std::int64_t cycles = 0;
  std::int64_t overruns = 0;
  double jitter_min_s = 0.0;
  double jitter_mean_s = 0.0;
  double jitter_max_s = 0.0;
  std::int32_t jitter_histogram[kJitterBins] = {};
};

/// What the loop hands to the non-real-time side. The loop posts `wake` after pushing, so the consumer sleeps on
/// it instead of polling.
struct Outbox {
  Outbox();
  ~Outbox();
  Outbox(const Outbox&) = delete;
  Outbox& operator=(const Outbox&) = delete;
  /// Wakes the consumer. Real-time safe (sem_post: an atomic increment, a futex wake only if someone waits).
  void Notify();
  /// Waits up to `timeout_s` for a notification (consumer side; not real-time safe).
  void Wait(double timeout_s);

  SpscQueue<TelemetrySnapshot, 64> telemetry;
  SpscQueue<FaultEvent, 64> faults;
  std::atomic<std::int64_t> cycles{0};  // loop iterations so far (for the controller heartbeat)

 private:
  sem_t wake_;
};

struct LoopConfig {
  double period_s = 0.002;        // s, 500 Hz by default; 0.001 for 1 kHz
  int telemetry_every = 10;       // cycles between telemetry samples (also sent on every mode change)
  bool realtime = true;           // try SCHED_FIFO and mlockall
  int priority = 80;              // SCHED_FIFO priority
  double overrun_report_s = 1.0;  // at most one overrun warning per this many seconds
};

/// One period as the loop saw it: the executor's input and what it commanded (for an event log; `visco replay` runs
/// the executor again on `input` and compares).
struct CycleRecord {
  std::int64_t cycle = 0;
  ExecutorInput input;
  RobotCommand command;
  Mode mode = Mode::kIdle;
  std::int32_t step_index = -1;
  bool holding = false;
};
using CycleRecordQueue = SpscQueue<CycleRecord, 256>;

/// What the loop reads besides the driver.
struct LoopSources {
  drivers::RobotLink* link = nullptr;                  // required (SocketCAN, LCM or in-process)
  LatestValue<VisualFrame>* frames = nullptr;          // optional
  LatestValue<PositionEstimate>* estimates = nullptr;  // optional
  const std::atomic<bool>* estop = nullptr;            // optional
  CycleRecordQueue* records = nullptr;  // optional: every period's CycleRecord is pushed here (dropped when full)
};

/// Result of asking for real-time scheduling; `message` is the log line.
struct RealtimeSetup {
  bool fifo = false;
  bool locked = false;
  std::string message;
};

/// Tries mlockall(MCL_CURRENT | MCL_FUTURE) and SCHED_FIFO at `priority` for the calling thread, and prefaults the
/// stack. Not real-time safe (setup).
RealtimeSetup ConfigureRealtime(int priority, bool lock_memory);

/// Monotonic and wall clocks. Real-time safe (vDSO).
std::int64_t MonotonicNs();
std::int64_t WallUtime();

class ControlLoop {
 public:
  /// Not real-time safe. @throws std::invalid_argument if the period is outside [0.5 ms, 100 ms] or no link.
  ControlLoop(Executor& executor, const LoopSources& sources, const LoopConfig& config, Outbox& outbox);

  /// One read -> update -> write iteration at the given times, without sleeping. Real-time safe.
  void RunCycle(std::int64_t now_ns, std::int64_t now_utime);
  /// Runs timed cycles until `stop` is set, the executor finishes (then `linger_cycles` more, so the final zero
  /// command and telemetry go out), or `max_cycles` (<= 0: unlimited). Real-time safe once running.
  void Run(const std::atomic<bool>& stop, std::int64_t max_cycles = 0, int linger_cycles = 5);

  std::int64_t cycles() const { return cycles_; }
  std::int64_t overruns() const { return overruns_; }
  const JitterStats& total_jitter() const { return total_jitter_; }
  const ExecutorOutput& last_output() const { return output_; }
  const LoopConfig& config() const { return config_; }

 private:
  void PushTelemetry(std::int64_t now_utime);

  Executor& executor_;
  LoopSources sources_;
  LoopConfig config_;
  Outbox& outbox_;
  ExecutorInput input_;
  ExecutorOutput output_;
  VisualFrame frame_scratch_;
  PositionEstimate estimate_scratch_;
  drivers::RobotStatus status_scratch_;
  drivers::LinkFault fault_scratch_;
  int send_failures_ = 0;  // consecutive commands the link could not send
  drivers::LinkResult last_send_result_ = drivers::LinkResult::kOk;
  JitterStats window_jitter_;  // since the last telemetry sample
  JitterStats total_jitter_;   // since start
  std::int64_t cycles_ = 0;
  std::int64_t overruns_ = 0;
  std::int64_t last_overrun_report_ns_ = 0;
  CycleRecord record_scratch_;
  Mode last_mode_ = Mode::kIdle;
  std::int32_t last_step_ = -2;
  bool last_holding_ = false;
};

}  // namespace visco::control

#pragma once
// The controller's LCM side (not real-time): the vision inputs (visual events, robot estimate), the e-stop channel,
// and the publisher of telemetry, faults and the controller heartbeat. Two threads: one receives
// (lcm.handleTimeout), one drains the real-time loop's outbox and publishes (lcm-cpp's publish allocates, so the
// loop never calls it). The robot link (commands, status) is drivers::RobotLink, separate from this bridge.

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "common/latest_value.h"
#include "control/control_loop.h"
#include "control/spsc_queue.h"
#include "control/task.h"
#include "visco/robot_estimate_t.hpp"
#include "visco/visual_events_t.hpp"

namespace lcm {
class LCM;
class Subscription;
}  // namespace lcm

namespace visco::control {

/// Converts a capture time (utime, microseconds since the epoch) to the monotonic clock, given the reception time on
/// both clocks. A capture "in the future" (clock skew) counts as received now.
std::int64_t CaptureToMonotonic(std::int64_t capture_utime, std::int64_t receive_ns, std::int64_t receive_utime);

/// The loop's view of a visual_events_t received at `receive_ns` / `receive_utime`: ray ids resolved against `task`
/// (events of unknown rays are left out and counted in `unknown_rays`), capture time on the monotonic clock. The
/// bridge and `visco replay` use it. Not real-time safe.
VisualFrame ToVisualFrame(const visual_events_t& m, const Task& task, std::int64_t receive_ns,
                          std::int64_t receive_utime, std::uint64_t* unknown_rays = nullptr);
/// The loop's view of a robot_estimate_t (as ToVisualFrame). Not real-time safe.
PositionEstimate ToPositionEstimate(const robot_estimate_t& m, std::int64_t receive_ns, std::int64_t receive_utime);

struct BridgeCounters {
  std::atomic<std::uint64_t> frames{0};
  std::atomic<std::uint64_t> unknown_rays{0};
  std::atomic<std::uint64_t> estimates{0};
  std::atomic<std::uint64_t> faults{0};
  std::atomic<std::uint64_t> telemetry{0};
};

/// The bridge's clocks: receive times of vision's messages and the heartbeat's time. Empty: MonotonicNs and
/// WallUtime. A lockstep simulation sets its simulated clock here.
struct BridgeClock {
  std::function<std::int64_t()> monotonic_ns;
  std::function<std::int64_t()> wall_utime;
};

class ControllerBridge {
 public:
  /// Subscribes on `lcm` (which must outlive the bridge). `task` resolves visual events' ray ids. Not real-time safe.
  ControllerBridge(lcm::LCM& lcm, const Task& task, Outbox& outbox, BridgeClock clock = {});
  ~ControllerBridge();
  ControllerBridge(const ControllerBridge&) = delete;
  ControllerBridge& operator=(const ControllerBridge&) = delete;

  /// Starts the receive and publish threads.
  void Start();
  /// Drains the outbox one last time and joins the threads.
  void Stop();
  /// Publishes what the loop left in the outbox (faults, telemetry) and the controller's heartbeat when it is due: what
  /// the publish thread does when woken. Without Start() (a lockstep simulation: one thread, which also serves `lcm`
  /// for the receiving side) the caller calls it after each period. Not real-time safe.
  void Drain();

  LatestValue<VisualFrame>& frames() { return frames_; }
  LatestValue<PositionEstimate>& estimates() { return estimates_; }
  /// Set by an e-stop message on VISCO_ESTOP (or by the caller, e.g. on SIGINT).
  std::atomic<bool>& estop() { return estop_; }
  const BridgeCounters& counters() const { return counters_; }
  /// Newest telemetry sample published (for the caller's summary; copy taken on the publish thread).
  TelemetrySnapshot last_telemetry() const;

 private:
  class Handlers;
  void ReceiveLoop();
  void PublishLoop();
  std::int64_t NowNs() const;
  std::int64_t NowUtime() const;

  lcm::LCM& lcm_;
  const Task& task_;
  Outbox& outbox_;
  BridgeClock clock_;
  LatestValue<VisualFrame> frames_;
  LatestValue<PositionEstimate> estimates_;
  std::atomic<bool> estop_{false};
  std::atomic<bool> running_{false};
  std::unique_ptr<Handlers> handlers_;
  std::vector<lcm::Subscription*> subscriptions_;
  std::thread receiver_;
  std::thread publisher_;
  BridgeCounters counters_;
  std::int64_t last_heartbeat_ns_ = 0;
  std::int64_t heartbeat_cycles_ = -1;
  std::int32_t heartbeat_counter_ = 0;
  Mode logged_mode_ = Mode::kIdle;
  int logged_step_ = -2;
  mutable std::mutex telemetry_mutex_;  // publish thread <-> caller only; the loop never takes it
  TelemetrySnapshot last_telemetry_;
};

}  // namespace visco::control

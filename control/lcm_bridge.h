#pragma once
// The controller's LCM side (not real-time): an LCM robot link, the vision inputs and the publisher of commands,
// telemetry, faults and the controller heartbeat. Two threads: one receives (lcm.handleTimeout), one drains the
// real-time loop's outbox and publishes (lcm-cpp's publish allocates, so the loop never calls it).

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "common/latest_value.h"
#include "control/control_loop.h"
#include "control/robot_link.h"
#include "control/spsc_queue.h"
#include "control/task.h"

namespace lcm {
class LCM;
}

namespace visco::control {

/// RobotLink over LCM: commands go out on VISCO_COMMAND (published by ControllerBridge's thread), statuses come
/// in on VISCO_STATUS, heartbeats on VISCO_HEARTBEAT_DRIVER.
class LcmRobotLink final : public RobotLink {
 public:
  explicit LcmRobotLink(int node_id) : node_id_(node_id) {}
  // Controller side. Real-time safe.
  bool SendCommand(const RobotCommand& command) override { return commands_.TryPush(command); }
  bool PollStatus(RobotStatus& out) override { return status_.TryTake(out); }
  std::int64_t LastHeartbeatNs() const override { return heartbeat_ns_.load(std::memory_order_acquire); }

  // LCM side (not real-time safe).
  int node_id() const { return node_id_; }
  bool TakeCommand(RobotCommand& out) { return commands_.TryPop(out); }
  void PutStatus(const RobotStatus& status) { status_.Publish(status); }
  void PutHeartbeat(std::int64_t now_ns) { heartbeat_ns_.store(now_ns, std::memory_order_release); }
  std::size_t dropped_commands() const { return commands_.dropped(); }

 private:
  int node_id_;
  SpscQueue<RobotCommand, 64> commands_;
  LatestValue<RobotStatus> status_;
  std::atomic<std::int64_t> heartbeat_ns_{0};
};

/// Converts a capture time (utime, microseconds since the epoch) to the monotonic clock, given the reception time on
/// both clocks. A capture "in the future" (clock skew) counts as received now.
std::int64_t CaptureToMonotonic(std::int64_t capture_utime, std::int64_t receive_ns, std::int64_t receive_utime);

struct BridgeCounters {
  std::atomic<std::uint64_t> statuses{0};
  std::atomic<std::uint64_t> frames{0};
  std::atomic<std::uint64_t> unknown_rays{0};
  std::atomic<std::uint64_t> estimates{0};
  std::atomic<std::uint64_t> commands{0};
  std::atomic<std::uint64_t> faults{0};
  std::atomic<std::uint64_t> telemetry{0};
};

class ControllerBridge {
 public:
  /// Subscribes on `lcm` (which must outlive the bridge). `task` resolves visual events' ray ids. Not real-time safe.
  ControllerBridge(lcm::LCM& lcm, const Task& task, int node_id, Outbox& outbox);
  ~ControllerBridge();
  ControllerBridge(const ControllerBridge&) = delete;
  ControllerBridge& operator=(const ControllerBridge&) = delete;

  /// Starts the receive and publish threads.
  void Start();
  /// Drains the outbox one last time and joins the threads.
  void Stop();

  LcmRobotLink& link() { return link_; }
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
  void Drain();

  lcm::LCM& lcm_;
  const Task& task_;
  Outbox& outbox_;
  LcmRobotLink link_;
  LatestValue<VisualFrame> frames_;
  LatestValue<PositionEstimate> estimates_;
  std::atomic<bool> estop_{false};
  std::atomic<bool> running_{false};
  std::unique_ptr<Handlers> handlers_;
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

#pragma once
// An in-process RobotLink: commands and statuses are handed over through lock-free latest-value slots. The robot
// side (a simulated robot thread, or a test) calls the Robot* functions. Like ros2_control's mock hardware, it lets
// the loop run without any driver.

#include <atomic>
#include <cstdint>

#include "common/latest_value.h"
#include "control/robot_link.h"

namespace visco::control {

class LoopbackLink final : public RobotLink {
 public:
  // Controller side. Real-time safe.
  bool SendCommand(const RobotCommand& command) override {
    commands_.Publish(command);
    sent_.fetch_add(1, std::memory_order_relaxed);
    return true;
  }
  bool PollStatus(RobotStatus& out) override { return status_.TryTake(out); }
  std::int64_t LastHeartbeatNs() const override { return heartbeat_ns_.load(std::memory_order_acquire); }

  // Robot side (one thread). Real-time safe.
  /// Publishes a status (its receive_ns is the controller's reception time: set it to the current monotonic time).
  void RobotPublishStatus(const RobotStatus& status) { status_.Publish(status); }
  void RobotHeartbeat(std::int64_t now_ns) { heartbeat_ns_.store(now_ns, std::memory_order_release); }
  /// The newest command, if a new one arrived.
  bool RobotTakeCommand(RobotCommand& out) { return commands_.TryTake(out); }
  std::uint64_t commands_sent() const { return sent_.load(std::memory_order_relaxed); }

 private:
  LatestValue<RobotCommand> commands_;
  LatestValue<RobotStatus> status_;
  std::atomic<std::int64_t> heartbeat_ns_{0};
  std::atomic<std::uint64_t> sent_{0};
};

}  // namespace visco::control

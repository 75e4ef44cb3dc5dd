#pragma once
// The controller's view of the robot driver: send a command, poll the newest status, see the driver's heartbeat.
// Implementations: LcmRobotLink (lcm_bridge.h) here; the SocketCAN link lives in drivers/.

#include <cstdint>

#include "control/types.h"

namespace visco::control {

class RobotLink {
 public:
  virtual ~RobotLink() = default;
  /// Queues `command` for the driver. Returns false if it could not be queued (counted by the link).
  /// Real-time safe: no allocation, no blocking.
  virtual bool SendCommand(const RobotCommand& command) = 0;
  /// Copies the newest status into `out` if one arrived since the last call. Real-time safe.
  virtual bool PollStatus(RobotStatus& out) = 0;
  /// Monotonic time (ns) of the driver's last heartbeat, 0 if none yet. Real-time safe.
  virtual std::int64_t LastHeartbeatNs() const = 0;
};

}  // namespace visco::control

#pragma once
// What the SocketCAN and the LCM robot links share on the controller's side (internal to drivers/): the newest
// accepted status, handed to the loop once; the driver's liveness judged by the time of that status; the queue of
// faults for the loop, whose overflow is counted; the counters. Each link fills them from its own transport in Poll.
// Real-time safe.

#include <cstdint>

#include "drivers/ring.h"
#include "drivers/robot_link.h"

namespace visco::drivers {

class QueuedRobotLink : public RobotLink {
 public:
  LinkResult TakeStatus(RobotStatus& out) final {
    if (!fresh_status_) return LinkResult::kNoData;
    out = status_;
    fresh_status_ = false;
    return LinkResult::kOk;
  }
  LinkResult TakeFault(LinkFault& out) final { return faults_.Pop(out) ? LinkResult::kOk : LinkResult::kNoData; }
  PeerState peer_state(std::int64_t now_us) const final {
    if (last_status_us_ < 0) return PeerState::kUnknown;
    return now_us - last_status_us_ <= heartbeat_timeout_us_ ? PeerState::kAlive : PeerState::kLost;
  }
  LinkCounters counters() const final { return counters_; }

 protected:
  explicit QueuedRobotLink(std::int64_t heartbeat_timeout_us) : heartbeat_timeout_us_(heartbeat_timeout_us) {}

  /// Queues a fault for TakeFault; a full queue drops it and counts the drop.
  void QueueFault(const LinkFault& fault) {
    if (!faults_.Push(fault)) ++counters_.faults_dropped;
  }

  RobotStatus status_;                // the newest status for the loop; the link may fill it in parts
  bool fresh_status_ = false;         // status_ is new since the last TakeStatus
  std::int64_t last_status_us_ = -1;  // when the last accepted status arrived (-1: never)
  LinkCounters counters_;

 private:
  const std::int64_t heartbeat_timeout_us_;
  FixedQueue<LinkFault, 64> faults_;
};

}  // namespace visco::drivers

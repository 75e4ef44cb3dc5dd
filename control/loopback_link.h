#pragma once
// An in-process drivers::RobotLink: commands and statuses are handed over through lock-free latest-value slots, so
// the control loop runs against a robot simulated in the same process (tests, benchmarks) exactly as it runs
// against the SocketCAN or LCM link. Like ros2_control's mock hardware. The robot side (one thread) calls Robot*.

#include <atomic>
#include <cstdint>

#include "common/latest_value.h"
#include "drivers/robot_link.h"

namespace visco::control {

class LoopbackLink final : public drivers::RobotLink {
 public:
  /// @param heartbeat_timeout_us peer lost when no heartbeat for this long.
  explicit LoopbackLink(std::int64_t heartbeat_timeout_us = 300'000) : heartbeat_timeout_us_(heartbeat_timeout_us) {}

  // Controller side. Real-time safe.
  drivers::LinkResult SendCommand(const drivers::VelocityCommand& command, std::int64_t now_us) override {
    Sent sent{command, ++seq_, now_us};
    commands_.Publish(sent);
    ++counters_.commands_sent;
    return drivers::LinkResult::kOk;
  }
  void Poll(std::int64_t now_us) override {
    drivers::RobotStatus s;
    if (status_.TryTake(s)) {
      s.receive_us = now_us;
      status_cache_ = s;
      fresh_ = true;
      ++counters_.statuses_received;
    }
    const std::uint64_t beats = beats_.load(std::memory_order_acquire);
    if (beats != beats_seen_) {
      beats_seen_ = beats;
      last_heartbeat_us_ = now_us;
      ++counters_.heartbeats_received;
    }
  }
  drivers::LinkResult TakeStatus(drivers::RobotStatus& out) override {
    if (!fresh_) return drivers::LinkResult::kNoData;
    out = status_cache_;
    fresh_ = false;
    return drivers::LinkResult::kOk;
  }
  drivers::LinkResult TakeFault(drivers::LinkFault&) override { return drivers::LinkResult::kNoData; }
  drivers::PeerState peer_state(std::int64_t now_us) const override {
    if (last_heartbeat_us_ < 0) return drivers::PeerState::kUnknown;
    return now_us - last_heartbeat_us_ <= heartbeat_timeout_us_ ? drivers::PeerState::kAlive
                                                                : drivers::PeerState::kLost;
  }
  drivers::NmtState peer_nmt_state() const override { return drivers::NmtState::kOperational; }
  drivers::BusState bus_state() const override { return drivers::BusState::kActive; }
  std::uint32_t last_command_seq() const override { return seq_; }
  std::uint32_t session() const override { return 1; }  // in-process: one session for the link's life
  drivers::LinkCounters counters() const override { return counters_; }

  // Robot side (one thread). Real-time safe.
  struct Sent {
    drivers::VelocityCommand command;
    std::uint32_t seq = 0;
    std::int64_t sent_us = 0;
  };
  void RobotPublishStatus(const drivers::RobotStatus& status) { status_.Publish(status); }
  void RobotHeartbeat() { beats_.fetch_add(1, std::memory_order_release); }
  /// The newest command, if a new one arrived.
  bool RobotTakeCommand(Sent& out) { return commands_.TryTake(out); }

 private:
  const std::int64_t heartbeat_timeout_us_;
  LatestValue<Sent> commands_;
  LatestValue<drivers::RobotStatus> status_;
  std::atomic<std::uint64_t> beats_{0};
  // Controller side only.
  std::uint32_t seq_ = 0;
  drivers::RobotStatus status_cache_;
  bool fresh_ = false;
  std::uint64_t beats_seen_ = 0;
  std::int64_t last_heartbeat_us_ = -1;
  drivers::LinkCounters counters_;
};

}  // namespace visco::control

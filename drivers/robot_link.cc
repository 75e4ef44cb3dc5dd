#include "drivers/robot_link.h"

#include <ctime>

namespace visco::drivers {
namespace {

std::int64_t ClockMicros(clockid_t clock) {
  timespec ts{};
  clock_gettime(clock, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000 + ts.tv_nsec / 1000;
}

}  // namespace

const char* ToString(LinkResult result) {
  switch (result) {
    case LinkResult::kOk:
      return "ok";
    case LinkResult::kNoData:
      return "no data";
    case LinkResult::kBusOff:
      return "bus-off";
    case LinkResult::kBufferFull:
      return "buffer full";
    case LinkResult::kOutOfRange:
      return "out of range";
    case LinkResult::kError:
      return "error";
    case LinkResult::kNoSession:
      return "no session";
  }
  return "?";
}

const char* ToString(RobotState state) {
  switch (state) {
    case RobotState::kDisabled:
      return "disabled";
    case RobotState::kReady:
      return "ready";
    case RobotState::kMoving:
      return "moving";
    case RobotState::kStopped:
      return "stopped";
    case RobotState::kEStop:
      return "estop";
  }
  return "?";
}

const char* ToString(PeerState state) {
  switch (state) {
    case PeerState::kUnknown:
      return "unknown";
    case PeerState::kAlive:
      return "alive";
    case PeerState::kLost:
      return "lost";
  }
  return "?";
}

std::int64_t MonotonicMicros() { return ClockMicros(CLOCK_MONOTONIC); }
std::int64_t WallMicros() { return ClockMicros(CLOCK_REALTIME); }

}  // namespace visco::drivers

#include "drivers/driver.h"

#include <spdlog/spdlog.h>
#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "common/error.h"
#include "visco/fault_t.hpp"

namespace visco::drivers {

Driver::Driver(const DriverConfig& config, DriverTransport& transport, RobotInterface& robot)
    : config_(config), transport_(transport), robot_(robot) {
  if (config.watchdog_us <= 0) throw InputError("command line", "--watchdog-ms", "must be positive");
  if (config.period_us <= 0) throw InputError("command line", "--period-us", "must be positive");
  if (config.status_period_us <= 0) throw InputError("command line", "--status-period-ms", "must be positive");
  if (config.heartbeat_period_us <= 0) throw InputError("command line", "--heartbeat-ms", "must be positive");
  if (!(config.max_speed > 0.0)) throw InputError("command line", "--max-speed", "must be positive");
}

void Driver::Start(std::int64_t now_us) {
  transport_.SendHeartbeat(NmtState::kBootUp);
  last_update_us_ = now_us;
  next_status_us_ = now_us;
  next_heartbeat_us_ = now_us + config_.heartbeat_period_us;
}

void Driver::Update(std::int64_t now_us) {
  // A bounded number of events per call: they are all taken to have arrived at `now_us`, so draining a queue that
  // keeps filling (a slow CPU, a flood of frames) must not go on with an ever older `now_us`. Run() calls again at
  // once with a fresh time.
  constexpr int kMaxEventsPerUpdate = 16;
  DriverEvent event;
  bool drained = false;
  for (int handled = 0; handled < kMaxEventsPerUpdate; ++handled) {
    if (!transport_.NextEvent(now_us, event)) {
      drained = true;
      break;
    }
    switch (event.kind) {
      case DriverEventKind::kCommand:
        OnCommand(event, now_us);
        break;
      case DriverEventKind::kBadCommand:
        ++stats_.bad_commands;
        SetFault(fault_bits::kBadFrame,
                 event.decode == can::DecodeStatus::kBadLength ? can::kEmcyPdoLength : can::kEmcyProtocol,
                 fault_t::CODE_BAD_MESSAGE, false, can::ToString(event.decode));
        SendStatus(now_us);  // the answer shows the fault bit
        break;
      case DriverEventKind::kEStop:
        EStop(now_us, "NMT stop");
        break;
      case DriverEventKind::kResetRequest:
        OnReset(now_us);
        break;
      case DriverEventKind::kBusOff:
        ++stats_.bus_offs;
        bus_off_ = true;
        if (state_ == RobotState::kReady || state_ == RobotState::kMoving) StopRobot(RobotState::kStopped);
        fault_bits_ = static_cast<std::uint16_t>(fault_bits_ | fault_bits::kBus);
        // Announced even when error passive set the bit before: bus-off stops the robot. (While the interface is
        // down the EMCY cannot go out; the bus-off-recovered EMCY reports the stop when it is back.)
        Announce(can::kEmcyBusOff, fault_t::CODE_CAN_ERROR, true, false, "CAN bus-off: robot stopped");
        break;
      case DriverEventKind::kBusRestarted:
        bus_off_ = false;
        ClearFault(fault_bits::kBus);
        Announce(can::kEmcyBusOffRecovered, fault_t::CODE_CAN_ERROR, state_ == RobotState::kStopped, true,
                 "CAN bus recovered from bus-off");
        break;
      case DriverEventKind::kBusPassive:
        SetFault(fault_bits::kBus, can::kEmcyCanPassive, fault_t::CODE_CAN_ERROR, false, "CAN error passive");
        break;
      case DriverEventKind::kBusActive:
        if (!bus_off_) {
          ClearFault(fault_bits::kBus);
          Announce(can::kEmcyNoError, fault_t::CODE_CAN_ERROR, false, true, "CAN back to error active");
        }
        break;
      case DriverEventKind::kFramesDropped: {
        char message[80];
        std::snprintf(message, sizeof(message), "kernel dropped %u received frames", event.count);
        Announce(can::kEmcyCanOverrun, fault_t::CODE_CAN_ERROR, false, false, message);
        break;
      }
    }
  }

  // Watchdog, once every pending event has been looked at (a valid command may still wait in the queue).
  if (drained && last_valid_us_ >= 0 && (state_ == RobotState::kReady || state_ == RobotState::kMoving) &&
      now_us - last_valid_us_ > config_.watchdog_us) {
    ++stats_.watchdog_stops;
    StopRobot(RobotState::kStopped);
    char message[100];
    std::snprintf(message, sizeof(message), "no valid command for %.1f ms (watchdog %.1f ms): robot stopped",
                  (now_us - last_valid_us_) / 1e3, config_.watchdog_us / 1e3);
    SetFault(fault_bits::kWatchdog, can::kEmcyRpdoTimeout, fault_t::CODE_PEER_TIMEOUT, true, message);
  }

  // Robot.
  if (last_update_us_ >= 0 && now_us > last_update_us_) robot_.Step((now_us - last_update_us_) * 1e-6);
  last_update_us_ = now_us;
  const RobotFeedback feedback = robot_.Read();
  // Leaving the workspace stops the robot once per episode; after a reset it may move (back in) from outside,
  // and the episode ends when it is inside again.
  if (feedback.out_of_bounds && !out_of_bounds_) {
    ++stats_.bounds_stops;
    StopRobot(RobotState::kStopped);
    char message[100];
    std::snprintf(message, sizeof(message), "robot outside its workspace at (%.3f, %.3f) m: robot stopped",
                  feedback.position[0], feedback.position[1]);
    SetFault(fault_bits::kBounds, can::kEmcyBounds, fault_t::CODE_LIMIT, true, message);
  }
  out_of_bounds_ = feedback.out_of_bounds;

  if (now_us >= next_status_us_) SendStatus(now_us);
  if (now_us >= next_heartbeat_us_) {
    transport_.SendHeartbeat(NmtState::kOperational);
    next_heartbeat_us_ = now_us + config_.heartbeat_period_us;
  }
}

void Driver::OnCommand(const DriverEvent& event, std::int64_t now_us) {
  const std::uint32_t modulus = transport_.sequence_modulus();
  if (have_seq_ && !SequenceAdvances(last_seq_, event.seq, modulus)) {
    ++stats_.out_of_sequence;
    char message[100];
    std::snprintf(message, sizeof(message), "command %u out of sequence (last accepted %u): ignored", event.seq,
                  last_seq_);
    SetFault(fault_bits::kSequence, can::kEmcyProtocol, fault_t::CODE_BAD_MESSAGE, false, message);
    SendStatus(now_us);  // the answer shows the fault bit and the last accepted sequence number
    return;
  }
  if (have_seq_) stats_.sequence_gaps += (event.seq + modulus - last_seq_) % modulus - 1;
  have_seq_ = true;
  last_seq_ = event.seq;
  last_valid_us_ = std::max(now_us, event.receive_us);
  ClearFault(fault_bits::kBadFrame);
  ClearFault(fault_bits::kSequence);

  if (event.command.estop) {
    EStop(now_us, "e-stop requested by the controller");
  } else if (event.command.reset) {
    OnReset(now_us);
  } else if (state_ == RobotState::kReady || state_ == RobotState::kMoving) {
    double v[2] = {event.command.velocity[0], event.command.velocity[1]};
    const double speed = std::hypot(v[0], v[1]);
    if (speed > config_.max_speed) {
      v[0] *= config_.max_speed / speed;
      v[1] *= config_.max_speed / speed;
      char message[100];
      std::snprintf(message, sizeof(message), "commanded speed %.3f m/s clamped to %.3f m/s", speed, config_.max_speed);
      SetFault(fault_bits::kLimit, can::kEmcyVelocityLimit, fault_t::CODE_LIMIT, false, message);
    } else {
      ClearFault(fault_bits::kLimit);
    }
    robot_.SetVelocity(v);
    state_ = (v[0] != 0.0 || v[1] != 0.0) ? RobotState::kMoving : RobotState::kReady;
    ++stats_.commands_applied;
  }
  SendStatus(now_us);  // every command gets an answer with its sequence number
}

void Driver::OnReset(std::int64_t now_us) {
  ++stats_.resets;
  if (bus_off_) return;  // cannot reset while the bus is off
  const bool was_latched = state_ == RobotState::kStopped || state_ == RobotState::kEStop || fault_bits_ != 0;
  const double zero[2] = {0.0, 0.0};
  robot_.SetVelocity(zero);
  fault_bits_ = 0;
  state_ = RobotState::kReady;
  last_valid_us_ = std::max(last_valid_us_, now_us);  // a reset command already set it to its arrival
  if (was_latched) Announce(can::kEmcyNoError, fault_t::CODE_NONE, false, true, "reset: faults cleared, ready");
}

void Driver::EStop(std::int64_t /*now_us*/, const char* why) {
  ++stats_.estops;
  StopRobot(RobotState::kEStop);
  SetFault(fault_bits::kEStop, can::kEmcyGeneric, fault_t::CODE_ESTOP, true, why);
}

void Driver::StopRobot(RobotState state) {
  robot_.QuickStop();
  state_ = state;
}

void Driver::SetFault(std::uint16_t bit, std::uint16_t emcy, std::int32_t code, bool stopped, const char* message) {
  if (fault_bits_ & bit) return;  // one announcement per episode
  fault_bits_ = static_cast<std::uint16_t>(fault_bits_ | bit);
  Announce(emcy, code, stopped, false, message);
}

void Driver::ClearFault(std::uint16_t bit) { fault_bits_ = static_cast<std::uint16_t>(fault_bits_ & ~bit); }

void Driver::Announce(std::uint16_t emcy, std::int32_t code, bool stopped, bool cleared, const char* message) {
  DriverFault fault;
  fault.emcy_code = emcy;
  fault.code = code;
  fault.severity = cleared ? fault_t::SEVERITY_INFO : (stopped ? fault_t::SEVERITY_ERROR : fault_t::SEVERITY_WARNING);
  fault.fault_bits = fault_bits_;
  fault.robot_stopped = stopped;
  fault.cleared = cleared;
  std::snprintf(fault.message, sizeof(fault.message), "%s", message);
  if (transport_.SendFault(fault) == LinkResult::kOk) {
    ++stats_.faults_sent;
  } else {
    ++stats_.send_failures;
  }
  if (cleared) {
    spdlog::info("driver: {} (EMCY 0x{:04X})", message, emcy);
  } else {
    spdlog::warn("driver: {} (EMCY 0x{:04X}, fault bits 0x{:02X}{})", message, emcy, fault_bits_,
                 stopped ? ", robot stopped" : "");
  }
}

void Driver::SendStatus(std::int64_t now_us) {
  const RobotFeedback feedback = robot_.Read();
  RobotStatus status;
  status.utime = WallMicros();
  status.seq = ++status_seq_ % transport_.sequence_modulus();
  status.command_seq = last_seq_;
  for (int i = 0; i < 2; ++i) {
    status.position[i] = feedback.position[i];
    status.velocity[i] = feedback.velocity[i];
    status.contact_force[i] = feedback.contact_force[i];
  }
  status.contact = feedback.contact;
  status.state = state_;
  status.fault_bits = fault_bits_;
  if (transport_.SendStatus(status) == LinkResult::kOk) {
    ++stats_.statuses_sent;
  } else {
    ++stats_.send_failures;
  }
  next_status_us_ = now_us + config_.status_period_us;
}

void Driver::Run(const std::atomic<bool>& stop) {
  std::int64_t next = MonotonicMicros();
  Start(next);
  while (!stop.load(std::memory_order_relaxed)) {
    next += config_.period_us;
    std::int64_t now = MonotonicMicros();
    if (next < now) next = now;  // overran: do not try to catch up
    // Sleep until the next period, waking early when a frame arrives so that commands are answered at once.
    while (now < next && !stop.load(std::memory_order_relaxed)) {
      transport_.Wait(next - now);
      now = MonotonicMicros();
      Update(now);
    }
    Update(MonotonicMicros());
  }
}

}  // namespace visco::drivers

#include "drivers/driver.h"

#include <spdlog/spdlog.h>
#include <sys/random.h>
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
  rng_ = config.session_seed;
  if (rng_ == 0 && getrandom(&rng_, sizeof(rng_), GRND_NONBLOCK) != static_cast<ssize_t>(sizeof(rng_))) {
    timespec ts{};
    clock_gettime(CLOCK_REALTIME, &ts);  // no entropy yet (early boot): the clock still differs per start
    rng_ = static_cast<std::uint64_t>(ts.tv_sec) * 1'000'000'000ULL + static_cast<std::uint64_t>(ts.tv_nsec);
  }
  PublishSnapshot(robot_.Read());
}

std::uint32_t Driver::NextNonce() {
  // splitmix64 (Steele, Lea, Flood 2014): every seed gives a long, well-mixed sequence.
  rng_ += 0x9E3779B97F4A7C15ULL;
  std::uint64_t z = rng_;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return static_cast<std::uint32_t>((z ^ (z >> 31)) >> 16);
}

void Driver::NewSession(std::int64_t now_us) {
  const auto tag_is_recent = [this](std::uint32_t nonce) {
    const int n = std::min(recent_tag_count_, kRecentTags);
    return std::find(recent_tags_.begin(), recent_tags_.begin() + n, static_cast<std::uint8_t>(nonce)) !=
           recent_tags_.begin() + n;
  };
  std::uint32_t nonce = NextNonce();
  while (nonce == 0 || tag_is_recent(nonce)) nonce = NextNonce();
  recent_tags_[recent_tag_count_ % kRecentTags] = static_cast<std::uint8_t>(nonce);
  ++recent_tag_count_;
  if (recent_tag_count_ == 2 * kRecentTags) recent_tag_count_ = kRecentTags;  // the ring is full; keep it bounded
  session_ = nonce;
  last_seq_ = 0;
  accepted_frames_.Clear();
  last_valid_us_ = -1;  // the watchdog waits for the session's first command
  session_expired_ = false;
  ++stats_.sessions;
  session_announced_ = transport_.SendSession(session_, status_seq_) == LinkResult::kOk;
  if (!session_announced_) ++stats_.send_failures;
  spdlog::info("driver: session 0x{:08X} ({})", session_, ToString(state_));
  SendStatus(now_us);
}

void Driver::Start(std::int64_t now_us) {
  transport_.SendHeartbeat(NmtState::kBootUp);
  last_update_us_ = now_us;
  next_heartbeat_us_ = now_us + config_.heartbeat_period_us;
  state_ = RobotState::kDisabled;
  NewSession(now_us);
  PublishSnapshot(robot_.Read());
}

void Driver::Update(std::int64_t now_us) {
  // A bounded number of events per call: they are all taken to have arrived at `now_us`, so draining a queue that
  // keeps filling (a slow CPU, a flood of frames) must not go on with an ever older `now_us`. Run() calls again at
  // once with a fresh time.
  constexpr int kMaxEventsPerUpdate = 16;
  if (operator_release_.exchange(false, std::memory_order_relaxed)) OnOperatorRelease();
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
        OnNmtReset();
        break;
      case DriverEventKind::kNmtStart:
        OnNmtStart();
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
      case DriverEventKind::kBusWarning:  // reported, nothing else: the bus still works
        Announce(can::kEmcyCanWarning, fault_t::CODE_CAN_ERROR, false, false, "CAN error warning");
        break;
      case DriverEventKind::kBusActive:
        if (!bus_off_) {
          ClearFault(fault_bits::kBus);
          Announce(can::kEmcyNoError, fault_t::CODE_CAN_ERROR, false, true, "CAN back to error active");
        }
        break;
      case DriverEventKind::kFramesDropped:
        // Counted at once, reported at most once per kDropReportIntervalUs (below): a flood must not become a flood
        // of EMCY frames and log lines.
        stats_.frames_dropped += event.count;
        drops_unreported_ += event.count;
        break;
    }
  }

  if (drops_unreported_ > 0 && now_us - last_drop_report_us_ >= kDropReportIntervalUs) {
    char message[96];
    std::snprintf(message, sizeof(message), "kernel dropped %llu received frames (receive queue full)",
                  static_cast<unsigned long long>(drops_unreported_));
    Announce(can::kEmcyCanOverrun, fault_t::CODE_CAN_ERROR, false, false, message);
    drops_unreported_ = 0;
    last_drop_report_us_ = now_us;
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
  // A session that accepted commands and hears none for a watchdog period ends, whatever the state: a controller
  // that comes later starts from a fresh session, and the old controller's frames are void.
  if (drained && last_seq_ != 0 && last_valid_us_ >= 0 && now_us - last_valid_us_ > config_.watchdog_us) {
    session_expired_ = true;
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
  if (feedback.fault && !robot_fault_) {
    ++stats_.robot_faults;
    // (A disabled or e-stopped driver stays so: the robot is stopped all the same.)
    StopRobot(state_ == RobotState::kReady || state_ == RobotState::kMoving ? RobotState::kStopped : state_);
    if (feedback.fault_bus) fault_bits_ = static_cast<std::uint16_t>(fault_bits_ | fault_bits::kBus);
    const std::int32_t code = feedback.fault_bus ? static_cast<std::int32_t>(fault_t::CODE_CAN_ERROR)
                                                 : static_cast<std::int32_t>(fault_t::CODE_ROBOT_FAULT);
    Announce(feedback.fault_code, code, true, false,
             feedback.fault_message[0] != '\0' ? feedback.fault_message : "robot fault");
  }
  robot_fault_ = feedback.fault;

  if (session_expired_) NewSession(now_us);  // after this update's EMCYs, which say why
  if (now_us >= next_status_us_) SendStatus(now_us);
  if (now_us >= next_heartbeat_us_) {
    transport_.SendHeartbeat(NmtState::kOperational);
    // For controllers and tools that join later.
    session_announced_ = transport_.SendSession(session_, status_seq_) == LinkResult::kOk || session_announced_;
    next_heartbeat_us_ = now_us + config_.heartbeat_period_us;
  }
  PublishSnapshot(feedback);
}

void Driver::OnCommand(const DriverEvent& event, std::int64_t now_us) {
  const std::uint32_t modulus = transport_.sequence_modulus();
  std::uint32_t seq = event.seq;
  const can::CommandVerdict verdict =
      event.has_frame ? can::JudgeCommand(event.frame, session_, last_seq_, kCommandWindow, seq, &accepted_frames_)
                      : JudgeSequence(event.session, event.seq, session_, last_seq_, kCommandWindow, modulus);
  // An e-stop is honoured from any well-formed command frame, whatever its session, number or checksum.
  if (event.command.estop) {
    EStop(now_us, verdict == can::CommandVerdict::kAccept ? "e-stop requested by the controller"
                                                          : "e-stop flag in a command of no valid session (honoured)");
  } else if (event.command.quick_stop) {
    QuickStopRequested(verdict == can::CommandVerdict::kAccept);
  }
  if (session_expired_ && verdict == can::CommandVerdict::kAccept && !event.command.estop &&
      !event.command.quick_stop) {
    // The session ended earlier in this update (a stop, the operator's release) and the next one starts at its end:
    // frames of the ended session still queued, sent before the stop, are void already (found in the HIL VM: a
    // reset sent during an e-stop, read just after the operator's release, enabled the driver).
    ++stats_.wrong_session;
    return;
  }
  if (verdict != can::CommandVerdict::kAccept) {
    Reject(verdict, event, seq);
    // The answer shows the fault bit and the last accepted number; at most one per kRejectAnswerIntervalUs, so that
    // a flood of bad frames does not become three times as many status frames on the bus.
    if (now_us - last_status_us_ >= kRejectAnswerIntervalUs) SendStatus(now_us);
    return;
  }
  stats_.sequence_gaps += (seq + modulus - last_seq_) % modulus - 1;
  last_seq_ = seq;
  if (event.has_frame) accepted_frames_.Add(event.frame);
  last_valid_us_ = std::max(now_us, event.receive_us);
  ClearFault(fault_bits::kBadFrame);
  ClearFault(fault_bits::kSequence);
  ClearFault(fault_bits::kSession);

  if (event.command.estop || event.command.quick_stop) {
    // Stopped above.
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
  SendStatus(now_us);  // every command gets an answer with its number
}

void Driver::Reject(can::CommandVerdict verdict, const DriverEvent& event, std::uint32_t seq) {
  char message[120];
  switch (verdict) {
    case can::CommandVerdict::kWrongSession:
      ++stats_.wrong_session;
      std::snprintf(message, sizeof(message), "command of another session (0x%X, current 0x%08X): ignored",
                    event.session, session_);
      SetFault(fault_bits::kSession, can::kEmcyProtocol, fault_t::CODE_BAD_MESSAGE, false, message);
      return;
    case can::CommandVerdict::kStale:
      ++stats_.out_of_sequence;
      std::snprintf(message, sizeof(message), "command %u is stale (last accepted %u): a duplicate or replay, ignored",
                    seq, last_seq_);
      SetFault(fault_bits::kSequence, can::kEmcyProtocol, fault_t::CODE_BAD_MESSAGE, false, message);
      return;
    case can::CommandVerdict::kRepeat:
      ++stats_.out_of_sequence;
      std::snprintf(message, sizeof(message),
                    "command frame repeats one accepted earlier in this session (a replay): ignored");
      SetFault(fault_bits::kSequence, can::kEmcyProtocol, fault_t::CODE_BAD_MESSAGE, false, message);
      return;
    case can::CommandVerdict::kAhead:
      ++stats_.out_of_sequence;
      std::snprintf(message, sizeof(message), "command %u is more than %u ahead of the last accepted %u: ignored", seq,
                    kCommandWindow, last_seq_);
      SetFault(fault_bits::kSequence, can::kEmcyProtocol, fault_t::CODE_BAD_MESSAGE, false, message);
      return;
    case can::CommandVerdict::kBadChecksum:
    case can::CommandVerdict::kAccept:
      break;
  }
  ++stats_.bad_commands;
  SetFault(fault_bits::kBadFrame, can::kEmcyProtocol, fault_t::CODE_BAD_MESSAGE, false,
           "bad checksum for this session (corrupted, or replayed from an earlier wrap of the counter): ignored");
}

void Driver::RefuseWhileEStop(const char* what) {
  ++stats_.refused_resets;
  if (refusal_announced_) return;  // once per e-stop episode
  refusal_announced_ = true;
  char message[120];
  std::snprintf(message, sizeof(message), "%s refused: e-stop latched, the operator must release it at the driver",
                what);
  Announce(can::kEmcyResetRefused, fault_t::CODE_ESTOP, true, false, message);
}

void Driver::OnReset(std::int64_t now_us) {
  ++stats_.resets;
  if (state_ == RobotState::kEStop) {
    RefuseWhileEStop("reset");
    return;
  }
  if (bus_off_) return;  // cannot reset while the bus is off
  const bool was_latched =
      (state_ != RobotState::kReady && state_ != RobotState::kMoving) || fault_bits_ != 0 || robot_fault_;
  const double zero[2] = {0.0, 0.0};
  robot_.SetVelocity(zero);
  robot_.Reset();  // a robot's own fault: its fault reset; a fault that persists is reported again
  robot_fault_ = false;
  fault_bits_ = 0;
  state_ = RobotState::kReady;
  last_valid_us_ = std::max(last_valid_us_, now_us);  // a reset command already set it to its arrival
  if (was_latched) Announce(can::kEmcyNoError, fault_t::CODE_NONE, false, true, "reset: faults cleared, ready");
}

void Driver::OnNmtReset() {
  ++stats_.nmt_resets;
  StopRobot(state_ == RobotState::kEStop ? RobotState::kEStop : RobotState::kDisabled);
  fault_bits_ = static_cast<std::uint16_t>(fault_bits_ & (fault_bits::kEStop | fault_bits::kBus));
  transport_.SendHeartbeat(NmtState::kBootUp);  // CANopen: a reset node boots up again
  spdlog::warn("driver: NMT reset: restarting the session ({})", ToString(state_));
}

void Driver::OnNmtStart() {
  ++stats_.nmt_starts;
  if (state_ == RobotState::kEStop) RefuseWhileEStop("NMT start");
}

void Driver::OnOperatorRelease() {
  if (state_ != RobotState::kEStop) {
    spdlog::info("driver: operator release: no e-stop latched ({})", ToString(state_));
    return;
  }
  ++stats_.operator_releases;
  const double zero[2] = {0.0, 0.0};
  robot_.SetVelocity(zero);
  fault_bits_ = static_cast<std::uint16_t>(fault_bits_ & fault_bits::kBus);
  state_ = RobotState::kDisabled;
  refusal_announced_ = false;
  session_expired_ = true;
  Announce(can::kEmcyNoError, fault_t::CODE_ESTOP, false, true,
           "e-stop released by the operator: disabled until a controller's reset");
}

void Driver::EStop(std::int64_t /*now_us*/, const char* why) {
  if (state_ == RobotState::kEStop) {
    robot_.QuickStop();
    return;
  }
  ++stats_.estops;
  StopRobot(RobotState::kEStop);
  refusal_announced_ = false;
  SetFault(fault_bits::kEStop, can::kEmcyGeneric, fault_t::CODE_ESTOP, true, why);
}

void Driver::QuickStopRequested(bool valid) {
  robot_.QuickStop();
  if (state_ != RobotState::kReady && state_ != RobotState::kMoving) return;  // stopped already
  ++stats_.quick_stops;
  StopRobot(RobotState::kStopped);
  Announce(can::kEmcyQuickStop, fault_t::CODE_NONE, true, false,
           valid ? "quick stop requested by the controller: robot stopped"
                 : "quick-stop flag in a command of no valid session (honoured): robot stopped");
}

void Driver::StopRobot(RobotState state) {
  robot_.QuickStop();
  state_ = state;
  session_expired_ = true;  // every stop ends the session: frames of the controller that ran are void
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
  if (!session_announced_) {
    // The announcement was lost (the bus or the interface failed): it goes first, or the status waits.
    session_announced_ = transport_.SendSession(session_, status_seq_) == LinkResult::kOk;
    if (!session_announced_) {
      ++stats_.send_failures;
      next_status_us_ = now_us + config_.status_period_us;
      return;
    }
  }
  const RobotFeedback feedback = robot_.Read();
  RobotStatus status;
  status.utime = WallMicros();
  status.session = session_;
  status.seq = ++status_seq_;
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
  last_status_us_ = now_us;
}

void Driver::PublishSnapshot(const RobotFeedback& robot) {
  DriverSnapshot s;
  s.state = state_;
  s.fault_bits = fault_bits_;
  s.session = session_;
  s.stats = stats_;
  s.robot = robot;
  snapshot_.Publish(s);
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

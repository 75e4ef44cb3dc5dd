// SocketCAN implementations of RobotLink (controller side) and DriverTransport (driver side).

#include <algorithm>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <utility>

#include "common/error.h"
#include "drivers/can_protocol.h"
#include "drivers/driver_transport.h"
#include "drivers/queued_robot_link.h"
#include "drivers/ring.h"
#include "drivers/robot_link.h"
#include "drivers/socketcan.h"
#include "visco/fault_t.hpp"

namespace visco::drivers {
namespace {

constexpr std::uint32_t kStdDataMask = can::kSffMask | can::kEffFlag | can::kRtrFlag;
constexpr int kMaxFramesPerPoll = 512;  // bounds the time one Poll() can take

void CheckNode(int node) {
  if (node < can::kMinNode || node > can::kMaxNode) {
    throw InputError("command line", "--node", "CAN node id " + std::to_string(node) + " is outside 1..127");
  }
}

CanFilter Exact(std::uint32_t id) { return CanFilter{id, kStdDataMask}; }

// Tracks the bus from error frames and from ENETDOWN; shared by both sides.
class BusTracker {
 public:
  // Applies an error frame; returns the transition it caused (or none).
  enum class Change { kNone, kOff, kRestarted, kPassive, kWarning, kActive };
  Change OnErrorFrame(const can::ErrorFrameInfo& info) {
    if (info.bus_off) return Set(BusState::kBusOff) ? Change::kOff : Change::kNone;
    if (info.restarted) return Set(BusState::kActive) ? Change::kRestarted : Change::kNone;
    if (info.error_passive) return Set(BusState::kPassive) ? Change::kPassive : Change::kNone;
    if (info.error_warning && state_ == BusState::kActive) {
      return Set(BusState::kWarning) ? Change::kWarning : Change::kNone;
    }
    if (info.back_to_active && state_ != BusState::kBusOff) {
      return Set(BusState::kActive) ? Change::kActive : Change::kNone;
    }
    return Change::kNone;
  }
  // The interface is down (ENETDOWN on read or write).
  Change OnNetDown() {
    net_down_ = true;
    return Set(BusState::kBusOff) ? Change::kOff : Change::kNone;
  }
  // A write succeeded or a data frame arrived: an interface that was down is up again.
  Change OnTraffic() {
    if (!net_down_) return Change::kNone;
    net_down_ = false;
    return Set(BusState::kActive) ? Change::kRestarted : Change::kNone;
  }
  BusState state() const { return state_; }

 private:
  bool Set(BusState s) {
    if (s == state_) return false;
    state_ = s;
    return true;
  }
  BusState state_ = BusState::kActive;
  bool net_down_ = false;
};

// ---------------------------------------------------------------------------------------------------------------
class SocketCanRobotLink final : public QueuedRobotLink {
 public:
  explicit SocketCanRobotLink(const RobotLinkConfig& config)
      : SocketCanRobotLink(config, std::make_unique<CanSocket>(RxOptions(config)),
                           std::make_unique<CanSocket>(CanSocketOptions{config.can_interface, false, {}, 0, 0})) {}
  SocketCanRobotLink(const RobotLinkConfig& config, std::unique_ptr<CanPort> receive, std::unique_ptr<CanPort> send)
      : QueuedRobotLink(config.heartbeat_timeout_us),
        node_((CheckNode(config.node_id), config.node_id)),
        rx_holder_(std::move(receive)),
        tx_holder_(std::move(send)),
        rx_(*rx_holder_),
        tx_(*tx_holder_) {}

  LinkResult SendCommand(const VelocityCommand& command, std::int64_t now_us) override {
    // Without a session only an e-stop goes out (the driver honours its flag whatever the session).
    if (!session_.usable() && !command.estop && !command.quick_stop) return LinkResult::kNoSession;
    can::CommandFrame wire;
    wire.seq = session_.Next();
    wire.session = session_.session();
    wire.estop = command.estop;
    wire.reset = command.reset;
    wire.quick_stop = command.quick_stop;
    wire.velocity[0] = command.velocity[0];
    wire.velocity[1] = command.velocity[1];
    if (wire.session != sent_session_) {
      sent_frames_.Clear();
      sent_session_ = wire.session;
    }
    can::Frame frame;
    // A frame identical to the one sent a wrap earlier with the same low byte would be rejected as a replay: take
    // the next number (within the driver's window; two skips in a row are 1 in 65 536 commands).
    for (int skip = 0;; ++skip) {
      if (can::EncodeCommand(node_, wire, frame) != can::EncodeStatus::kOk) {
        ++counters_.send_failures;
        return LinkResult::kOutOfRange;
      }
      if (skip == static_cast<int>(kCommandWindow / 2) || !sent_frames_.Contains(frame)) break;
      ++wire.seq;
    }
    const CanIo io = tx_.Write(frame);
    switch (io) {
      case CanIo::kOk:
        session_.Sent(wire.seq);
        sent_frames_.Add(frame);
        ++counters_.commands_sent;
        Note(bus_.OnTraffic(), now_us);
        return LinkResult::kOk;
      case CanIo::kWouldBlock:
        ++counters_.send_failures;
        return LinkResult::kBufferFull;
      case CanIo::kNetDown:
        ++counters_.send_failures;
        Note(bus_.OnNetDown(), now_us);
        return LinkResult::kBusOff;
      case CanIo::kError:
        break;
    }
    ++counters_.send_failures;
    ++counters_.io_errors;
    return LinkResult::kError;
  }

  void Poll(std::int64_t now_us) override {
    ReceivedFrame in;
    for (int i = 0; i < kMaxFramesPerPoll; ++i) {
      const CanIo io = rx_.Read(in);
      if (io == CanIo::kWouldBlock) break;
      if (io == CanIo::kNetDown) {
        Note(bus_.OnNetDown(), now_us);
        break;
      }
      if (io == CanIo::kError) {
        ++counters_.io_errors;
        break;
      }
      ++counters_.frames_read;
      Handle(in, now_us);
    }
    if (rx_.dropped() != dropped_seen_) {
      counters_.rx_overflow_drops += static_cast<std::uint32_t>(rx_.dropped() - dropped_seen_);
      dropped_seen_ = rx_.dropped();
      PushLocal(now_us, can::kEmcyCanOverrun, false, fault_t::CODE_CAN_ERROR, true,
                "the kernel dropped received frames (receive queue full): the view of the driver is incomplete");
    }
  }

  NmtState peer_nmt_state() const override { return nmt_; }
  BusState bus_state() const override { return bus_.state(); }
  std::uint32_t last_command_seq() const override { return session_.last(); }
  std::uint32_t session() const override { return session_.session(); }

 private:
  static CanSocketOptions RxOptions(const RobotLinkConfig& config) {
    CheckNode(config.node_id);
    const auto n = static_cast<std::uint32_t>(config.node_id);
    CanSocketOptions options;
    options.interface = config.can_interface;
    options.filters = {Exact(can::kStatusBase + n),  Exact(can::kPositionBase + n),  Exact(can::kForceBase + n),
                       Exact(can::kSessionBase + n), Exact(can::kHeartbeatBase + n), Exact(can::kEmcyBase + n)};
    options.error_mask = DefaultErrorMask();
    return options;
  }

  void Handle(const ReceivedFrame& in, std::int64_t now_us) {
    const can::Frame& frame = in.frame;
    const can::FrameKind kind = can::Classify(frame, node_);
    if (kind == can::FrameKind::kError) {
      ++counters_.error_frames;
      can::ErrorFrameInfo info;
      can::DecodeErrorFrame(frame, info);
      Note(bus_.OnErrorFrame(info), now_us);
      if (info.rx_overflow) {
        PushLocal(now_us, can::kEmcyCanOverrun, false, fault_t::CODE_CAN_ERROR, true,
                  "the CAN controller's receive buffer overflowed: frames were lost");
      }
      return;
    }
    Note(bus_.OnTraffic(), now_us);
    can::DecodeStatus result = can::DecodeStatus::kWrongId;
    switch (kind) {
      case can::FrameKind::kStatus:
        result = OnStatusFrame(frame, in.utime, now_us);
        break;
      case can::FrameKind::kPosition: {
        // Only as the second frame of the triple being assembled; a lone one (e.g. replayed) is dropped.
        result = can::DecodeStatus::kOk;
        if (have_ == 1) {
          can::StatusFrames p;
          result = can::DecodePositionFrame(node_, frame, session_.session(), partial_.seq, p);
          have_ = 0;
          if (result == can::DecodeStatus::kOk) {
            partial_.position[0] = p.position[0];
            partial_.position[1] = p.position[1];
            have_ = 3;
          }
        }
        break;
      }
      case can::FrameKind::kForce: {
        result = can::DecodeStatus::kOk;
        if (have_ == 3) {
          can::StatusFrames f;
          result = can::DecodeForceFrame(node_, frame, session_.session(), partial_.seq, f);
          if (result == can::DecodeStatus::kOk) {
            partial_.contact_force[0] = f.contact_force[0];
            partial_.contact_force[1] = f.contact_force[1];
            partial_.fault_bits = f.fault_bits;
            Complete(now_us);
          }
        }
        have_ = 0;
        break;
      }
      case can::FrameKind::kSession: {
        can::SessionFrame announced;
        result = can::DecodeSession(node_, frame, announced);
        if (result == can::DecodeStatus::kOk) OnSession(announced, now_us);
        break;
      }
      case can::FrameKind::kHeartbeat:
        result = can::DecodeHeartbeat(node_, frame, nmt_);
        if (result == can::DecodeStatus::kOk) {
          ++counters_.heartbeats_received;
          if (session_.OnHeartbeat(nmt_ == NmtState::kBootUp)) {
            ++counters_.boot_ups;
            status_synced_ = false;
            have_ = 0;
            PushLocal(now_us, 0, false, fault_t::CODE_PEER_TIMEOUT, true,
                      "the driver restarted (boot-up heartbeat): its session and this controller's commands are void");
          }
        }
        break;
      case can::FrameKind::kEmcy: {
        can::EmcyFrame emcy;
        result = can::DecodeEmcy(node_, frame, emcy);
        if (result == can::DecodeStatus::kOk) {
          ++counters_.faults_received;
          LinkFault fault;
          fault.receive_us = now_us;
          fault.emcy_code = emcy.error_code;
          fault.code = emcy.code;
          fault.fault_bits = emcy.fault_bits;
          fault.robot_stopped = emcy.robot_stopped;
          fault.cleared = emcy.cleared || emcy.error_code == can::kEmcyNoError;
          fault.what = DriverFaultWhat(emcy.error_code);
          fault.foreign = !session_.owned() && emcy.error_code != can::kEmcyResetRefused;
          QueueFault(fault);
        }
        break;
      }
      default:
        return;  // the kernel filters should not let anything else through
    }
    if (result != can::DecodeStatus::kOk) ++counters_.bad_frames;
  }

  // A status frame (TPDO1) starts a triple: its counter is reconstructed from the low 8 bits (ahead of the last
  // accepted status, or from the announced epoch before the first) and checked by the CRC with the session.
  can::DecodeStatus OnStatusFrame(const can::Frame& frame, std::int64_t utime, std::int64_t now_us) {
    have_ = 0;
    if (!session_.have()) {
      ++counters_.unverified_frames;  // no session known yet: nothing to check it against
      return can::DecodeStatus::kOk;
    }
    const std::uint32_t session = session_.session();
    const std::uint8_t low = frame.data[0];
    std::uint32_t candidates[2];
    if (status_synced_) {
      candidates[0] = can::CounterAhead(status_last_, low);  // status_last_ + 1..256
      candidates[1] = candidates[0] - 256;                   // status_last_ - 0..255
    } else {
      candidates[0] = (status_epoch_ << 8) | low;
      candidates[1] = ((status_epoch_ + 1) << 8) | low;  // a wrap since the announcement
    }
    for (int i = 0; i < 2; ++i) {
      can::StatusFrames s;
      const can::DecodeStatus r = can::DecodeStatusFrame(node_, frame, session, candidates[i], s);
      if (r == can::DecodeStatus::kBadChecksum) continue;
      if (r != can::DecodeStatus::kOk) return r;
      const bool ahead = !status_synced_ || (i == 0 && candidates[0] - status_last_ <= kStatusWindow);
      if (!ahead) {
        // A status of this session that is not newer than the last one: a replay or a duplicate. It must not refresh
        // the view of the driver; the controller stops (once per episode).
        ++counters_.stale_statuses;
        if (!stale_reported_) {
          stale_reported_ = true;
          PushLocal(now_us, can::kEmcyProtocol, false, fault_t::CODE_BAD_MESSAGE, true,
                    "a status of the driver's session out of sequence (a replay, or the driver restarted its "
                    "numbering)");
        }
        return can::DecodeStatus::kOk;
      }
      partial_ = s;
      partial_utime_ = utime;
      have_ = 1;
      return can::DecodeStatus::kOk;
    }
    return can::DecodeStatus::kBadChecksum;  // another session's, or corrupted
  }

  void OnSession(const can::SessionFrame& announced, std::int64_t now_us) {
    switch (session_.OnAnnounce(announced.session)) {
      case SessionView::Change::kNone:
        if (!status_synced_) status_epoch_ = announced.status_epoch;
        return;
      case SessionView::Change::kFirst:
        break;
      case SessionView::Change::kAdopted:
        ++counters_.session_changes;
        break;
      case SessionView::Change::kLost:
        ++counters_.session_changes;
        PushLocal(now_us, 0, false, fault_t::CODE_PEER_TIMEOUT, true,
                  "the driver started a new session (it stopped, restarted or was reset): this controller's commands "
                  "are void");
        break;
    }
    status_epoch_ = announced.status_epoch;
    status_synced_ = false;
    stale_reported_ = false;
    have_ = 0;
  }

  void Complete(std::int64_t now_us) {
    if (status_synced_) {
      counters_.status_gaps += partial_.seq - status_last_ - 1;
    }
    status_synced_ = true;
    status_last_ = partial_.seq;
    stale_reported_ = false;
    last_status_us_ = now_us;
    have_ = 0;
    status_.utime = partial_utime_;
    status_.receive_us = now_us;
    status_.session = partial_.session;
    status_.seq = partial_.seq;
    // The frame carries the low 8 bits of the driver's last accepted command: the newest of this link's numbers with
    // those bits (0: none accepted in this session).
    const std::uint32_t last = session_.last();
    status_.command_seq = last - static_cast<std::uint8_t>(static_cast<std::uint8_t>(last) - partial_.command_seq);
    ++counters_.statuses_received;
    if (session_.OnStatus(status_.command_seq)) QueueFault(ForeignSessionFault(now_us, fault_t::CODE_BAD_MESSAGE));
    // Another controller's session: the driver is alive (peer_state), but its state is not this controller's to
    // start from; it waits for the fresh session the driver issues when that one ends.
    if (session_.foreign()) return;
    for (int i = 0; i < 2; ++i) {
      status_.position[i] = partial_.position[i];
      status_.velocity[i] = partial_.velocity[i];
      status_.contact_force[i] = partial_.contact_force[i];
    }
    status_.contact = partial_.contact;
    status_.state = partial_.state;
    status_.fault_bits = partial_.fault_bits;
    fresh_status_ = true;
  }

  void Note(BusTracker::Change change, std::int64_t now_us) {
    switch (change) {
      case BusTracker::Change::kNone:
        return;
      case BusTracker::Change::kOff:
        // Each bus state by its own code; only bus-off (or the interface down) stops the controller.
        ++counters_.bus_off_events;
        PushLocal(now_us, can::kEmcyBusOff, false, fault_t::CODE_CAN_ERROR, true,
                  "CAN bus-off or the interface is down: nothing reaches the driver");
        return;
      case BusTracker::Change::kPassive:
        PushLocal(now_us, can::kEmcyCanPassive, false);
        return;
      case BusTracker::Change::kWarning:
        PushLocal(now_us, can::kEmcyCanWarning, false);
        return;
      case BusTracker::Change::kRestarted:
        PushLocal(now_us, can::kEmcyBusOffRecovered, true);
        return;
      case BusTracker::Change::kActive:
        PushLocal(now_us, can::kEmcyNoError, true);
        return;
    }
  }

  void PushLocal(std::int64_t now_us, std::uint16_t emcy_code, bool cleared,
                 std::int32_t code = fault_t::CODE_CAN_ERROR, bool stopped = false, const char* what = nullptr) {
    LinkFault fault;
    fault.receive_us = now_us;
    fault.emcy_code = emcy_code;
    fault.code = code;
    fault.fault_bits = code == fault_t::CODE_CAN_ERROR ? fault_bits::kBus : 0;
    fault.cleared = cleared;
    fault.robot_stopped = stopped;
    fault.local = true;
    fault.what = what;
    QueueFault(fault);
  }

  const int node_;
  std::unique_ptr<CanPort> rx_holder_;
  std::unique_ptr<CanPort> tx_holder_;
  CanPort& rx_;
  CanPort& tx_;
  BusTracker bus_;
  SessionView session_;
  can::FrameHistory sent_frames_;  // of sent_session_
  std::uint32_t sent_session_ = 0;
  std::uint32_t dropped_seen_ = 0;
  can::StatusFrames partial_;
  std::int64_t partial_utime_ = 0;
  int have_ = 0;                    // 1: status frame, 3: and position frame of the triple being assembled
  bool status_synced_ = false;      // status_last_ is known (an accepted status in this session)
  std::uint32_t status_last_ = 0;   // counter of the last accepted status
  std::uint32_t status_epoch_ = 0;  // from the session frame, until the first accepted status
  bool stale_reported_ = false;
  NmtState nmt_ = NmtState::kBootUp;
};

// ---------------------------------------------------------------------------------------------------------------
class SocketCanDriverTransport final : public DriverTransport {
 public:
  explicit SocketCanDriverTransport(const DriverTransportConfig& config)
      : node_(config.node_id), rx_(RxOptions(config)), tx_(CanSocketOptions{config.can_interface, false, {}, 0, 0}) {}

  void Wait(std::int64_t timeout_us) override { rx_.WaitReadable(timeout_us); }

  bool NextEvent(std::int64_t now_us, DriverEvent& out) override {
    if (pending_.Pop(out)) return true;
    if (rx_.dropped() != dropped_seen_) {
      out = DriverEvent{};
      out.kind = DriverEventKind::kFramesDropped;
      out.receive_us = now_us;
      out.count = rx_.dropped() - dropped_seen_;
      counters_.rx_overflow_drops += out.count;
      dropped_seen_ = rx_.dropped();
      return true;
    }
    ReceivedFrame in;
    for (int i = 0; i < kMaxFramesPerPoll; ++i) {
      const CanIo io = rx_.Read(in);
      if (io == CanIo::kWouldBlock) return false;
      if (io == CanIo::kNetDown) return BusEvent(bus_.OnNetDown(), now_us, out);
      if (io == CanIo::kError) {
        ++counters_.io_errors;
        return false;
      }
      if (Handle(in.frame, ArrivalMicros(in, now_us), out)) return true;
    }
    return false;
  }

  LinkResult SendStatus(const RobotStatus& status) override {
    can::StatusFrames wire;
    wire.seq = status.seq;
    wire.session = status.session;
    wire.command_seq = static_cast<std::uint8_t>(status.command_seq);
    for (int i = 0; i < 2; ++i) {
      wire.velocity[i] = status.velocity[i];
      wire.position[i] = status.position[i];
      wire.contact_force[i] = status.contact_force[i];
    }
    wire.state = status.state;
    wire.contact = status.contact;
    wire.fault_bits = status.fault_bits;
    can::Frame frames[3];
    can::EncodeStatusFrames(node_, wire, frames);
    for (const can::Frame& f : frames) {
      const LinkResult r = Write(f);
      if (r != LinkResult::kOk) return r;
    }
    ++counters_.statuses_received;  // here: statuses sent
    return LinkResult::kOk;
  }

  LinkResult SendHeartbeat(NmtState state) override {
    can::Frame frame;
    can::EncodeHeartbeat(node_, state, frame);
    return Write(frame);
  }

  LinkResult SendFault(const DriverFault& fault) override {
    can::EmcyFrame emcy;
    emcy.error_code = fault.emcy_code;  // 0x0000 for a reset; 0x8140 "recovered from bus-off" keeps its code
    // CiA 301 error register: bit 0 generic error, bit 4 communication error.
    const bool comm = fault.code == fault_t::CODE_CAN_ERROR || fault.code == fault_t::CODE_BAD_MESSAGE ||
                      fault.code == fault_t::CODE_PEER_TIMEOUT;
    emcy.error_register = fault.cleared ? 0 : static_cast<std::uint8_t>(0x01 | (comm ? 0x10 : 0));
    emcy.code = static_cast<std::uint8_t>(fault.code);
    emcy.fault_bits = fault.fault_bits;
    emcy.robot_stopped = fault.robot_stopped;
    emcy.cleared = fault.cleared;
    emcy.counter = emcy_counter_++;
    can::Frame frame;
    can::EncodeEmcy(node_, emcy, frame);
    return Write(frame);
  }

  LinkResult SendSession(std::uint32_t session, std::uint32_t status_seq) override {
    can::SessionFrame announce;
    announce.session = session;
    announce.status_epoch = status_seq >> 8;
    can::Frame frame;
    if (can::EncodeSession(node_, announce, frame) != can::EncodeStatus::kOk) return LinkResult::kOutOfRange;
    return Write(frame);
  }

  std::uint32_t sequence_modulus() const override { return 256; }
  LinkCounters counters() const override { return counters_; }

 private:
  static CanSocketOptions RxOptions(const DriverTransportConfig& config) {
    CheckNode(config.node_id);
    CanSocketOptions options;
    options.interface = config.can_interface;
    options.filters = {Exact(can::kCommandBase + static_cast<std::uint32_t>(config.node_id)), Exact(can::kNmtId)};
    options.error_mask = DefaultErrorMask();
    return options;
  }

  LinkResult Write(const can::Frame& frame) {
    switch (tx_.Write(frame)) {
      case CanIo::kOk: {
        DriverEvent event;
        if (BusEvent(bus_.OnTraffic(), 0, event)) pending_.Push(event);
        return LinkResult::kOk;
      }
      case CanIo::kWouldBlock:
        return LinkResult::kBufferFull;
      case CanIo::kNetDown: {
        DriverEvent event;
        if (BusEvent(bus_.OnNetDown(), 0, event)) pending_.Push(event);
        return LinkResult::kBusOff;
      }
      case CanIo::kError:
        break;
    }
    ++counters_.io_errors;
    return LinkResult::kError;
  }

  bool BusEvent(BusTracker::Change change, std::int64_t now_us, DriverEvent& out) {
    out = DriverEvent{};
    out.receive_us = now_us;
    switch (change) {
      case BusTracker::Change::kNone:
        return false;
      case BusTracker::Change::kOff:
        ++counters_.bus_off_events;
        out.kind = DriverEventKind::kBusOff;
        return true;
      case BusTracker::Change::kRestarted:
        out.kind = DriverEventKind::kBusRestarted;
        return true;
      case BusTracker::Change::kPassive:
        out.kind = DriverEventKind::kBusPassive;
        return true;
      case BusTracker::Change::kWarning:
        out.kind = DriverEventKind::kBusWarning;
        return true;
      case BusTracker::Change::kActive:
        out.kind = DriverEventKind::kBusActive;
        return true;
    }
    return false;
  }

  // When a frame arrived, on the monotonic clock (its kernel timestamp moved by the wall-to-monotonic offset), but
  // never before `now_us`: a frame that waited in the queue counts from when the driver looked, as the caller's
  // clock says; one that arrived while this thread was preempted after reading `now_us` (a starved CPU) counts from
  // its arrival, or the command watchdog would measure from before the command came and fire early.
  static std::int64_t ArrivalMicros(const ReceivedFrame& in, std::int64_t now_us) {
    if (in.utime <= 0) return now_us;
    const std::int64_t age = std::max<std::int64_t>(WallMicros() - in.utime, 0);
    return std::max(now_us, MonotonicMicros() - age);
  }

  // Turns one received frame into an event; false if it carries none.
  bool Handle(const can::Frame& frame, std::int64_t now_us, DriverEvent& out) {
    switch (can::Classify(frame, node_)) {
      case can::FrameKind::kError: {
        ++counters_.error_frames;
        can::ErrorFrameInfo info;
        can::DecodeErrorFrame(frame, info);
        return BusEvent(bus_.OnErrorFrame(info), now_us, out);
      }
      case can::FrameKind::kCommand: {
        DriverEvent traffic;
        if (BusEvent(bus_.OnTraffic(), now_us, traffic)) pending_.Push(traffic);
        out = CommandFrameEvent(node_, frame, now_us);
        if (out.kind == DriverEventKind::kBadCommand) {
          ++counters_.bad_frames;
        } else {
          ++counters_.commands_sent;  // here: commands received
        }
        return true;
      }
      case can::FrameKind::kNmt: {
        std::uint8_t command = 0;
        if (can::DecodeNmt(node_, frame, command) != can::DecodeStatus::kOk) return false;
        out = DriverEvent{};
        out.receive_us = now_us;
        if (command == can::kNmtStop) {
          out.kind = DriverEventKind::kEStop;
          return true;
        }
        if (command == can::kNmtStart) {
          out.kind = DriverEventKind::kNmtStart;
          return true;
        }
        if (command == can::kNmtResetNode || command == can::kNmtResetCommunication) {
          out.kind = DriverEventKind::kResetRequest;
          return true;
        }
        return false;
      }
      default:
        return false;
    }
  }

  const int node_;
  CanSocket rx_;
  CanSocket tx_;
  BusTracker bus_;
  std::uint32_t dropped_seen_ = 0;
  std::uint8_t emcy_counter_ = 0;
  FixedQueue<DriverEvent, 16> pending_;
  LinkCounters counters_;
};

}  // namespace

std::unique_ptr<RobotLink> MakeSocketCanRobotLink(const RobotLinkConfig& config) {
  return std::make_unique<SocketCanRobotLink>(config);
}

std::unique_ptr<RobotLink> MakeCanRobotLink(const RobotLinkConfig& config, std::unique_ptr<CanPort> receive,
                                            std::unique_ptr<CanPort> send) {
  if (!receive || !send) throw std::invalid_argument("MakeCanRobotLink: both ports are required");
  return std::make_unique<SocketCanRobotLink>(config, std::move(receive), std::move(send));
}

std::unique_ptr<DriverTransport> MakeSocketCanDriverTransport(const DriverTransportConfig& config) {
  return std::make_unique<SocketCanDriverTransport>(config);
}

can::CommandVerdict JudgeSequence(std::uint32_t claimed, std::uint32_t seq, std::uint32_t session, std::uint32_t last,
                                  std::uint32_t window, std::uint32_t modulus) {
  if (claimed != session) return can::CommandVerdict::kWrongSession;
  const std::uint64_t ahead = (static_cast<std::uint64_t>(seq) + modulus - (last % modulus)) % modulus;
  if (ahead >= 1 && ahead <= window) return can::CommandVerdict::kAccept;
  if (ahead == 0 || ahead >= modulus / 2) return can::CommandVerdict::kStale;
  return can::CommandVerdict::kAhead;
}

const char* ToString(DriverEventKind kind) {
  switch (kind) {
    case DriverEventKind::kCommand:
      return "command";
    case DriverEventKind::kBadCommand:
      return "bad command";
    case DriverEventKind::kEStop:
      return "NMT stop (e-stop)";
    case DriverEventKind::kResetRequest:
      return "NMT reset node";
    case DriverEventKind::kNmtStart:
      return "NMT start";
    case DriverEventKind::kBusOff:
      return "bus-off";
    case DriverEventKind::kBusRestarted:
      return "bus restarted";
    case DriverEventKind::kBusPassive:
      return "bus error passive";
    case DriverEventKind::kBusWarning:
      return "bus error warning";
    case DriverEventKind::kBusActive:
      return "bus error active";
    case DriverEventKind::kFramesDropped:
      return "frames dropped";
  }
  return "?";
}

}  // namespace visco::drivers

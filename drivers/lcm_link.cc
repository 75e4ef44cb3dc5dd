// LCM implementations of RobotLink (controller side) and DriverTransport (driver side). LCM's C++ API allocates
// when it encodes and decodes, so an I/O thread owns the lcm::LCM object; the real-time side hands values over
// through lock-free queues and wakes the thread with an eventfd write.

#include <poll.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <atomic>
#include <cstring>
#include <functional>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "common/error.h"
#include "drivers/driver_transport.h"
#include "drivers/queued_robot_link.h"
#include "drivers/ring.h"
#include "drivers/robot_link.h"
#include "lcmtypes/channels.h"
#include "visco/fault_t.hpp"
#include "visco/heartbeat_t.hpp"
#include "visco/robot_status_t.hpp"
#include "visco/velocity_command_t.hpp"

namespace visco::drivers {
namespace {

constexpr std::uint32_t kLcmSeqModulus = 0x80000000U;
// A status is newer than the last one when its number is 1..half the modulus ahead (serial number arithmetic): the
// number is explicit here, so any run of lost statuses is a gap. (The CAN link's window of kStatusWindow comes from
// reconstructing an 8-bit counter; over LCM it took every status after 128 lost ones for a replay.)
constexpr std::uint32_t kLcmStatusWindow = kLcmSeqModulus / 2;
// UDP does not keep order: on a multi-core host a publisher whose thread moves between CPUs hands consecutive
// datagrams to different CPUs' loopback queues, and one can overtake another (seen in the VM: status 2577 arrived
// 28 ms late, after 2578 and 2579). A status this few behind the last accepted one, or a copy of it, is the network's
// reordering: dropped and counted, not a stop. Further behind is a replay or a restarted numbering.
constexpr std::uint32_t kLcmReorderWindow = 64;

// Owns an lcm::LCM, an eventfd and the thread that serves both. In a lockstep simulation (LockstepBus) it uses the
// caller's instance instead, starts no thread, and Wake() flushes at once on the caller's thread; message times come
// from the simulated clock.
class LcmIo {
 public:
  LcmIo(const std::string& url, const LockstepBus& lockstep) : clock_(lockstep.utime_now) {
    if (lockstep.bus != nullptr) {
      lcm_ = lockstep.bus;
      return;
    }
    owned_ = std::make_unique<lcm::LCM>(url);
    lcm_ = owned_.get();
    if (!lcm_->good()) throw JobFailed("LCM: cannot initialise provider '" + (url.empty() ? "default" : url) + "'");
    wake_ = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (wake_ < 0) throw JobFailed("LCM: eventfd failed");
  }
  ~LcmIo() {
    Stop();
    for (lcm::Subscription* sub : subscriptions_) lcm_->unsubscribe(sub);  // a shared bus outlives this link
  }
  // Keeps a subscription on a shared bus, to be removed with the link (an own instance goes with its subscriptions).
  lcm::Subscription* Track(lcm::Subscription* sub) {
    if (!owned_) subscriptions_.push_back(sub);
    return sub;
  }

  void Start(std::function<void()> on_wake) {
    on_wake_ = std::move(on_wake);
    if (owned_) thread_ = std::thread([this] { Run(); });
  }
  void Stop() {
    if (thread_.joinable()) {
      stop_.store(true);
      Wake();
      thread_.join();
    }
    if (wake_ >= 0) {
      close(wake_);
      wake_ = -1;
    }
  }
  // Real-time safe: one non-blocking write(2). (Lockstep: the flush itself, on the caller's thread.)
  void Wake() {
    if (!owned_) {
      if (on_wake_) on_wake_();
      return;
    }
    const std::uint64_t one = 1;
    [[maybe_unused]] const ssize_t n = write(wake_, &one, sizeof(one));
  }
  lcm::LCM& lcm() { return *lcm_; }
  // Message time: the wall clock, or the lockstep simulation's clock. Real-time safe with the wall clock.
  std::int64_t Now() const { return clock_ ? clock_() : WallMicros(); }

 private:
  void Run() {
    pollfd fds[2] = {{lcm_->getFileno(), POLLIN, 0}, {wake_, POLLIN, 0}};
    while (!stop_.load()) {
      on_wake_();  // flush outgoing first, then wait
      if (poll(fds, 2, 20) <= 0) continue;
      if (fds[1].revents & POLLIN) {
        std::uint64_t count = 0;
        [[maybe_unused]] const ssize_t n = read(wake_, &count, sizeof(count));
      }
      if (fds[0].revents & POLLIN) lcm_->handleTimeout(0);
    }
    on_wake_();
  }
  std::unique_ptr<lcm::LCM> owned_;
  lcm::LCM* lcm_ = nullptr;
  std::function<std::int64_t()> clock_;
  std::vector<lcm::Subscription*> subscriptions_;  // on a shared bus
  int wake_ = -1;
  std::atomic<bool> stop_{false};
  std::thread thread_;
  std::function<void()> on_wake_;
};

// Undelivered messages LCM keeps per subscription of the 500 Hz channels (its default is 30).
constexpr int kLcmQueueCapacity = 512;

// ---------------------------------------------------------------------------------------------------------------
class LcmRobotLink final : public QueuedRobotLink {
 public:
  explicit LcmRobotLink(const RobotLinkConfig& config)
      : QueuedRobotLink(config.heartbeat_timeout_us), node_(config.node_id), io_(config.lcm_url, config.lockstep) {
    // LCM keeps 30 undelivered messages per subscription and drops the rest: at 500 Hz a thread held off for 60 ms
    // (a loaded machine, an image-rendering neighbour) lost a run of statuses or commands, which the session rules
    // then treat as a fault. Room for one watchdog period of them.
    io_.Track(io_.lcm().subscribe(channels::kStatus, &LcmRobotLink::OnStatus, this))
        ->setQueueCapacity(kLcmQueueCapacity);
    io_.Track(io_.lcm().subscribe(channels::kHeartbeatDriver, &LcmRobotLink::OnHeartbeat, this));
    io_.Track(io_.lcm().subscribe(channels::kFault, &LcmRobotLink::OnFault, this));
    io_.Start([this] { Flush(); });
  }
  ~LcmRobotLink() override { io_.Stop(); }

  LinkResult SendCommand(const VelocityCommand& command, std::int64_t /*now_us*/) override {
    for (double v : command.velocity) {
      if (!(v > -1e6 && v < 1e6)) {
        ++counters_.send_failures;
        return LinkResult::kOutOfRange;
      }
    }
    // Without a session only an e-stop goes out (the driver honours it whatever the session).
    if (!session_.usable() && !command.estop && !command.quick_stop) return LinkResult::kNoSession;
    Outgoing out;
    out.command = command;
    out.session = session_.session();
    out.seq = session_.Next() % kLcmSeqModulus;
    out.utime = io_.Now();
    if (!outgoing_.Push(out)) {
      ++counters_.send_failures;
      return LinkResult::kBufferFull;
    }
    session_.Sent(out.seq);
    ++counters_.commands_sent;
    io_.Wake();
    return LinkResult::kOk;
  }

  void Poll(std::int64_t now_us) override {
    Incoming in;
    while (incoming_.Pop(in)) {
      if (in.heartbeat) {
        ++counters_.heartbeats_received;
        nmt_state_ = in.nmt;
        if (session_.OnHeartbeat(in.nmt == NmtState::kBootUp)) {
          ++counters_.boot_ups;
          status_synced_ = false;
          PushLocal(now_us, fault_t::CODE_PEER_TIMEOUT,
                    "the driver restarted (boot-up heartbeat): its session and this controller's commands are void");
        } else if (in.nmt != NmtState::kBootUp) {
          Announce(in.status.session);
        }
        continue;
      }
      // Statuses never announce a session (only heartbeats do): a replayed status of an old session is ignored.
      RobotStatus& s = in.status;
      if (!session_.have() || s.session != session_.session()) continue;
      if (status_synced_) {
        const std::uint32_t ahead = (s.seq - status_last_) % kLcmSeqModulus;
        if (ahead == 0 || ahead >= kLcmStatusWindow) {
          // A status of this session that is not newer than the last one never refreshes the view of the driver.
          if (kLcmSeqModulus - ahead <= kLcmReorderWindow || ahead == 0) {
            ++counters_.reordered_statuses;
            continue;
          }
          // Far behind: a replay, or a numbering that restarted. The controller stops (once per episode).
          ++counters_.stale_statuses;
          if (!stale_reported_) {
            stale_reported_ = true;
            PushLocal(now_us, fault_t::CODE_BAD_MESSAGE,
                      "a status of the driver's session out of sequence (a replay, or the driver restarted its "
                      "numbering)");
          }
          continue;
        }
        counters_.status_gaps += ahead - 1;
      }
      status_synced_ = true;
      stale_reported_ = false;
      status_last_ = s.seq;
      last_status_us_ = now_us;
      s.receive_us = now_us;
      ++counters_.statuses_received;
      if (session_.OnStatus(s.command_seq)) QueueFault(ForeignSessionFault(now_us, fault_t::CODE_BAD_MESSAGE));
      // Another controller's session: the driver is alive (peer_state), but its state is not this controller's to
      // start from; it waits for the fresh session the driver issues when that one ends.
      if (session_.foreign()) continue;
      status_ = s;
      fresh_status_ = true;
    }
    // The driver sends the fault it stopped for before it announces the session the stop begins (on another
    // channel, handed over on another queue): a fault that arrives with the announcement is this controller's
    // session's, and it goes first, so that the controller stops with the driver's reason.
    LinkFault f;
    while (incoming_faults_.Pop(f)) {
      f.receive_us = now_us;
      f.foreign = !session_.owned() && !session_lost_ && f.emcy_code != 0xFF01;  // 0xFF01: can::kEmcyResetRefused
      ++counters_.faults_received;
      QueueFault(f);
    }
    if (session_lost_) {
      session_lost_ = false;
      PushLocal(now_us, fault_t::CODE_PEER_TIMEOUT,
                "the driver started a new session (it stopped, restarted or was reset): this controller's commands "
                "are void");
    }
    counters_.bad_frames = bad_messages_.load(std::memory_order_relaxed);
  }

  NmtState peer_nmt_state() const override { return nmt_state_; }
  BusState bus_state() const override { return BusState::kActive; }
  std::uint32_t last_command_seq() const override { return session_.last(); }
  std::uint32_t session() const override { return session_.session(); }

 private:
  struct Outgoing {
    VelocityCommand command;
    std::uint32_t session = 0;
    std::uint32_t seq = 0;
    std::int64_t utime = 0;
  };
  // What the I/O thread hands over, in arrival order: a status, or a heartbeat (its session in status.session).
  struct Incoming {
    bool heartbeat = false;
    NmtState nmt = NmtState::kBootUp;
    RobotStatus status;
  };

  // Real-time side: an announced session (a heartbeat's or a status's).
  void Announce(std::uint32_t nonce) {
    switch (session_.OnAnnounce(nonce)) {
      case SessionView::Change::kNone:
        return;
      case SessionView::Change::kFirst:
        break;
      case SessionView::Change::kAdopted:
        ++counters_.session_changes;
        break;
      case SessionView::Change::kLost:
        ++counters_.session_changes;
        session_lost_ = true;  // reported at the end of Poll, after the driver's own reason
        break;
    }
    status_synced_ = false;
    stale_reported_ = false;
  }
  void PushLocal(std::int64_t now_us, std::int32_t code, const char* what) {
    LinkFault fault;
    fault.receive_us = now_us;
    fault.code = code;
    fault.robot_stopped = true;
    fault.local = true;
    fault.what = what;
    QueueFault(fault);
  }

  // I/O thread.
  void Flush() {
    Outgoing out;
    while (outgoing_.Pop(out)) {
      velocity_command_t msg{};
      msg.utime = out.utime;
      msg.node_id = node_;
      msg.session = static_cast<std::int32_t>(out.session);
      msg.seq = static_cast<std::int32_t>(out.seq);
      msg.velocity[0] = out.command.velocity[0];
      msg.velocity[1] = out.command.velocity[1];
      msg.estop = out.command.estop;
      msg.reset = out.command.reset;
      msg.quick_stop = out.command.quick_stop;
      io_.lcm().publish(channels::kCommand, &msg);
    }
  }
  void OnStatus(const lcm::ReceiveBuffer*, const std::string&, const robot_status_t* msg) {
    if (msg->node_id != node_) return;
    if (msg->state < 0 || msg->state > static_cast<int>(RobotState::kEStop)) {
      bad_messages_.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    Incoming in;
    RobotStatus& s = in.status;
    s.utime = msg->utime;
    s.session = static_cast<std::uint32_t>(msg->session);
    s.seq = static_cast<std::uint32_t>(msg->seq);
    s.command_seq = static_cast<std::uint32_t>(msg->command_seq);
    for (int i = 0; i < 2; ++i) {
      s.position[i] = msg->position[i];
      s.velocity[i] = msg->velocity[i];
      s.contact_force[i] = msg->contact_force[i];
    }
    s.contact = msg->contact;
    s.state = static_cast<RobotState>(msg->state);
    s.fault_bits = static_cast<std::uint16_t>(msg->fault_bits & fault_bits::kAll);
    incoming_.Push(in);
  }
  void OnHeartbeat(const lcm::ReceiveBuffer*, const std::string&, const heartbeat_t* msg) {
    if (msg->node_id != node_) return;
    Incoming in;
    in.heartbeat = true;
    in.nmt = static_cast<NmtState>(static_cast<std::uint8_t>(msg->state));
    in.status.session = static_cast<std::uint32_t>(msg->session);
    incoming_.Push(in);
  }
  void OnFault(const lcm::ReceiveBuffer*, const std::string&, const fault_t* msg) {
    if (msg->source != "driver") return;
    LinkFault f;
    f.code = msg->code;
    f.emcy_code = static_cast<std::uint16_t>(msg->emcy_code);
    f.fault_bits = static_cast<std::uint16_t>(msg->fault_bits & fault_bits::kAll);
    f.robot_stopped = msg->robot_stopped;
    f.cleared = msg->cleared;
    f.what = DriverFaultWhat(f.emcy_code);
    incoming_faults_.Push(f);
  }

  const int node_;
  SpscQueue<Outgoing, 256> outgoing_;
  SpscQueue<Incoming, 128> incoming_;
  SpscQueue<LinkFault, 64> incoming_faults_;
  std::atomic<std::uint64_t> bad_messages_{0};
  // Real-time side only.
  SessionView session_;
  NmtState nmt_state_ = NmtState::kBootUp;
  bool status_synced_ = false;
  bool stale_reported_ = false;
  bool session_lost_ = false;  // this Poll saw the announcement of a session that replaced this controller's
  std::uint32_t status_last_ = 0;
  LcmIo io_;  // last: its thread stops before the queues go away
};

// ---------------------------------------------------------------------------------------------------------------
class LcmDriverTransport final : public DriverTransport {
 public:
  explicit LcmDriverTransport(const DriverTransportConfig& config)
      : node_(config.node_id), io_(config.lcm_url, config.lockstep) {
    rx_ready_ = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (rx_ready_ < 0) throw JobFailed("LCM: eventfd failed");
    io_.Track(io_.lcm().subscribe(channels::kCommand, &LcmDriverTransport::OnCommand, this))
        ->setQueueCapacity(kLcmQueueCapacity);
    io_.Start([this] { Flush(); });
  }
  ~LcmDriverTransport() override {
    io_.Stop();
    close(rx_ready_);
  }

  void Wait(std::int64_t timeout_us) override {
    pollfd p{rx_ready_, POLLIN, 0};
    timespec ts{static_cast<time_t>(timeout_us / 1'000'000), static_cast<long>((timeout_us % 1'000'000) * 1000)};
    if (ppoll(&p, 1, &ts, nullptr) > 0) {
      std::uint64_t count = 0;
      [[maybe_unused]] const ssize_t n = read(rx_ready_, &count, sizeof(count));
    }
  }
  bool NextEvent(std::int64_t now_us, DriverEvent& out) override {
    if (!events_.Pop(out)) return false;
    out.receive_us = now_us;
    if (out.kind == DriverEventKind::kCommand) ++counters_.commands_sent;  // here: commands received
    if (out.kind == DriverEventKind::kBadCommand) ++counters_.bad_frames;
    return true;
  }
  LinkResult SendStatus(const RobotStatus& status) override {
    Out out;
    out.kind = Out::kStatus;
    out.status = status;
    out.utime = io_.Now();
    return Queue(out);
  }
  LinkResult SendHeartbeat(NmtState state) override {
    Out out;
    out.kind = Out::kHeartbeat;
    out.nmt = state;
    out.session = session_;
    last_nmt_ = state;
    out.utime = io_.Now();
    return Queue(out);
  }
  LinkResult SendFault(const DriverFault& fault) override {
    Out out;
    out.kind = Out::kFault;
    out.fault = fault;
    out.utime = io_.Now();
    return Queue(out);
  }
  LinkResult SendSession(std::uint32_t session, std::uint32_t /*status_seq*/) override {
    if (session == session_) return LinkResult::kOk;  // (repeated with every heartbeat, which carries it)
    session_ = session;                               // in every heartbeat from now on (statuses carry their own)
    // A new one is announced at once with a heartbeat of the current NMT state (after the boot-up one:
    // pre-operational).
    return SendHeartbeat(last_nmt_ == NmtState::kBootUp ? NmtState::kPreOperational : last_nmt_);
  }
  std::uint32_t sequence_modulus() const override { return kLcmSeqModulus; }
  LinkCounters counters() const override { return counters_; }

 private:
  struct Out {
    enum Kind : std::uint8_t { kStatus, kHeartbeat, kFault } kind = kStatus;
    RobotStatus status;
    NmtState nmt = NmtState::kBootUp;
    std::uint32_t session = 0;  // heartbeats
    DriverFault fault;
    std::int64_t utime = 0;
  };

  LinkResult Queue(const Out& out) {
    if (!outgoing_.Push(out)) return LinkResult::kBufferFull;
    io_.Wake();
    return LinkResult::kOk;
  }

  void Flush() {
    Out out;
    while (outgoing_.Pop(out)) {
      switch (out.kind) {
        case Out::kStatus: {
          robot_status_t msg{};
          msg.utime = out.utime;
          msg.node_id = node_;
          msg.session = static_cast<std::int32_t>(out.status.session);
          msg.seq = static_cast<std::int32_t>(out.status.seq % kLcmSeqModulus);
          msg.command_seq = static_cast<std::int32_t>(out.status.command_seq);
          for (int i = 0; i < 2; ++i) {
            msg.position[i] = out.status.position[i];
            msg.velocity[i] = out.status.velocity[i];
            msg.contact_force[i] = out.status.contact_force[i];
          }
          msg.contact = out.status.contact;
          msg.state = static_cast<std::int32_t>(out.status.state);
          msg.fault_bits = out.status.fault_bits;
          io_.lcm().publish(channels::kStatus, &msg);
          break;
        }
        case Out::kHeartbeat: {
          heartbeat_t msg{};
          msg.utime = out.utime;
          msg.sender = "driver";
          msg.node_id = node_;
          msg.counter = heartbeat_counter_++;
          msg.state = static_cast<std::int8_t>(out.nmt);
          msg.session = static_cast<std::int32_t>(out.session);
          io_.lcm().publish(channels::kHeartbeatDriver, &msg);
          break;
        }
        case Out::kFault: {
          fault_t msg{};
          msg.utime = out.utime;
          msg.source = "driver";
          msg.code = out.fault.code;
          msg.severity = out.fault.severity;
          msg.robot_stopped = out.fault.robot_stopped;
          msg.cleared = out.fault.cleared;
          msg.message = out.fault.message;
          msg.emcy_code = out.fault.emcy_code;
          msg.fault_bits = out.fault.fault_bits;
          io_.lcm().publish(channels::kFault, &msg);
          break;
        }
      }
    }
  }

  void OnCommand(const lcm::ReceiveBuffer*, const std::string&, const velocity_command_t* msg) {
    if (msg->node_id != node_) return;
    DriverEvent event;
    const bool finite =
        msg->velocity[0] > -1e6 && msg->velocity[0] < 1e6 && msg->velocity[1] > -1e6 && msg->velocity[1] < 1e6;
    if (!finite || msg->seq < 0) {
      event.kind = DriverEventKind::kBadCommand;
      event.decode = can::DecodeStatus::kBadReserved;
    } else {
      event.kind = DriverEventKind::kCommand;
      event.seq = static_cast<std::uint32_t>(msg->seq);
      event.session = static_cast<std::uint32_t>(msg->session);
      event.command.velocity[0] = msg->velocity[0];
      event.command.velocity[1] = msg->velocity[1];
      event.command.estop = msg->estop;
      event.command.reset = msg->reset;
      event.command.quick_stop = msg->quick_stop;
    }
    if (events_.Push(event)) {
      const std::uint64_t one = 1;
      [[maybe_unused]] const ssize_t n = write(rx_ready_, &one, sizeof(one));
    }
  }

  const int node_;
  int rx_ready_ = -1;
  std::uint32_t session_ = 0;              // driver thread only
  NmtState last_nmt_ = NmtState::kBootUp;  // driver thread only
  std::int32_t heartbeat_counter_ = 0;     // I/O thread only
  SpscQueue<DriverEvent, 256> events_;
  SpscQueue<Out, 256> outgoing_;
  LinkCounters counters_;
  LcmIo io_;  // last: its thread stops before the queues go away
};

}  // namespace

std::unique_ptr<RobotLink> MakeLcmRobotLink(const RobotLinkConfig& config) {
  return std::make_unique<LcmRobotLink>(config);
}

std::unique_ptr<DriverTransport> MakeLcmDriverTransport(const DriverTransportConfig& config) {
  return std::make_unique<LcmDriverTransport>(config);
}

}  // namespace visco::drivers

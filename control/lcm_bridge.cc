#include "control/lcm_bridge.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <lcm/lcm-cpp.hpp>
#include <utility>

#include "control/fault_message.h"
#include "lcmtypes/channels.h"
#include "visco/controller_telemetry_t.hpp"
#include "visco/fault_t.hpp"
#include "visco/heartbeat_t.hpp"
#include "visco/robot_estimate_t.hpp"
#include "visco/visual_events_t.hpp"

namespace visco::control {

std::int64_t CaptureToMonotonic(std::int64_t capture_utime, std::int64_t receive_ns, std::int64_t receive_utime) {
  const std::int64_t age_us = std::max<std::int64_t>(0, receive_utime - capture_utime);
  return receive_ns - age_us * 1000;
}

VisualFrame ToVisualFrame(const visual_events_t& m, const Task& task, std::int64_t receive_ns,
                          std::int64_t receive_utime, std::uint64_t* unknown_rays) {
  VisualFrame frame;
  frame.capture_ns = CaptureToMonotonic(m.frame_utime, receive_ns, receive_utime);
  frame.frame_seq = m.frame_seq;
  for (const visual_event_t& e : m.events) {
    const int ray = task.RayIndex(e.cvc_ray);
    if (ray < 0) {
      if (unknown_rays != nullptr) ++*unknown_rays;
      continue;
    }
    if (frame.count >= kMaxVisualObservations) break;
    VisualObservation& obs = frame.items[frame.count++];
    obs.ray = ray;
    obs.state = e.state;
    obs.crossed = e.crossed;
    obs.signed_distance_px = e.signed_distance_px;
    obs.stddev_px = e.distance_stddev_px;
  }
  return frame;
}

PositionEstimate ToPositionEstimate(const robot_estimate_t& m, std::int64_t receive_ns, std::int64_t receive_utime) {
  PositionEstimate e;
  e.capture_ns = CaptureToMonotonic(m.utime, receive_ns, receive_utime);
  e.frame_seq = m.frame_seq;
  e.valid = m.valid;
  e.position = {m.position[0], m.position[1]};
  e.stddev = m.position_stddev;
  return e;
}

class ControllerBridge::Handlers {
 public:
  explicit Handlers(ControllerBridge& bridge) : bridge_(bridge) {}

  void Events(const lcm::ReceiveBuffer*, const std::string&, const visual_events_t* m) {
    std::uint64_t unknown = 0;
    const VisualFrame frame = ToVisualFrame(*m, bridge_.task_, bridge_.NowNs(), bridge_.NowUtime(), &unknown);
    if (unknown > 0) bridge_.counters_.unknown_rays.fetch_add(unknown, std::memory_order_relaxed);
    bridge_.frames_.Publish(frame);
    bridge_.counters_.frames.fetch_add(1, std::memory_order_relaxed);
  }

  void Estimate(const lcm::ReceiveBuffer*, const std::string&, const robot_estimate_t* m) {
    bridge_.estimates_.Publish(ToPositionEstimate(*m, bridge_.NowNs(), bridge_.NowUtime()));
    bridge_.counters_.estimates.fetch_add(1, std::memory_order_relaxed);
  }

  void Estop(const lcm::ReceiveBuffer*, const std::string&, const fault_t* m) {
    if (m->cleared) return;  // an e-stop is latched; clearing it needs a new run
    spdlog::error("e-stop requested on {} by {}: {}", channels::kEstop, m->source, m->message);
    bridge_.estop_.store(true, std::memory_order_release);
  }

 private:
  ControllerBridge& bridge_;
};

ControllerBridge::ControllerBridge(lcm::LCM& lcm, const Task& task, Outbox& outbox, BridgeClock clock)
    : lcm_(lcm), task_(task), outbox_(outbox), clock_(std::move(clock)), handlers_(std::make_unique<Handlers>(*this)) {
  subscriptions_ = {lcm_.subscribe(channels::kVisualEvents, &Handlers::Events, handlers_.get()),
                    lcm_.subscribe(channels::kRobotEstimate, &Handlers::Estimate, handlers_.get()),
                    lcm_.subscribe(channels::kEstop, &Handlers::Estop, handlers_.get())};
}

ControllerBridge::~ControllerBridge() {
  Stop();
  for (lcm::Subscription* sub : subscriptions_) lcm_.unsubscribe(sub);  // the bus may outlive the bridge
}

std::int64_t ControllerBridge::NowNs() const { return clock_.monotonic_ns ? clock_.monotonic_ns() : MonotonicNs(); }
std::int64_t ControllerBridge::NowUtime() const { return clock_.wall_utime ? clock_.wall_utime() : WallUtime(); }

void ControllerBridge::Start() {
  if (running_.exchange(true)) return;
  receiver_ = std::thread([this] { ReceiveLoop(); });
  publisher_ = std::thread([this] { PublishLoop(); });
}

void ControllerBridge::Stop() {
  if (!running_.exchange(false)) return;
  outbox_.Notify();
  if (publisher_.joinable()) publisher_.join();
  if (receiver_.joinable()) receiver_.join();
  Drain();
}

TelemetrySnapshot ControllerBridge::last_telemetry() const {
  std::lock_guard<std::mutex> lock(telemetry_mutex_);
  return last_telemetry_;
}

void ControllerBridge::ReceiveLoop() {
  while (running_.load(std::memory_order_acquire)) lcm_.handleTimeout(20);
}

void ControllerBridge::PublishLoop() {
  while (running_.load(std::memory_order_acquire)) {
    outbox_.Wait(0.02);
    Drain();
  }
}

void ControllerBridge::Drain() {
  FaultEvent fault;
  while (outbox_.faults.TryPop(fault)) {
    const fault_t m = ToFaultMessage(fault);
    lcm_.publish(channels::kFault, &m);
    counters_.faults.fetch_add(1, std::memory_order_relaxed);
    const char* what = fault.cleared ? "cleared" : (fault.robot_stopped ? "robot stopped" : "fault");
    if (fault.severity >= fault_t::SEVERITY_ERROR) {
      spdlog::error("controller: {} (code {}): {}", what, m.code, fault.message);
    } else if (fault.severity == fault_t::SEVERITY_WARNING) {
      spdlog::warn("controller: {} (code {}): {}", what, m.code, fault.message);
    } else {
      spdlog::info("controller: {} (code {}): {}", what, m.code, fault.message);
    }
  }
  TelemetrySnapshot t;
  bool any = false;
  while (outbox_.telemetry.TryPop(t)) {
    any = true;
    controller_telemetry_t m;
    m.utime = t.utime;
    m.step_index = t.step_index;
    m.mode = static_cast<std::int8_t>(t.mode);
    m.stop_reason = t.stop_reason;
    m.command[0] = t.command.x;
    m.command[1] = t.command.y;
    m.estimate[0] = t.estimate.x;
    m.estimate[1] = t.estimate.y;
    m.estimate_age_s = t.estimate_age_s;
    m.period_s = t.period_s;
    m.cycles = t.cycles;
    m.overruns = t.overruns;
    m.jitter_min_s = t.jitter_min_s;
    m.jitter_mean_s = t.jitter_mean_s;
    m.jitter_max_s = t.jitter_max_s;
    std::copy(std::begin(t.jitter_histogram), std::end(t.jitter_histogram), m.jitter_histogram);
    lcm_.publish(channels::kTelemetry, &m);
    counters_.telemetry.fetch_add(1, std::memory_order_relaxed);
    if (t.mode != logged_mode_ || t.step_index != logged_step_) {
      if (t.mode == Mode::kDone) {
        spdlog::info("controller: strategy finished: {}", t.stop_reason);
      } else if (t.mode != Mode::kStopped) {
        if (t.step_index != logged_step_ && t.step_reason[0] != '\0') {
          spdlog::info("controller: step {} mode {} ({})", t.step_index, ToString(t.mode), t.step_reason);
        } else {
          spdlog::info("controller: step {} mode {}", t.step_index, ToString(t.mode));
        }
      }
      logged_mode_ = t.mode;
      logged_step_ = t.step_index;
    }
  }
  if (any) {
    std::lock_guard<std::mutex> lock(telemetry_mutex_);
    last_telemetry_ = t;
  }
  // The controller's heartbeat, 10 Hz, only while the loop is cycling (a stuck loop must look dead).
  const std::int64_t now = NowNs();
  const std::int64_t cycles = outbox_.cycles.load(std::memory_order_relaxed);
  if (now - last_heartbeat_ns_ >= 100'000'000 && cycles != heartbeat_cycles_) {
    last_heartbeat_ns_ = now;
    heartbeat_cycles_ = cycles;
    heartbeat_t m;
    m.utime = NowUtime();
    m.sender = "controller";
    m.node_id = -1;
    m.counter = ++heartbeat_counter_;
    m.state = (logged_mode_ == Mode::kStopped || logged_mode_ == Mode::kDone) ? heartbeat_t::STATE_STOPPED
                                                                              : heartbeat_t::STATE_OPERATIONAL;
    m.session = 0;  // only the robot driver has a session
    lcm_.publish(channels::kHeartbeatController, &m);
  }
}

}  // namespace visco::control

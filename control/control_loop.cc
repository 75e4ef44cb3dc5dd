#include "control/control_loop.h"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <time.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "visco/fault_t.hpp"

namespace visco::control {
namespace {

constexpr std::int64_t kNsPerS = 1'000'000'000;
constexpr int kMaxSendFailures = 3;  // consecutive unsent commands that stop the controller

timespec ToTimespec(std::int64_t ns) {
  timespec ts;
  ts.tv_sec = static_cast<time_t>(ns / kNsPerS);
  ts.tv_nsec = static_cast<long>(ns % kNsPerS);
  return ts;
}

// Touches `bytes` of stack so that its pages are mapped (and locked) before the loop runs.
void PrefaultStack() {
  constexpr std::size_t kBytes = 256 * 1024;
  unsigned char buffer[kBytes];
  for (std::size_t i = 0; i < kBytes; i += 4096) static_cast<volatile unsigned char*>(buffer)[i] = 0;
  asm volatile("" : : "r"(buffer) : "memory");
}

}  // namespace

std::int64_t MonotonicNs() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * kNsPerS + ts.tv_nsec;
}

std::int64_t WallUtime() {
  timespec ts;
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000 + ts.tv_nsec / 1000;
}

Outbox::Outbox() { sem_init(&wake_, 0, 0); }
Outbox::~Outbox() { sem_destroy(&wake_); }
void Outbox::Notify() { sem_post(&wake_); }
void Outbox::Wait(double timeout_s) {
  timespec deadline;
  clock_gettime(CLOCK_REALTIME, &deadline);
  const std::int64_t ns = static_cast<std::int64_t>(deadline.tv_sec) * kNsPerS + deadline.tv_nsec +
                          static_cast<std::int64_t>(timeout_s * 1e9);
  deadline = ToTimespec(ns);
  while (sem_timedwait(&wake_, &deadline) != 0 && errno == EINTR) {
  }
  // Absorb further posts: one wake drains everything queued.
  while (sem_trywait(&wake_) == 0) {
  }
}

RealtimeSetup ConfigureRealtime(int priority, bool lock_memory) {
  RealtimeSetup setup;
  std::string locked_text;
  if (lock_memory) {
    if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
      setup.locked = true;
      locked_text = "memory locked (mlockall)";
    } else {
      locked_text = std::string("mlockall failed (") + std::strerror(errno) +
                    "): page faults may add latency; run as root or raise RLIMIT_MEMLOCK";
    }
  } else {
    locked_text = "memory not locked (disabled)";
  }
  sched_param param{};
  param.sched_priority = priority;
  const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
  std::string sched_text;
  if (rc == 0) {
    setup.fifo = true;
    sched_text = "SCHED_FIFO priority " + std::to_string(priority);
  } else {
    sched_text = std::string("SCHED_FIFO not permitted (") + std::strerror(rc) +
                 "): running under the default scheduler, expect more jitter; grant CAP_SYS_NICE or an rtprio limit";
  }
  PrefaultStack();
  setup.message = "real-time setup: " + sched_text + "; " + locked_text;
  return setup;
}

ControlLoop::ControlLoop(Executor& executor, const LoopSources& sources, const LoopConfig& config, Outbox& outbox)
    : executor_(executor), sources_(sources), config_(config), outbox_(outbox) {
  if (sources_.link == nullptr) throw std::invalid_argument("ControlLoop: a robot link is required");
  if (!(config_.period_s >= 0.0005 && config_.period_s <= 0.1)) {
    throw std::invalid_argument("ControlLoop: period " + std::to_string(config_.period_s) +
                                " s is outside [0.0005, 0.1] s");
  }
  if (config_.telemetry_every < 1) config_.telemetry_every = 1;
}

void ControlLoop::RunCycle(std::int64_t now_ns, std::int64_t now_utime) {
  // Read.
  input_.now_ns = now_ns;
  input_.now_utime = now_utime;
  const std::int64_t now_us = now_ns / 1000;
  drivers::RobotLink& link = *sources_.link;
  link.Poll(now_us);
  if (link.TakeStatus(status_scratch_) == drivers::LinkResult::kOk) {
    const drivers::RobotStatus& s = status_scratch_;
    RobotStatus& status = input_.status;
    status.receive_ns = s.receive_us * 1000;
    status.utime = s.utime;
    status.seq = static_cast<std::int32_t>(s.seq);
    status.command_seq = static_cast<std::int32_t>(s.command_seq);
    status.position = {s.position[0], s.position[1]};
    status.velocity = {s.velocity[0], s.velocity[1]};
    status.contact = s.contact;
    status.contact_force = {s.contact_force[0], s.contact_force[1]};
    status.state = static_cast<std::int32_t>(s.state);
    status.fault_bits = s.fault_bits;
    input_.have_status = true;
  }
  const drivers::PeerState peer = link.peer_state(now_us);
  if (peer == drivers::PeerState::kAlive) input_.heartbeat_ns = now_ns;
  input_.peer_lost = peer == drivers::PeerState::kLost;
  while (link.TakeFault(fault_scratch_) == drivers::LinkResult::kOk) {
    const drivers::LinkFault& f = fault_scratch_;
    // A foreign fault is about another controller's session (e.g. the watchdog stop of the controller that ran
    // before this one): this controller is not commanding the driver, and waits for it to be ready.
    if (f.foreign && f.local && f.what != nullptr) {  // the link's own report about a foreign session: a warning
      FaultEvent warning;
      warning.utime = now_utime;
      warning.code = FaultCode::kPeerTimeout;
      warning.severity = visco::fault_t::SEVERITY_WARNING;
      CopyText(warning.message, f.what);
      outbox_.faults.TryPush(warning);
    }
    if (f.cleared || f.foreign || input_.link_fault_code != 0) continue;
    // Faults that stop the controller: those the driver stopped the robot for, and the link's own stopping ones
    // (bus-off, lost frames, a restarted driver, a lost session). Error passive and warning are reported only.
    if (f.robot_stopped) {
      input_.link_fault_code = f.code != 0 ? f.code : static_cast<std::int32_t>(FaultCode::kPeerTimeout);
      if (f.what != nullptr) {
        CopyText(input_.link_fault, f.what);
      } else {
        // The driver's own reason, in words (its EMCY code), with the codes.
        VISCO_FORMAT_TEXT(input_.link_fault, "%s: %s (EMCY 0x%04x, fault bits 0x%02x)",
                          f.local ? "link fault" : "the driver stopped the robot", drivers::EmcyWhat(f.emcy_code),
                          static_cast<unsigned>(f.emcy_code), static_cast<unsigned>(f.fault_bits));
      }
    }
  }
  if (input_.link_fault_code == 0 && link.bus_state() == drivers::BusState::kBusOff) {
    input_.link_fault_code = static_cast<std::int32_t>(FaultCode::kCanError);
    CopyText(input_.link_fault, "CAN bus-off");
  }
  if (input_.link_fault_code == 0 && send_failures_ >= kMaxSendFailures) {
    input_.link_fault_code = static_cast<std::int32_t>(FaultCode::kCanError);
    VISCO_FORMAT_TEXT(input_.link_fault, "%d commands in a row not sent (%s)", send_failures_,
                      drivers::ToString(last_send_result_));
  }
  if (sources_.frames != nullptr && sources_.frames->TryTake(frame_scratch_)) {
    input_.frame = frame_scratch_;
    input_.have_frame = true;
  }
  if (sources_.estimates != nullptr && sources_.estimates->TryTake(estimate_scratch_)) {
    input_.estimate = estimate_scratch_;
    input_.have_estimate = true;
  }
  input_.estop = sources_.estop != nullptr && sources_.estop->load(std::memory_order_acquire);

  // Update.
  executor_.Update(input_, output_);
  if (sources_.records != nullptr) {
    record_scratch_.cycle = cycles_;
    record_scratch_.input = input_;
    record_scratch_.command = output_.command;
    record_scratch_.mode = output_.mode;
    record_scratch_.step_index = output_.step_index;
    record_scratch_.holding = output_.holding;
    sources_.records->TryPush(record_scratch_);
  }

  // Write.
  drivers::VelocityCommand command;
  command.velocity[0] = output_.command.velocity.x;
  command.velocity[1] = output_.command.velocity.y;
  command.estop = output_.command.estop;
  command.reset = output_.command.reset;
  command.quick_stop = output_.command.quick_stop;
  last_send_result_ = link.SendCommand(command, now_us);
  // kNoSession: the driver's session is not known yet (nothing to command; the executor waits for a ready status).
  if (last_send_result_ != drivers::LinkResult::kNoSession) {
    send_failures_ = last_send_result_ == drivers::LinkResult::kOk ? 0 : send_failures_ + 1;
  }
  ++cycles_;
  outbox_.cycles.store(cycles_, std::memory_order_relaxed);
  for (int i = 0; i < output_.num_faults; ++i) outbox_.faults.TryPush(output_.faults[i]);
  const bool changed =
      output_.mode != last_mode_ || output_.step_index != last_step_ || output_.holding != last_holding_;
  if (changed || output_.num_faults > 0 || cycles_ % config_.telemetry_every == 0) {
    last_mode_ = output_.mode;
    last_step_ = output_.step_index;
    last_holding_ = output_.holding;
    PushTelemetry(now_utime);
  }
  outbox_.Notify();
}

void ControlLoop::PushTelemetry(std::int64_t now_utime) {
  TelemetrySnapshot t;
  t.utime = now_utime;
  t.step_index = output_.step_index;
  t.mode = output_.mode;
  t.holding = output_.holding;
  CopyText(t.stop_reason, output_.stop_reason);
  CopyText(t.step_reason, output_.step_reason);
  t.command = output_.command.velocity;
  t.estimate = output_.estimate;
  t.estimate_age_s = output_.estimate_age_s;
  t.period_s = config_.period_s;
  t.cycles = cycles_;
  t.overruns = overruns_;
  if (window_jitter_.count > 0) {
    t.jitter_min_s = static_cast<double>(window_jitter_.min_ns) * 1e-9;
    t.jitter_mean_s = window_jitter_.mean_ns() * 1e-9;
    t.jitter_max_s = static_cast<double>(window_jitter_.max_ns) * 1e-9;
    for (int i = 0; i < kJitterBins; ++i) t.jitter_histogram[i] = window_jitter_.histogram[i];
  }
  if (outbox_.telemetry.TryPush(t)) window_jitter_.Reset();
}

void ControlLoop::Run(const std::atomic<bool>& stop, std::int64_t max_cycles, int linger_cycles) {
  const std::int64_t period_ns = static_cast<std::int64_t>(std::llround(config_.period_s * 1e9));
  std::int64_t next = MonotonicNs() + period_ns;
  std::int64_t done_cycles = -1;
  std::int64_t count = 0;
  while (!stop.load(std::memory_order_acquire)) {
    if (max_cycles > 0 && count >= max_cycles) break;
    const timespec wake = ToTimespec(next);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &wake, nullptr) == EINTR) {
    }
    const std::int64_t woke = MonotonicNs();
    window_jitter_.Record(woke - next);
    total_jitter_.Record(woke - next);
    RunCycle(woke, WallUtime());
    ++count;
    next += period_ns;
    const std::int64_t after = MonotonicNs();
    if (after > next) {
      // Missed deadlines: count them and restart the schedule from now rather than bursting to catch up.
      std::int64_t missed = 0;
      while (next <= after) {
        next += period_ns;
        ++missed;
      }
      overruns_ += missed;
      if (after - last_overrun_report_ns_ > static_cast<std::int64_t>(config_.overrun_report_s * 1e9)) {
        last_overrun_report_ns_ = after;
        FaultEvent fault;
        fault.utime = WallUtime();
        fault.code = FaultCode::kOverrun;
        fault.severity = fault_t::SEVERITY_WARNING;
        VISCO_FORMAT_TEXT(fault.message, "control loop overran its %.3f ms period (%lld overruns in %lld cycles)",
                          config_.period_s * 1e3, static_cast<long long>(overruns_), static_cast<long long>(cycles_));
        outbox_.faults.TryPush(fault);
      }
    }
    if (executor_.finished()) {
      if (done_cycles < 0) done_cycles = 0;
      if (++done_cycles > linger_cycles) break;
    }
  }
}

}  // namespace visco::control

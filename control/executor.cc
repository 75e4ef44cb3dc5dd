#include "control/executor.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "visco/fault_t.hpp"
#include "visco/robot_status_t.hpp"
#include "visco/visual_event_t.hpp"

namespace visco::control {
namespace {

constexpr double kNsPerS = 1e9;
double Seconds(std::int64_t ns) { return static_cast<double>(ns) / kNsPerS; }
std::int64_t Nanoseconds(double s) { return static_cast<std::int64_t>(s * kNsPerS); }

FaultCode CodeForDriverFaults(std::int32_t bits, std::int32_t state) {
  if ((bits & robot_status_t::FAULT_ESTOP) != 0 || state == robot_status_t::STATE_ESTOP) return FaultCode::kEstop;
  if ((bits & robot_status_t::FAULT_BUS) != 0) return FaultCode::kCanError;
  if ((bits & (int32_t{robot_status_t::FAULT_BAD_FRAME} | int32_t{robot_status_t::FAULT_SEQUENCE} |
               int32_t{robot_status_t::FAULT_SESSION})) != 0)
    return FaultCode::kBadMessage;
  if ((bits & (int32_t{robot_status_t::FAULT_LIMIT} | int32_t{robot_status_t::FAULT_BOUNDS})) != 0)
    return FaultCode::kLimit;
  return FaultCode::kPeerTimeout;  // watchdog, or stopped for a reason it did not give
}

// Names of the set fault bits, e.g. "watchdog|sequence". Real-time safe (fixed buffer).
void FaultBitNames(std::int32_t bits, char (&out)[96]) {
  static constexpr struct {
    std::int32_t bit;
    const char* name;
  } kNames[] = {{robot_status_t::FAULT_WATCHDOG, "watchdog"}, {robot_status_t::FAULT_BAD_FRAME, "bad-frame"},
                {robot_status_t::FAULT_SEQUENCE, "sequence"}, {robot_status_t::FAULT_LIMIT, "limit"},
                {robot_status_t::FAULT_BOUNDS, "bounds"},     {robot_status_t::FAULT_BUS, "bus"},
                {robot_status_t::FAULT_ESTOP, "estop"},       {robot_status_t::FAULT_SESSION, "session"}};
  out[0] = '\0';
  std::size_t used = 0;
  for (const auto& entry : kNames) {
    if ((bits & entry.bit) == 0) continue;
    const int written = std::snprintf(out + used, sizeof(out) - used, "%s%s", used == 0 ? "" : "|", entry.name);
    if (written < 0) break;
    used = std::min(sizeof(out) - 1, used + static_cast<std::size_t>(written));
  }
  if (used == 0) CopyText(out, "none");
}

}  // namespace

const char* ToString(Mode mode) {
  switch (mode) {
    case Mode::kIdle:
      return "idle";
    case Mode::kFree:
      return "free";
    case Mode::kVisualGuarded:
      return "visual-guarded";
    case Mode::kVisualCompliant:
      return "visual-compliant";
    case Mode::kDone:
      return "done";
    case Mode::kStopped:
      return "stopped";
  }
  return "?";
}

Executor::Executor(const Task& task, const ExecutorConfig& config)
    : task_(task),
      config_(config),
      safety_(config.limits, task.bounds),
      speed_(task.speed > 0 ? task.speed : config.default_speed) {
  ValidateTask(task_, task_.scene.empty() ? "strategy" : task_.scene);
  rays_.assign(task_.rays.size(), RayState{});
}

void Executor::Start(std::int64_t now_ns) {
  started_ = true;
  start_ns_ = now_ns;
  step_reason_[0] = '\0';
  mode_ = Mode::kIdle;
  step_ = -1;
}

void Executor::BeginStep(int index, std::int64_t now_ns, int reached_ray) {
  step_ = index;
  step_start_ns_ = now_ns;
  std::fill(rays_.begin(), rays_.end(), RayState{});
  engaged_ray_ = -1;
  contact_latched_ = false;
  contact_since_ns_ = -1;
  stuck_since_ns_ = -1;
  const Step& step = task_.steps[static_cast<std::size_t>(index)];
  mode_ = step.terminate == TerminateKind::kVisualGuarded ? Mode::kVisualGuarded : Mode::kFree;
  // The previous step ended on reaching `reached_ray` (visual guarded motion): if this step complies to that ray, it
  // starts engaged on it. The robot is on the ray by construction, up to the stop's overshoot, which the law's
  // normal correction removes; waiting to reach the ray again could wait forever (the new direction may lead away
  // from the side the overshoot left it on).
  if (reached_ray >= 0 &&
      std::find(step.active_rays.begin(), step.active_rays.end(), reached_ray) != step.active_rays.end()) {
    engaged_ray_ = reached_ray;
    rays_[static_cast<std::size_t>(reached_ray)].reached = true;
  }
}

void Executor::AddFault(ExecutorOutput& out, const ExecutorInput& in, FaultCode code, std::int8_t severity,
                        bool stopped, bool cleared, const char* message) {
  if (out.num_faults >= kMaxFaultsPerUpdate) return;
  FaultEvent& fault = out.faults[out.num_faults++];
  fault.utime = in.now_utime;
  fault.code = code;
  fault.severity = severity;
  fault.robot_stopped = stopped;
  fault.cleared = cleared;
  CopyText(fault.message, message);
}

void Executor::Stop(FaultCode code, const char* message, ExecutorOutput& out, const ExecutorInput& in) {
  mode_ = Mode::kStopped;
  stop_code_ = code;
  CopyText(stop_reason_, message);
  holding_ = false;
  AddFault(out, in, code, fault_t::SEVERITY_ERROR, true, false, message);
  Finish(out, in, {}, true);
}

const VisualObservation* Executor::Find(const VisualFrame& frame, int ray) const {
  const int n = std::min(frame.count, kMaxVisualObservations);
  for (int i = 0; i < n; ++i) {
    if (frame.items[i].ray == ray) return &frame.items[i];
  }
  return nullptr;
}

double Executor::ApproachSpeed(const ExecutorInput& in, const Step& step, Vec2 estimate) const {
  if (!(config_.approach_tolerance_m > 0) || !in.have_frame) return speed_;
  // The event of a crossing is seen up to one frame interval plus the frame's age after it happens.
  const double late = std::max(1e-3, Seconds(in.now_ns - in.frame.capture_ns) + frame_interval_s_);
  double speed = speed_;
  auto consider = [&](int ray) {
    if (ray < 0 || ray == engaged_ray_ || rays_[static_cast<std::size_t>(ray)].reached) return;
    const VisualObservation* obs = Find(in.frame, ray);
    if (!obs || static_cast<Side>(obs->state) == Side::kUnknown) return;
    const CvcRay& r = task_.rays[static_cast<std::size_t>(ray)];
    double distance = 0.0;
    if (config_.servo.camera.valid) {
      // Metres to the line along its normal, through the exact interaction (px/m along n) at the estimate.
      const Vec2 row =
          CameraInteractionRow(config_.servo.camera, r.direction, estimate + r.cm_offset, config_.servo.min_range_m);
      const double px_per_m = Dot(row, LeftNormal(r.direction));
      distance = px_per_m > 0 ? std::abs(obs->signed_distance_px) / px_per_m : 0.0;
    } else {
      const double range =
          std::max(r.has_cm_offset ? Norm(estimate + r.cm_offset - r.to) : config_.servo.nominal_range_m,
                   config_.servo.min_range_m);
      distance = std::abs(obs->signed_distance_px) * range / config_.servo.focal_px;
    }
    speed = std::min(speed, std::max(config_.approach_tolerance_m, distance) / late);
  };
  for (int ray : step.active_rays) consider(ray);
  consider(step.terminate_ray);
  return speed;
}

bool Executor::TrackRay(int ray, const VisualObservation& obs) {
  RayState& state = rays_[static_cast<std::size_t>(ray)];
  const Side side = static_cast<Side>(obs.state);
  if (side == Side::kUnknown) return false;
  bool reached = side == Side::kOnLine || obs.crossed;
  if (!reached && state.first_side != Side::kUnknown && side != state.first_side) reached = true;
  if (reached) {
    state.reached = true;
    state.first_side = Side::kUnknown;  // re-armed: the next clear side is the new reference
  } else if (state.first_side == Side::kUnknown) {
    state.first_side = side;
  }
  return reached;
}

void Executor::Finish(ExecutorOutput& out, const ExecutorInput& in, Vec2 nominal, bool zero) {
  Vec2 command{};
  if (!zero) {
    const Vec2* position = in.have_status ? &in.status.position : nullptr;
    const SafetyVerdict verdict = safety_.Apply(nominal, last_command_, config_.period_s, position, command);
    if (verdict == SafetyVerdict::kOutsideBounds || verdict == SafetyVerdict::kNonFinite) {
      char message[128];
      if (verdict == SafetyVerdict::kOutsideBounds) {
        VISCO_FORMAT_TEXT(message, "position (%.4f, %.4f) m is outside the workspace bounds", in.status.position.x,
                          in.status.position.y);
      } else {
        CopyText(message, "the control law produced a non-finite velocity");
      }
      Stop(FaultCode::kLimit, message, out, in);
      return;
    }
  }
  last_command_ = command;
  out.command.utime = in.now_utime;
  out.command.seq = ++seq_;
  out.command.velocity = command;
  out.command.estop = estop_latched_;
  out.command.reset = mode_ == Mode::kIdle && started_;
  out.command.quick_stop = mode_ == Mode::kStopped;
  out.mode = mode_;
  out.step_index = step_;
  out.holding = holding_;
  CopyText(out.step_reason, step_reason_);
  if (mode_ == Mode::kStopped) {
    CopyText(out.stop_reason, stop_reason_);
  } else if (holding_) {
    CopyText(out.stop_reason, hold_reason_);
  } else if (mode_ == Mode::kDone) {
    CopyText(out.stop_reason, stop_reason_);
  } else {
    out.stop_reason[0] = '\0';
  }
}

void Executor::Update(const ExecutorInput& in, ExecutorOutput& out) {
  out.num_faults = 0;
  char message[128];
  const bool use_odometry = config_.goal_from_odometry || !in.have_estimate;
  out.estimate = use_odometry ? in.status.position : in.estimate.position;
  out.estimate_age_s = use_odometry ? (in.have_status ? Seconds(in.now_ns - in.status.receive_ns) : 0.0)
                                    : Seconds(in.now_ns - in.estimate.capture_ns);
  if (!started_ || mode_ == Mode::kDone || mode_ == Mode::kStopped) {
    Finish(out, in, {}, true);
    return;
  }
  if (in.estop) {
    estop_latched_ = true;
    Stop(FaultCode::kEstop, "e-stop requested", out, in);
    return;
  }

  if (in.link_fault_code != 0) {
    VISCO_FORMAT_TEXT(message, "robot link: %s", in.link_fault);
    Stop(static_cast<FaultCode>(in.link_fault_code), message, out, in);
    return;
  }
  if (in.peer_lost && mode_ != Mode::kIdle) {
    Stop(FaultCode::kPeerTimeout, "driver heartbeat lost (no heartbeat within the link's time-out)", out, in);
    return;
  }

  // Driver liveness: its status stream (a status follows every command and comes at least every few ms), and the
  // link's judgement of its heartbeat (peer_lost, above).
  const std::int64_t life_ns = in.have_status ? in.status.receive_ns : 0;
  const bool alive = life_ns > 0 && in.now_ns - life_ns <= Nanoseconds(config_.heartbeat_timeout_s);
  const std::int32_t state = in.status.state;
  // The bus bit alone (error passive: the driver keeps the robot going) is no reason to stop; bus-off stops the
  // driver, whose state then says so.
  const bool driver_ok = in.have_status && (in.status.fault_bits & ~std::int32_t{robot_status_t::FAULT_BUS}) == 0 &&
                         (state == robot_status_t::STATE_READY || state == robot_status_t::STATE_MOVING);
  if (mode_ == Mode::kIdle) {
    // Start when the driver is ready and, if the first step watches the camera, once vision has spoken (so that a
    // start does not begin with a hold).
    const Step& first = task_.steps.front();
    const bool first_needs_events = !first.active_rays.empty() || first.terminate_ray >= 0;
    const bool first_needs_estimate = first.terminate == TerminateKind::kGoal && !config_.goal_from_odometry;
    const bool vision_ready = (!first_needs_events || in.have_frame) && (!first_needs_estimate || in.have_estimate);
    if (alive && driver_ok && vision_ready) {
      BeginStep(0, in.now_ns);
      Finish(out, in, {}, true);
      return;
    }
    if (in.now_ns - start_ns_ > Nanoseconds(config_.startup_timeout_s)) {
      if (alive && driver_ok) {
        VISCO_FORMAT_TEXT(message, "no %s from vision within %.1f s of start",
                          first_needs_events && !in.have_frame ? "visual events" : "robot estimate",
                          config_.startup_timeout_s);
        Stop(FaultCode::kVisionStale, message, out, in);
        return;
      }
      if (!alive) {
        VISCO_FORMAT_TEXT(message, "no status or heartbeat from the driver within %.1f s of start",
                          config_.startup_timeout_s);
      } else if (state == robot_status_t::STATE_ESTOP) {
        CopyText(message, "driver e-stop latched: the operator must release it at the driver (visco driver: SIGUSR1)");
      } else {
        char bits[96];
        FaultBitNames(in.status.fault_bits, bits);
        VISCO_FORMAT_TEXT(message, "driver not ready within %.1f s of start (state %d, faults %s)",
                          config_.startup_timeout_s, static_cast<int>(state), bits);
      }
      Stop(FaultCode::kPeerTimeout, message, out, in);
      return;
    }
    Finish(out, in, {}, true);  // zero velocity with reset, until the driver is ready
    return;
  }
  if (!alive) {
    VISCO_FORMAT_TEXT(message, "driver silent: no status or heartbeat for %.0f ms (limit %.0f ms)",
                      life_ns > 0 ? Seconds(in.now_ns - life_ns) * 1e3 : -1.0, config_.heartbeat_timeout_s * 1e3);
    Stop(FaultCode::kPeerTimeout, message, out, in);
    return;
  }
  if (!driver_ok) {
    char bits[96];
    FaultBitNames(in.status.fault_bits, bits);
    VISCO_FORMAT_TEXT(message, "driver reports a fault: state %d, faults %s", static_cast<int>(state), bits);
    Stop(CodeForDriverFaults(in.status.fault_bits, state), message, out, in);
    return;
  }

  const Step& step = task_.steps[static_cast<std::size_t>(step_)];
  const double timeout = step.timeout_s > 0 ? step.timeout_s : config_.default_step_timeout_s;
  if (in.now_ns - step_start_ns_ > Nanoseconds(timeout)) {
    VISCO_FORMAT_TEXT(message, "step %d (terminate %s) did not terminate within %.1f s", step_,
                      ToString(step.terminate), timeout);
    Stop(FaultCode::kStepTimeout, message, out, in);
    return;
  }

  // Visual input this step needs: fresh, and an observation of every ray it watches.
  FaultCode hold = FaultCode::kNone;
  const std::int64_t max_age = Nanoseconds(config_.max_vision_age_s);
  const bool need_events = !step.active_rays.empty() || step.terminate_ray >= 0;
  if (need_events) {
    if (!in.have_frame) {
      hold = FaultCode::kVisionStale;
      CopyText(message, "no visual events received");
    } else if (in.now_ns - in.frame.capture_ns > max_age) {
      hold = FaultCode::kVisionStale;
      VISCO_FORMAT_TEXT(message, "visual events %.0f ms old (limit %.0f ms)",
                        Seconds(in.now_ns - in.frame.capture_ns) * 1e3, config_.max_vision_age_s * 1e3);
    } else {
      auto check = [&](int ray) {
        const VisualObservation* obs = Find(in.frame, ray);
        if (hold == FaultCode::kNone && (obs == nullptr || obs->state == visual_event_t::STATE_UNKNOWN)) {
          hold = FaultCode::kVisionLost;
          VISCO_FORMAT_TEXT(message, "CVC ray \"%s\" not observed in frame %lld",
                            task_.rays[static_cast<std::size_t>(ray)].id.c_str(),
                            static_cast<long long>(in.frame.frame_seq));
        }
      };
      for (int ray : step.active_rays) check(ray);
      if (step.terminate_ray >= 0) check(step.terminate_ray);
    }
  }
  if (hold == FaultCode::kNone && step.terminate == TerminateKind::kGoal && !config_.goal_from_odometry) {
    if (!in.have_estimate) {
      hold = FaultCode::kVisionStale;
      CopyText(message, "no robot position estimate received");
    } else if (in.now_ns - in.estimate.capture_ns > max_age) {
      hold = FaultCode::kVisionStale;
      VISCO_FORMAT_TEXT(message, "robot position estimate %.0f ms old (limit %.0f ms)",
                        Seconds(in.now_ns - in.estimate.capture_ns) * 1e3, config_.max_vision_age_s * 1e3);
    } else if (!in.estimate.valid) {
      hold = FaultCode::kVisionLost;
      CopyText(message, "robot not seen by the camera");
    }
  }
  if (hold != FaultCode::kNone) {
    if (!holding_ || hold != hold_code_) {
      if (!holding_) hold_since_ns_ = in.now_ns;
      holding_ = true;
      hold_code_ = hold;
      VISCO_FORMAT_TEXT(hold_reason_, "holding: %s", message);
      AddFault(out, in, hold, fault_t::SEVERITY_WARNING, true, false, message);
    } else if (in.now_ns - hold_since_ns_ > Nanoseconds(config_.max_hold_s)) {
      char stop[128];
      VISCO_FORMAT_TEXT(stop, "vision not restored within %.1f s: %s", config_.max_hold_s, message);
      Stop(hold, stop, out, in);
      return;
    }
    Finish(out, in, {}, true);
    return;
  }
  if (holding_) {
    holding_ = false;
    VISCO_FORMAT_TEXT(message, "vision restored after %.0f ms; resuming step %d",
                      Seconds(in.now_ns - hold_since_ns_) * 1e3, step_);
    AddFault(out, in, hold_code_, fault_t::SEVERITY_INFO, false, true, message);
  }

  // Termination and ray engagement, from frames captured during this step, each processed once.
  bool terminated = false;
  int reached_ray = -1;
  if (need_events && in.frame.frame_seq != last_frame_seq_ && in.frame.capture_ns >= step_start_ns_) {
    last_frame_seq_ = in.frame.frame_seq;
    if (last_capture_ns_ >= 0 && in.frame.capture_ns > last_capture_ns_)
      frame_interval_s_ = Seconds(in.frame.capture_ns - last_capture_ns_);
    last_capture_ns_ = in.frame.capture_ns;
    for (int ray : step.active_rays) {
      const VisualObservation* obs = Find(in.frame, ray);
      if (TrackRay(ray, *obs) && ray != engaged_ray_ && !contact_latched_) engaged_ray_ = ray;
    }
    if (step.terminate_ray >= 0) {
      const VisualObservation* obs = Find(in.frame, step.terminate_ray);
      const bool already_tracked =
          std::find(step.active_rays.begin(), step.active_rays.end(), step.terminate_ray) != step.active_rays.end();
      if (already_tracked ? rays_[static_cast<std::size_t>(step.terminate_ray)].reached
                          : TrackRay(step.terminate_ray, *obs)) {
        terminated = true;
        reached_ray = step.terminate_ray;
        VISCO_FORMAT_TEXT(message, "step %d: reached CVC ray \"%s\"", step_,
                          task_.rays[static_cast<std::size_t>(step.terminate_ray)].id.c_str());
      }
    }
  }
  if (step.terminate == TerminateKind::kGoal && task_.goal &&
      InKernel(*task_.goal, task_.position_uncertainty, out.estimate)) {
    terminated = true;
    VISCO_FORMAT_TEXT(message, "step %d: goal recognised at (%.4f, %.4f) m", step_, out.estimate.x, out.estimate.y);
  }
  const bool stopped_in_contact = in.status.contact && Norm(in.status.velocity) < config_.contact_speed;
  if (stopped_in_contact) {
    if (contact_since_ns_ < 0) contact_since_ns_ = in.now_ns;
  } else {
    contact_since_ns_ = -1;
  }
  if (step.terminate == TerminateKind::kContact && contact_since_ns_ >= 0 &&
      in.now_ns - contact_since_ns_ >= Nanoseconds(config_.contact_dwell_s) &&
      in.now_ns - step_start_ns_ >= Nanoseconds(config_.contact_min_step_s)) {
    terminated = true;
    VISCO_FORMAT_TEXT(message, "step %d: stopped in contact at (%.4f, %.4f) m", step_, in.status.position.x,
                      in.status.position.y);
  }
  // Stuck: in contact and not moving for stuck_s, away from the goal. Under the step's constant direction nothing
  // frees it (docs/semantics.md: sticking is final), so the step can no longer end as planned: say where, now.
  if (in.status.contact) {
    if (stuck_since_ns_ < 0 || Norm(in.status.position - stuck_at_) > config_.stuck_distance) {
      stuck_since_ns_ = in.now_ns;
      stuck_at_ = in.status.position;
    }
  } else {
    stuck_since_ns_ = -1;
  }
  if (!terminated && step.terminate != TerminateKind::kContact && config_.stuck_s > 0 && stuck_since_ns_ >= 0 &&
      in.now_ns - stuck_since_ns_ >= Nanoseconds(config_.stuck_s) &&
      !(task_.goal && (InPolygon(*task_.goal, out.estimate) ||
                       BoundaryDistance(*task_.goal, out.estimate) <= task_.position_uncertainty))) {
    VISCO_FORMAT_TEXT(message,
                      "step %d (terminate %s): stuck in contact at (%.4f, %.4f) m for %.1f s, away from the goal",
                      step_, ToString(step.terminate), out.estimate.x, out.estimate.y, config_.stuck_s);
    Stop(FaultCode::kStrategyFailed, message, out, in);
    return;
  }
  if (terminated) {
    if (step_ + 1 >= static_cast<int>(task_.steps.size())) {
      mode_ = Mode::kDone;
      VISCO_FORMAT_TEXT(stop_reason_, "done: %s", message);
      step_ = static_cast<int>(task_.steps.size());
    } else {
      CopyText(step_reason_, message);
      BeginStep(step_ + 1, in.now_ns, reached_ray);
    }
    Finish(out, in, {}, true);  // the terminated motion stops; the next one starts next period
    return;
  }

  // Command. Contact ends a visual compliant motion (the contact rules take over, docs/semantics.md).
  if (in.status.contact && engaged_ray_ >= 0) {
    contact_latched_ = true;
    engaged_ray_ = -1;
  } else if (contact_latched_ && !in.status.contact) {
    contact_latched_ = false;
  }
  const Vec2 direction = FromAngle(step.theta);
  Vec2 nominal = (engaged_ray_ >= 0 ? speed_ : ApproachSpeed(in, step, out.estimate)) * direction;
  if (engaged_ray_ >= 0) {
    const CvcRay& ray = task_.rays[static_cast<std::size_t>(engaged_ray_)];
    const VisualObservation* obs = Find(in.frame, engaged_ray_);
    if (config_.servo.camera.valid) {
      // The calibrated camera: the exact interaction row at the tracked point (the CM vertex at the estimate).
      const Vec2 row = CameraInteractionRow(config_.servo.camera, ray.direction, out.estimate + ray.cm_offset,
                                            config_.servo.min_range_m);
      nominal =
          VisualComplianceLaw(config_.servo, ray.direction, direction, speed_, obs->signed_distance_px, row).velocity;
    } else {
      const double range = ray.has_cm_offset ? Norm(out.estimate + ray.cm_offset - ray.to) : 0.0;
      nominal =
          VisualComplianceLaw(config_.servo, ray.direction, direction, speed_, obs->signed_distance_px, range).velocity;
    }
    mode_ = Mode::kVisualCompliant;
  } else {
    mode_ = step.terminate == TerminateKind::kVisualGuarded ? Mode::kVisualGuarded : Mode::kFree;
  }
  Finish(out, in, nominal, false);
}

}  // namespace visco::control

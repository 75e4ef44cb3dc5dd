#include "control/safety.h"

#include <cmath>

namespace visco::control {

namespace {

// The largest speed towards a wall `d` metres away from which decelerating by `a` per period of `dt` stops the robot
// within `d`: with v, v - a dt, v - 2 a dt, ... the distance is about v^2 / (2a) + v dt / 2, so
// v = sqrt((a dt / 2)^2 + 2 a d) - a dt / 2 (0 at d <= 0).
double BrakingSpeed(double d, double a, double dt) {
  if (!(d > 0)) return 0.0;
  const double h = 0.5 * a * dt;
  return std::sqrt(h * h + 2.0 * a * d) - h;
}

// Caps the component of `v` along +axis (sign +1) or -axis (sign -1) at `limit` (>= 0).
void CapOutward(double& component, double sign, double limit, bool& changed) {
  if (sign * component > limit) {
    component = sign * limit;
    changed = true;
  }
}

}  // namespace

SafetyVerdict SafetyFilter::Apply(Vec2 nominal, Vec2 previous, double dt, const Vec2* position, Vec2& out) const {
  out = {};
  if (!std::isfinite(nominal.x) || !std::isfinite(nominal.y)) return SafetyVerdict::kNonFinite;
  SafetyVerdict verdict = SafetyVerdict::kOk;
  Vec2 v = nominal;
  if (bounds_ && position != nullptr) {
    const Vec2 p = *position;
    if (p.x < bounds_->min.x || p.x > bounds_->max.x || p.y < bounds_->min.y || p.y > bounds_->max.y) {
      return SafetyVerdict::kOutsideBounds;
    }
  }
  const double speed = Norm(v);
  if (speed > limits_.max_speed) {
    v = (limits_.max_speed / speed) * v;
    verdict = SafetyVerdict::kClipped;
  }
  const Vec2 dv = v - previous;
  const double step = Norm(dv);
  const double allowed = limits_.max_accel * dt;
  if (step > allowed) {
    v = previous + (allowed / step) * dv;
    verdict = SafetyVerdict::kClipped;
  }
  // The bounds last, so that nothing puts outward velocity back: towards each bound the speed is capped at the
  // braking speed for the distance left to the margin line (bound - margin), so the robot decelerates at the
  // acceleration limit and comes to rest before the margin, which only has to cover the position's latency.
  if (bounds_ && position != nullptr) {
    const Vec2 p = *position;
    const double m = limits_.bounds_margin;
    const double a = limits_.max_accel;
    bool changed = false;
    CapOutward(v.x, -1.0, BrakingSpeed(p.x - bounds_->min.x - m, a, dt), changed);
    CapOutward(v.x, +1.0, BrakingSpeed(bounds_->max.x - m - p.x, a, dt), changed);
    CapOutward(v.y, -1.0, BrakingSpeed(p.y - bounds_->min.y - m, a, dt), changed);
    CapOutward(v.y, +1.0, BrakingSpeed(bounds_->max.y - m - p.y, a, dt), changed);
    if (changed) verdict = SafetyVerdict::kClipped;
  }
  out = v;
  return verdict;
}

}  // namespace visco::control

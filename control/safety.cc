#include "control/safety.h"

#include <cmath>

namespace visco::control {

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
    const double m = limits_.bounds_margin;
    const Vec2 before = v;
    if (p.x <= bounds_->min.x + m && v.x < 0) v.x = 0;
    if (p.x >= bounds_->max.x - m && v.x > 0) v.x = 0;
    if (p.y <= bounds_->min.y + m && v.y < 0) v.y = 0;
    if (p.y >= bounds_->max.y - m && v.y > 0) v.y = 0;
    if (v.x != before.x || v.y != before.y) verdict = SafetyVerdict::kClipped;
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
  out = v;
  return verdict;
}

}  // namespace visco::control

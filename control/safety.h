#pragma once
// Command limits applied to every command before it leaves the controller: speed, acceleration and workspace
// bounds (a braking curve towards each bound, applied last). Stops do not pass through here: the executor zeroes the
// command at once (a stop is immediate).

#include <optional>

#include "control/task.h"
#include "control/types.h"

namespace visco::control {

struct SafetyLimits {
  double max_speed = 0.2;  // m/s, |v| is clipped to this
  double max_accel = 2.0;  // m/s^2, |dv/dt| is clipped to this
  // metres: the robot comes to rest this far inside a bound. Towards a bound the speed is capped at the braking
  // speed for the distance to bound - margin (about sqrt(2 a d)), after the speed and acceleration limits, so the
  // robot decelerates at max_accel and the margin only covers the latency of the measured position.
  double bounds_margin = 0.005;
};

/// Outcome of filtering one command.
enum class SafetyVerdict : std::int8_t {
  kOk = 0,
  kClipped,        // speed, acceleration or a bound changed the command
  kOutsideBounds,  // the position is outside the workspace: stop
  kNonFinite,      // the nominal command was NaN or infinite: stop
};

/// Applies the limits. Real-time safe: no allocation, never throws.
class SafetyFilter {
 public:
  SafetyFilter(const SafetyLimits& limits, std::optional<Bounds> bounds) : limits_(limits), bounds_(bounds) {}

  /// Filters `nominal` given the previous command `previous` (m/s), the period `dt` (s) and the position (m) if
  /// known. Writes the command to send into `out`. On kOutsideBounds / kNonFinite `out` is zero.
  SafetyVerdict Apply(Vec2 nominal, Vec2 previous, double dt, const Vec2* position, Vec2& out) const;

  const SafetyLimits& limits() const { return limits_; }
  const std::optional<Bounds>& bounds() const { return bounds_; }

 private:
  SafetyLimits limits_;
  std::optional<Bounds> bounds_;
};

}  // namespace visco::control

#include "control/servo_law.h"

#include <algorithm>

namespace visco::control {
namespace {
double Range(const ServoConfig& config, double range_m) {
  const double rho = range_m > 0 ? range_m : config.nominal_range_m;
  return std::max(rho, config.min_range_m);
}
}  // namespace

Vec2 InteractionRow(const ServoConfig& config, Vec2 direction, double range_m) {
  return (config.focal_px / Range(config, range_m)) * LeftNormal(direction);
}

ServoOutput VisualComplianceLaw(const ServoConfig& config, Vec2 direction, Vec2 command_direction, double speed,
                                double signed_distance_px, double range_m) {
  ServoOutput out;
  out.tangential = (speed * Dot(command_direction, direction)) * direction;
  // -lambda L^+ e, with L^+ = L^T / (L L^T) = (rho / f) n for the unit normal n.
  const Vec2 normal = LeftNormal(direction);
  double magnitude = -config.gain * (Range(config, range_m) / config.focal_px) * signed_distance_px;
  if (std::abs(magnitude) > config.max_normal_speed) {
    magnitude = magnitude > 0 ? config.max_normal_speed : -config.max_normal_speed;
    out.saturated = true;
  }
  out.normal = magnitude * normal;
  out.velocity = out.tangential + out.normal;
  return out;
}

}  // namespace visco::control

#include "control/servo_law.h"

#include <algorithm>
#include <cmath>

namespace visco::control {
namespace {
double Range(const ServoConfig& config, double range_m) {
  const double rho = range_m > 0 ? range_m : config.nominal_range_m;
  return std::max(rho, config.min_range_m);
}

// X = cRw (p, h) + ctw.
void CameraPoint(const ServoCamera& c, Vec2 p, double (&x)[3]) {
  for (int i = 0; i < 3; ++i) x[i] = c.cRw[i][0] * p.x + c.cRw[i][1] * p.y + c.cRw[i][2] * c.point_height_m + c.ctw[i];
}

double Saturate(double value, double limit, bool& saturated) {
  if (std::abs(value) > limit) {
    saturated = true;
    return value > 0 ? limit : -limit;
  }
  return value;
}
}  // namespace

ServoCamera MakeServoCamera(double px, double py, double u0, double v0, const double (&wRc)[3][3],
                            const double (&wtc)[3], double point_height_m) {
  ServoCamera c;
  c.valid = true;
  c.px = px, c.py = py, c.u0 = u0, c.v0 = v0;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) c.cRw[i][j] = wRc[j][i];
  }
  for (int i = 0; i < 3; ++i) c.ctw[i] = -(c.cRw[i][0] * wtc[0] + c.cRw[i][1] * wtc[1] + c.cRw[i][2] * wtc[2]);
  c.point_height_m = point_height_m;
  return c;
}

ImageLine VcImageLine(const ServoCamera& c, Vec2 direction) {
  // The VC surface: the vertical plane through the camera centre with horizontal normal (n, 0), n the left normal;
  // in the camera frame N . X = 0 with N = cRw (n, 0), positive on n's side.
  const Vec2 n = LeftNormal(direction);
  double N[3];
  for (int i = 0; i < 3; ++i) N[i] = c.cRw[i][0] * n.x + c.cRw[i][1] * n.y;
  // N . (x, y, 1) with x = (u - u0) / px, y = (v - v0) / py.
  ImageLine l{N[0] / c.px, N[1] / c.py, N[2] - N[0] * c.u0 / c.px - N[1] * c.v0 / c.py};
  const double s = std::hypot(l.a, l.b);
  if (s > 0) l = {l.a / s, l.b / s, l.c / s};
  return l;
}

double ModelSignedDistance(const ServoCamera& c, Vec2 direction, Vec2 point, bool* in_front) {
  double x[3];
  CameraPoint(c, point, x);
  if (in_front != nullptr) *in_front = x[2] > 0;
  const ImageLine l = VcImageLine(c, direction);
  const double u = c.u0 + c.px * x[0] / x[2], v = c.v0 + c.py * x[1] / x[2];
  return l.a * u + l.b * v + l.c;
}

Vec2 InteractionRow(const ServoConfig& config, Vec2 direction, double range_m) {
  return (config.focal_px / Range(config, range_m)) * LeftNormal(direction);
}

Vec2 CameraInteractionRow(const ServoCamera& c, Vec2 direction, Vec2 point, double min_depth_m) {
  double X[3];
  CameraPoint(c, point, X);
  if (!(X[2] > 0)) return {};
  const double z = std::max(X[2], min_depth_m);
  const ImageLine l = VcImageLine(c, direction);
  // dd/dX = (1/Z) (a px, b py, -(a px x + b py y)), then dX/dp = cRw[:, 0:2].
  const double x = X[0] / X[2], y = X[1] / X[2];
  const double g[3] = {l.a * c.px / z, l.b * c.py / z, -(l.a * c.px * x + l.b * c.py * y) / z};
  return {g[0] * c.cRw[0][0] + g[1] * c.cRw[1][0] + g[2] * c.cRw[2][0],
          g[0] * c.cRw[0][1] + g[1] * c.cRw[1][1] + g[2] * c.cRw[2][1]};
}

ServoOutput VisualComplianceLaw(const ServoConfig& config, Vec2 direction, Vec2 command_direction, double speed,
                                double signed_distance_px, double range_m) {
  ServoOutput out;
  out.tangential = (speed * Dot(command_direction, direction)) * direction;
  // -lambda L^+ e, with L^+ = L^T / (L L^T) = (rho / f) n for the unit normal n.
  const Vec2 normal = LeftNormal(direction);
  double magnitude = -config.gain * (Range(config, range_m) / config.focal_px) * signed_distance_px;
  magnitude = Saturate(magnitude, config.max_normal_speed, out.saturated);
  out.normal = magnitude * normal;
  out.velocity = out.tangential + out.normal;
  return out;
}

ServoOutput VisualComplianceLaw(const ServoConfig& config, Vec2 direction, Vec2 command_direction, double speed,
                                double signed_distance_px, Vec2 interaction) {
  ServoOutput out;
  out.tangential = (speed * Dot(command_direction, direction)) * direction;
  const Vec2 normal = LeftNormal(direction);
  const double jn = Dot(interaction, normal);
  double magnitude = 0.0;
  if (jn > 0 && std::isfinite(jn)) {
    // J (v_t + m n) = -lambda e.
    magnitude = -(config.gain * signed_distance_px + Dot(interaction, out.tangential)) / jn;
    magnitude = Saturate(magnitude, config.max_normal_speed, out.saturated);
  } else {
    out.degenerate = true;
  }
  out.normal = magnitude * normal;
  out.velocity = out.tangential + out.normal;
  return out;
}

}  // namespace visco::control

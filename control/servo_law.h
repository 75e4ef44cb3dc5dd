#pragma once
// The visual compliant motion law: keep a CM vertex on a VC line in the image while moving along it.
//
// Feature: s = the signed image distance d (pixels) from the CM vertex's image to the VC line, positive on the
// side of the ray's left normal n (visual_event_t). Desired: s* = 0.
// Interaction matrix: for a vertex at range rho (metres) from the camera centre along the ray, a world
// displacement dq moves its image by dd = L dq with L = (f / rho) n^T (1x2, px/m; f the focal length in pixels).
// This is the planar pinhole camera's derivative at the line (terms in d / rho vanish there).
// Law (image-based visual servoing, e = s - s*):
//   v = v_t + v_n,   v_t = s_cmd (u . t) t          the commanded velocity's projection on the ray (docs/semantics.md)
//                    v_n = sat(-lambda L^+ e)        with L^+ = (rho / f) n, saturated to |v_n| <= v_n,max
// where u is the commanded direction, t the ray's unit direction, s_cmd the commanded speed and lambda the gain
// (1/s). With the true interaction, e decays as exp(-lambda t) once out of saturation; with an estimated range
// rho_hat the rate is lambda rho_hat / rho, stable for any rho_hat > 0 in continuous time, and in discrete time for
// lambda T rho_hat / rho < 2 (T the vision period) — the gain default keeps lambda T below 0.3 at 30 Hz.

#include "control/types.h"

namespace visco::control {

/// Parameters of the law.
struct ServoConfig {
  double gain = 4.0;               // 1/s, lambda
  double focal_px = 800.0;         // pixels, f of the camera that measures d
  double nominal_range_m = 1.0;    // metres, rho when no position estimate is available
  double min_range_m = 0.05;       // metres, lower clamp of rho
  double max_normal_speed = 0.05;  // m/s, saturation of the correction v_n
};

/// Result of one evaluation.
struct ServoOutput {
  Vec2 velocity;           // m/s, world frame
  Vec2 tangential;         // m/s, v_t
  Vec2 normal;             // m/s, v_n
  bool saturated = false;  // v_n was clipped
};

/// The interaction matrix row L (px/m) for a ray of unit direction `direction` at range `range_m`. Real-time safe.
Vec2 InteractionRow(const ServoConfig& config, Vec2 direction, double range_m);

/// Evaluates the law. `direction`: the ray's unit direction (obstacle vertex towards camera); `command_direction`:
/// unit u; `speed`: m/s; `signed_distance_px`: d; `range_m`: rho estimate (<= 0 means use nominal). Real-time safe.
ServoOutput VisualComplianceLaw(const ServoConfig& config, Vec2 direction, Vec2 command_direction, double speed,
                                double signed_distance_px, double range_m);

}  // namespace visco::control

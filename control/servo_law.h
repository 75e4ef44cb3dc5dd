#pragma once
// The visual compliant motion law: keep a CM vertex on a VC line in the image while moving along it.
//
// Feature: s = the signed image distance d (ideal pixels) from the CM vertex's image to the VC line, positive on the
// side of the ray's left normal n (visual_event_t). Desired: s* = 0. The law needs the interaction row J (1x2,
// px/m): dd = J dq for a world displacement dq of the robot in the plane.
//
// Calibrated camera (ServoCamera, docs/control.md "The visual compliance law"): the tracked point is the top of
// the robot's vertical edge at the CM vertex, P = (p, h) in the world; its camera coordinates X = cRw P + ctw; its
// ideal pixel (u, v) = (u0 + px X1/X3, v0 + py X2/X3). The VC line is the image of the VC surface, the vertical plane
// through the camera centre C containing the ray's direction t; with N = cRw (n, 0) that plane is N . X = 0, so
// the line is l = (N1/px, N2/py, N3 - N1 u0/px - N2 v0/py) / |(N1/px, N2/py)| and d = l . (u, v, 1). Then
//   J = dd/dp = (1/X3) (l1 px, l2 py, -(l1 px x + l2 py y)) cRw[:, 0:2],   x = X1/X3, y = X2/X3,
// exact for any tilt. On the line J is parallel to n (moving along t stays in the VC plane); off it J . t != 0.
// Planar model (no calibration; the synthetic camera of `visco sim`): J = (f / rho) n, rho the planar range from the
// camera's foot point, f = focal_px.
//
// Law (image-based visual servoing, e = s - s*, the correction kept along n so that the motion along the ray is
// exactly the commanded one):
//   v = v_t + v_n,   v_t = s_cmd (u . t) t                   the commanded velocity's projection on the ray
//                    v_n = -((lambda e + J v_t) / (J . n)) n  saturated to |v_n| <= v_n,max
// so that J v = -lambda e: with the true J the error decays as exp(-lambda t) once out of saturation. In the planar
// model J v_t = 0 and v_n = -lambda (rho / f) e n, the law before the calibrated camera. An interaction off by a factor
// k (a wrong focal length or range) turns the rate into lambda / k; in discrete time lambda T / k < 2 is needed (T the
// vision period) — the gain default keeps lambda T below 0.3 at 30 Hz.

#include "control/types.h"

namespace visco::control {

/// The calibrated camera as the law needs it: intrinsics (ideal pixels), the world-to-camera transform and the
/// height of the tracked point above the motion plane. Fixed size, trivially copyable: computed at start-up
/// (LoadServoCamera, or from vision's calibration in the simulator) and read by the loop.
struct ServoCamera {
  bool valid = false;
  double px = 0.0, py = 0.0;  // focal lengths, pixels
  double u0 = 0.0, v0 = 0.0;  // principal point, pixels
  double cRw[3][3] = {};      // rotation world -> camera (ViSP camera frame: x right, y down, z forward)
  double ctw[3] = {};         // metres, the world origin in the camera frame
  double point_height_m = 0;  // metres, height of the tracked point above the plane (the robot's top, vision)
};

/// A ServoCamera from intrinsics and the camera pose in the world (wRc row-major, wtc). Not needed in the loop.
ServoCamera MakeServoCamera(double px, double py, double u0, double v0, const double (&wRc)[3][3],
                            const double (&wtc)[3], double point_height_m);

/// An image line a u + b v + c = 0 in ideal pixels, a^2 + b^2 = 1.
struct ImageLine {
  double a = 0.0, b = 0.0, c = 0.0;
};

/// The VC line of a ray of unit direction `direction` (obstacle vertex towards the camera's foot point), oriented so
/// that the ray's left normal side is positive. Real-time safe.
ImageLine VcImageLine(const ServoCamera& camera, Vec2 direction);

/// The signed distance (ideal pixels) to the VC line of the image of the tracked point above plane point `point`;
/// sets `*in_front` to whether the point is in front of the camera. Real-time safe.
double ModelSignedDistance(const ServoCamera& camera, Vec2 direction, Vec2 point, bool* in_front = nullptr);

/// Parameters of the law.
struct ServoConfig {
  double gain = 4.0;               // 1/s, lambda
  double focal_px = 800.0;         // pixels, f of the planar model (used only without `camera`)
  double nominal_range_m = 1.0;    // metres, rho when no position estimate is available (planar model)
  double min_range_m = 0.05;       // metres, lower clamp of rho, and of the point's depth with `camera`
  double max_normal_speed = 0.05;  // m/s, saturation of the correction v_n
  ServoCamera camera;              // the calibrated camera; when valid, J is exact (CameraInteractionRow)
};

/// Result of one evaluation.
struct ServoOutput {
  Vec2 velocity;            // m/s, world frame
  Vec2 tangential;          // m/s, v_t
  Vec2 normal;              // m/s, v_n
  bool saturated = false;   // v_n was clipped
  bool degenerate = false;  // J . n <= 0 (point behind the camera or at the horizon): no correction
};

/// The planar model's interaction row J = (f / rho) n (px/m) for a ray of unit direction `direction` at range
/// `range_m`. Real-time safe.
Vec2 InteractionRow(const ServoConfig& config, Vec2 direction, double range_m);

/// The calibrated camera's exact interaction row J (px/m): the derivative of the signed distance of the tracked point
/// above plane point `point` to the VC line of `direction`, with respect to the point's planar motion. The depth is
/// clamped below at `min_depth_m`; a point behind the camera gives {0, 0}. Real-time safe.
Vec2 CameraInteractionRow(const ServoCamera& camera, Vec2 direction, Vec2 point, double min_depth_m = 0.05);

/// The law with the planar model: `range_m` the rho estimate (<= 0 means use nominal). Real-time safe.
ServoOutput VisualComplianceLaw(const ServoConfig& config, Vec2 direction, Vec2 command_direction, double speed,
                                double signed_distance_px, double range_m);

/// The law with a given interaction row J (px/m) (CameraInteractionRow). Real-time safe.
ServoOutput VisualComplianceLaw(const ServoConfig& config, Vec2 direction, Vec2 command_direction, double speed,
                                double signed_distance_px, Vec2 interaction);

}  // namespace visco::control

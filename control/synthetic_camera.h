#pragma once
// Visual events computed from true positions: the planar pinhole model the servo law assumes (servo_law.h).
// For a CVC ray with workspace VC ray from obstacle vertex b to camera centre P (unit direction t, left normal n)
// and the CM vertex at a = q + cm_offset: range rho = -t.(a - P), signed distance d = f n.(a - P) / rho (pixels,
// positive on the left-normal side). Used by `visco sim` when no rendered camera is wanted and by tests.
// With UseCamera, the distances are those of a calibrated, tilted camera instead (ModelSignedDistance, servo_law.h:
// equal to vision's measurement, tests/control/servo_camera_test.cc).

#include <cstdint>
#include <random>

#include "control/servo_law.h"
#include "control/task.h"
#include "control/types.h"

namespace visco::control {

struct SyntheticCameraConfig {
  double focal_px = 800.0;       // pixels
  double on_line_band_px = 1.0;  // |d| within this is STATE_ON_LINE
  double noise_px = 0.0;         // 1-sigma Gaussian noise added to d
};

/// Computes one frame's events for every ray of `task` that has geometry, from the true reference point `q`.
/// `previous` holds the last frame (for the crossed flag and hysteresis); it is updated. Not real-time safe
/// (random numbers), allocation free.
class SyntheticCamera {
 public:
  SyntheticCamera(const Task& task, const SyntheticCameraConfig& config, std::uint64_t seed);
  /// Signed distance (px) of ray `ray`'s CM vertex at reference point `q`, and its range (m).
  double SignedDistance(int ray, Vec2 q, double* range_m = nullptr) const;
  /// Measures with the calibrated camera `camera` (the point at its height above the CM vertex) from now on.
  void UseCamera(const ServoCamera& camera) { camera_ = camera; }
  /// Fills `frame` (ray indices as in the task) for true position `q`, frame counter `seq`, capture time.
  void Observe(Vec2 q, std::int64_t seq, std::int64_t capture_ns, VisualFrame& frame);

 private:
  const Task& task_;
  SyntheticCameraConfig config_;
  ServoCamera camera_;  // valid: the calibrated camera's distances
  std::mt19937_64 rng_;
  std::int8_t last_state_[kMaxVisualObservations] = {};
};

}  // namespace visco::control

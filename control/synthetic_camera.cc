#include "control/synthetic_camera.h"

#include <cmath>

#include "visco/visual_event_t.hpp"

namespace visco::control {

SyntheticCamera::SyntheticCamera(const Task& task, const SyntheticCameraConfig& config, std::uint64_t seed)
    : task_(task), config_(config), rng_(seed) {}

double SyntheticCamera::SignedDistance(int ray, Vec2 q, double* range_m) const {
  const CvcRay& r = task_.rays[static_cast<std::size_t>(ray)];
  const Vec2 a = q + r.cm_offset - r.to;
  const double rho = -Dot(r.direction, a);
  if (range_m != nullptr) *range_m = rho;
  if (camera_.valid) {
    bool in_front = false;
    const double d = ModelSignedDistance(camera_, r.direction, q + r.cm_offset, &in_front);
    return in_front ? d : std::nan("");
  }
  if (rho <= 1e-9) return std::nan("");
  return config_.focal_px * Dot(LeftNormal(r.direction), a) / rho;
}

void SyntheticCamera::Observe(Vec2 q, std::int64_t seq, std::int64_t capture_ns, VisualFrame& frame) {
  frame.capture_ns = capture_ns;
  frame.frame_seq = seq;
  frame.count = 0;
  std::normal_distribution<double> noise(0.0, 1.0);
  const int n = static_cast<int>(task_.rays.size());
  for (int i = 0; i < n && frame.count < kMaxVisualObservations; ++i) {
    if (!task_.rays[static_cast<std::size_t>(i)].has_cm_offset) continue;
    VisualObservation& obs = frame.items[frame.count++];
    obs.ray = i;
    double d = SignedDistance(i, q);
    if (std::isnan(d)) {
      obs.state = visual_event_t::STATE_UNKNOWN;
      obs.signed_distance_px = 0;
      last_state_[i] = obs.state;
      continue;
    }
    if (config_.noise_px > 0) d += config_.noise_px * noise(rng_);
    obs.signed_distance_px = d;
    obs.stddev_px = config_.noise_px;
    obs.state = std::abs(d) <= config_.on_line_band_px
                    ? visual_event_t::STATE_ON_LINE
                    : (d > 0 ? visual_event_t::STATE_POSITIVE : visual_event_t::STATE_NEGATIVE);
    const std::int8_t last = last_state_[i];
    obs.crossed = last != visual_event_t::STATE_UNKNOWN && obs.state != last;
    last_state_[i] = obs.state;
  }
}

}  // namespace visco::control

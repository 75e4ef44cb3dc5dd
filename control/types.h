#pragma once
// Plain value types of the controller: what the real-time loop reads, computes and writes. All are trivially
// copyable so that they cross threads through visco::LatestValue and SpscQueue without allocation.
// Frames: world frame of docs/semantics.md (x right, y up, metres); positions are of the robot's reference point.
// Times are CLOCK_MONOTONIC nanoseconds (`*_ns`) unless named `utime` (microseconds since the epoch).

#include <cmath>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstring>

namespace visco::control {

/// A plane vector (metres or m/s). Plain struct, not Eigen, so that it stays trivially copyable.
struct Vec2 {
  double x = 0.0;
  double y = 0.0;
};
inline Vec2 operator+(Vec2 a, Vec2 b) { return {a.x + b.x, a.y + b.y}; }
inline Vec2 operator-(Vec2 a, Vec2 b) { return {a.x - b.x, a.y - b.y}; }
inline Vec2 operator*(double s, Vec2 a) { return {s * a.x, s * a.y}; }
inline double Dot(Vec2 a, Vec2 b) { return a.x * b.x + a.y * b.y; }
inline double Cross(Vec2 a, Vec2 b) { return a.x * b.y - a.y * b.x; }
inline double Norm(Vec2 a) { return std::hypot(a.x, a.y); }
/// The left normal (a rotated by +90 degrees).
inline Vec2 LeftNormal(Vec2 a) { return {-a.y, a.x}; }
inline Vec2 FromAngle(double theta) { return {std::cos(theta), std::sin(theta)}; }

/// Copies a C string into a fixed buffer, truncating, always terminated. Real-time safe.
template <std::size_t N>
void CopyText(char (&out)[N], const char* text) {
  const std::size_t n = strnlen(text, N - 1);
  std::memmove(out, text, n);
  out[n] = '\0';
}

/// printf into a fixed buffer, truncating. Real-time safe for numbers and strings (glibc's vsnprintf does not
/// allocate for these; the no-allocation test covers the messages the loop formats).
__attribute__((format(printf, 3, 4))) inline void FormatTextN(char* out, std::size_t size, const char* format, ...) {
  va_list args;
  va_start(args, format);
  std::vsnprintf(out, size, format, args);
  va_end(args);
}
#define VISCO_FORMAT_TEXT(buffer, ...) ::visco::control::FormatTextN((buffer), sizeof(buffer), __VA_ARGS__)

/// Driver feedback as the controller sees it (from robot_status_t or the CAN status frame).
struct RobotStatus {
  std::int64_t receive_ns = 0;  // monotonic time the controller received it
  std::int64_t utime = 0;       // driver's measurement time, microseconds since the epoch
  std::int32_t seq = 0;
  std::int32_t command_seq = 0;
  Vec2 position;  // metres, reference point (odometry)
  Vec2 velocity;  // m/s, actual velocity
  bool contact = false;
  Vec2 contact_force;           // newtons
  std::int32_t state = 0;       // robot_status_t::STATE_*
  std::int32_t fault_bits = 0;  // robot_status_t::FAULT_*
};

/// Command to the driver (velocity_command_t / the CAN command frame).
struct RobotCommand {
  std::int64_t utime = 0;  // controller time, microseconds since the epoch
  std::int32_t seq = 0;
  Vec2 velocity;  // m/s, world frame
  bool estop = false;
  bool reset = false;
  bool quick_stop = false;  // the executor stopped: the driver quick-stops at once (not only its watchdog, later)
};

/// Vision's position estimate of the reference point (robot_estimate_t).
struct PositionEstimate {
  std::int64_t capture_ns = 0;  // monotonic time of the frame's capture (converted from its utime)
  std::int64_t frame_seq = -1;  // image_t.seq of that frame (-1: unknown)
  bool valid = false;
  Vec2 position;        // metres
  double stddev = 0.0;  // metres
};

/// Capacity of one visual frame; strategies with more CVC rays are rejected at setup.
inline constexpr int kMaxVisualObservations = 32;

/// One CM-vertex/VC-line relation in one frame (visual_event_t), with the ray resolved to an index into the
/// task's ray table.
struct VisualObservation {
  std::int32_t ray = -1;  // index into Task::rays
  std::int8_t state = 0;  // visual_event_t::STATE_*
  bool crossed = false;
  double signed_distance_px = 0.0;  // pixels, positive on the ray's left-normal side
  double stddev_px = 0.0;
};

/// All observations of one frame (visual_events_t).
struct VisualFrame {
  std::int64_t capture_ns = 0;  // monotonic time of the frame's capture
  std::int64_t frame_seq = 0;
  std::int32_t count = 0;
  VisualObservation items[kMaxVisualObservations];
};

}  // namespace visco::control

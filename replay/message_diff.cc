#include "replay/message_diff.h"

#include <cstdio>
#include <cstring>
#include <string_view>
#include <type_traits>

#include "lcmtypes/channels.h"
#include "replay/safe_decode.h"
#include "visco/fault_t.hpp"
#include "visco/object_poses_t.hpp"
#include "visco/robot_estimate_t.hpp"
#include "visco/tag_detections_t.hpp"
#include "visco/visual_events_t.hpp"

namespace visco::replay {
namespace {

class Differ {
 public:
  std::optional<FieldDifference> result;

  template <class T>
  void Field(const std::string& name, const T& a, const T& b) {
    if (result || Same(a, b)) return;
    result = FieldDifference{name, Text(a), Text(b)};
  }
  template <class T, std::size_t N>
  void Field(const std::string& name, const T (&a)[N], const T (&b)[N]) {
    for (std::size_t i = 0; i < N; ++i) Field(name + "[" + std::to_string(i) + "]", a[i], b[i]);
  }

 private:
  static bool Same(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }  // bit for bit
  template <class T>
  static bool Same(const T& a, const T& b) {
    return a == b;
  }
  static std::string Text(double v) {
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%.17g", v);
    return buffer;
  }
  static std::string Text(const std::string& v) { return "\"" + v + "\""; }
  template <class T>
  static std::string Text(const T& v) {
    return std::to_string(static_cast<long long>(v));
  }
};

void Compare(Differ& d, const std::string& p, const tag_detection_t& a, const tag_detection_t& b) {
  d.Field(p + "utime", a.utime, b.utime);
  d.Field(p + "family", a.family, b.family);
  d.Field(p + "id", a.id, b.id);
  d.Field(p + "corners", a.corners, b.corners);
  d.Field(p + "decision_margin", a.decision_margin, b.decision_margin);
  d.Field(p + "hamming", a.hamming, b.hamming);
  d.Field(p + "position", a.position, b.position);
  d.Field(p + "orientation", a.orientation, b.orientation);
  d.Field(p + "reprojection_error", a.reprojection_error, b.reprojection_error);
  d.Field(p + "tracked", a.tracked, b.tracked);
}

void Compare(Differ& d, const tag_detections_t& a, const tag_detections_t& b) {
  d.Field("frame_utime", a.frame_utime, b.frame_utime);
  d.Field("frame_seq", a.frame_seq, b.frame_seq);
  d.Field("camera", a.camera, b.camera);
  d.Field("pixel_digest", a.pixel_digest, b.pixel_digest);
  d.Field("num_detections", a.num_detections, b.num_detections);
  for (std::size_t i = 0; i < a.detections.size() && i < b.detections.size(); ++i) {
    Compare(d, "detections[" + std::to_string(i) + "].", a.detections[i], b.detections[i]);
  }
}

void Compare(Differ& d, const std::string& p, const object_pose_t& a, const object_pose_t& b) {
  d.Field(p + "utime", a.utime, b.utime);
  d.Field(p + "object_id", a.object_id, b.object_id);
  d.Field(p + "position", a.position, b.position);
  d.Field(p + "orientation", a.orientation, b.orientation);
  d.Field(p + "position_stddev", a.position_stddev, b.position_stddev);
  d.Field(p + "orientation_stddev", a.orientation_stddev, b.orientation_stddev);
  d.Field(p + "contact_refined", a.contact_refined, b.contact_refined);
  d.Field(p + "pose_decision", a.pose_decision, b.pose_decision);
  d.Field(p + "ambiguous", a.ambiguous, b.ambiguous);
  d.Field(p + "tags_used", a.tags_used, b.tags_used);
  d.Field(p + "rms_error_px", a.rms_error_px, b.rms_error_px);
  d.Field(p + "model_tracked", a.model_tracked, b.model_tracked);
}

void Compare(Differ& d, const object_poses_t& a, const object_poses_t& b) {
  d.Field("frame_utime", a.frame_utime, b.frame_utime);
  d.Field("num_poses", a.num_poses, b.num_poses);
  for (std::size_t i = 0; i < a.poses.size() && i < b.poses.size(); ++i) {
    Compare(d, "poses[" + std::to_string(i) + "].", a.poses[i], b.poses[i]);
  }
}

void Compare(Differ& d, const robot_estimate_t& a, const robot_estimate_t& b) {
  d.Field("utime", a.utime, b.utime);
  d.Field("frame_seq", a.frame_seq, b.frame_seq);
  d.Field("valid", a.valid, b.valid);
  d.Field("position", a.position, b.position);
  d.Field("position_stddev", a.position_stddev, b.position_stddev);
  d.Field("heading", a.heading, b.heading);
}

void Compare(Differ& d, const visual_events_t& a, const visual_events_t& b) {
  d.Field("frame_utime", a.frame_utime, b.frame_utime);
  d.Field("frame_seq", a.frame_seq, b.frame_seq);
  d.Field("num_events", a.num_events, b.num_events);
  for (std::size_t i = 0; i < a.events.size() && i < b.events.size(); ++i) {
    const std::string p = "events[" + std::to_string(i) + "].";
    const visual_event_t& x = a.events[i];
    const visual_event_t& y = b.events[i];
    d.Field(p + "utime", x.utime, y.utime);
    d.Field(p + "cvc_ray", x.cvc_ray, y.cvc_ray);
    d.Field(p + "cm_vertex", x.cm_vertex, y.cm_vertex);
    d.Field(p + "signed_distance_px", x.signed_distance_px, y.signed_distance_px);
    d.Field(p + "distance_stddev_px", x.distance_stddev_px, y.distance_stddev_px);
    d.Field(p + "state", x.state, y.state);
    d.Field(p + "crossed", x.crossed, y.crossed);
  }
}

void Compare(Differ& d, const fault_t& a, const fault_t& b) {
  d.Field("utime", a.utime, b.utime);
  d.Field("source", a.source, b.source);
  d.Field("code", a.code, b.code);
  d.Field("severity", a.severity, b.severity);
  d.Field("robot_stopped", a.robot_stopped, b.robot_stopped);
  d.Field("cleared", a.cleared, b.cleared);
  d.Field("message", a.message, b.message);
  d.Field("emcy_code", a.emcy_code, b.emcy_code);
  d.Field("fault_bits", a.fault_bits, b.fault_bits);
}

template <class M>
std::optional<FieldDifference> Decoded(std::span<const std::uint8_t> logged, std::span<const std::uint8_t> replayed) {
  M a, b;
  const bool a_ok = SafeDecode(logged, a);
  const bool b_ok = SafeDecode(replayed, b);
  if (!a_ok || !b_ok) {
    return FieldDifference{"(message)", a_ok ? "decodes" : "does not decode as " + std::string(M::getTypeName()),
                           b_ok ? "decodes" : "does not decode as " + std::string(M::getTypeName())};
  }
  Differ d;
  Compare(d, a, b);
  return d.result;
}

}  // namespace

bool HasIgnoredTimingFields(const std::string& channel) {
  return channel == channels::kTagDetections || channel == channels::kObjectPoses || channel == channels::kVisualEvents;
}

std::optional<FieldDifference> CompareMessages(const std::string& channel, std::span<const std::uint8_t> logged,
                                               std::span<const std::uint8_t> replayed) {
  if (channel == channels::kTagDetections) return Decoded<tag_detections_t>(logged, replayed);
  if (channel == channels::kObjectPoses) return Decoded<object_poses_t>(logged, replayed);
  if (channel == channels::kRobotEstimate) return Decoded<robot_estimate_t>(logged, replayed);
  if (channel == channels::kVisualEvents) return Decoded<visual_events_t>(logged, replayed);
  if (channel == channels::kFault) return Decoded<fault_t>(logged, replayed);
  if (logged.size() == replayed.size() && std::memcmp(logged.data(), replayed.data(), logged.size()) == 0) {
    return std::nullopt;
  }
  return FieldDifference{"(bytes)", std::to_string(logged.size()) + " bytes",
                         std::to_string(replayed.size()) + " bytes, different"};
}

}  // namespace visco::replay

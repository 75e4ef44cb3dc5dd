#pragma once
// Field-by-field comparison of the messages vision produces, for `visco replay --check`. Numbers are compared bit
// for bit (a replay on the same machine and build must reproduce them exactly); the fields that only say when the
// live process happened to finish a frame are left out (they measure that machine's load, not the result):
// tag_detections_t.utime and .processing_time_s, object_poses_t.utime, visual_events_t.utime and .latency_s.

#include <cstdint>
#include <optional>
#include <span>
#include <string>

namespace visco::replay {

struct FieldDifference {
  std::string field;     // e.g. "detections[1].corners[2][0]"
  std::string logged;    // the value in the log
  std::string replayed;  // the value the replay produced
};

/// Decodes both messages as the type that `channel` carries and compares them. Returns the first differing field, or
/// nothing when they are identical. A message that does not decode is a difference of the field "(message)".
/// Channels without a known comparison are compared byte for byte.
std::optional<FieldDifference> CompareMessages(const std::string& channel, std::span<const std::uint8_t> logged,
                                               std::span<const std::uint8_t> replayed);

/// Whether the comparison of `channel` leaves out wall-clock fields (see above).
bool HasIgnoredTimingFields(const std::string& channel);

}  // namespace visco::replay

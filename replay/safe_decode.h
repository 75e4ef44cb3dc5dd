#pragma once
// Decoding a logged message that may be damaged. lcm-gen's C++ decode checks string lengths against the buffer but
// sizes a variable-length array from its count field before checking it: a damaged count (negative, or 2^30) throws
// std::length_error or allocates gigabytes. So the count fields of the types with arrays are checked against the
// bytes that follow them first (each element needs at least its minimal encoded size), and decode exceptions are
// caught. Not real-time safe.

#include <cstddef>
#include <cstdint>
#include <exception>
#include <span>

#include "visco/camera_info_t.hpp"
#include "visco/controller_cycle_t.hpp"
#include "visco/image_t.hpp"
#include "visco/object_poses_t.hpp"
#include "visco/tag_detections_t.hpp"
#include "visco/visual_events_t.hpp"

namespace visco::replay {
namespace safe_decode_detail {

// Walks the encoded fields in declaration order (after the 8-byte fingerprint).
class Cursor {
 public:
  explicit Cursor(std::span<const std::uint8_t> bytes) : bytes_(bytes) { Skip(8); }
  void Skip(std::size_t n) {
    if (!ok_ || bytes_.size() - pos_ < n) {
      ok_ = false;
      return;
    }
    pos_ += n;
  }
  std::int32_t Int32() {
    if (!ok_ || bytes_.size() - pos_ < 4) {
      ok_ = false;
      return 0;
    }
    const std::uint8_t* p = bytes_.data() + pos_;
    pos_ += 4;
    return static_cast<std::int32_t>((std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) |
                                     (std::uint32_t{p[2]} << 8) | std::uint32_t{p[3]});
  }
  void String() {
    const std::int32_t n = Int32();
    if (n < 0) ok_ = false;
    Skip(static_cast<std::size_t>(n));
  }
  // A count of elements of at least `element_bytes` each that must fit in the rest of the message.
  void Count(std::size_t element_bytes) {
    const std::int32_t n = Int32();
    if (n < 0 || static_cast<std::size_t>(n) > (bytes_.size() - pos_) / element_bytes) ok_ = false;
  }
  bool ok() const { return ok_; }

 private:
  std::span<const std::uint8_t> bytes_;
  std::size_t pos_ = 0;
  bool ok_ = true;
};

inline bool CountsFit(std::span<const std::uint8_t> b, const image_t*) {
  Cursor c(b);
  c.Skip(16);  // utime, seq
  c.String();  // camera
  c.Skip(16);  // width, height, row_stride, pixel_format
  c.Count(1);  // size -> data
  return c.ok();
}
inline bool CountsFit(std::span<const std::uint8_t> b, const camera_info_t*) {
  Cursor c(b);
  c.Skip(8);   // utime
  c.String();  // camera
  c.String();  // source
  c.Skip(41);  // width, height, px, py, u0, v0, distortion_model
  c.Count(8);  // num_distortion -> distortion
  return c.ok();
}
inline bool CountsFit(std::span<const std::uint8_t> b, const tag_detections_t*) {
  Cursor c(b);
  c.Skip(24);                                         // utime, frame_utime, frame_seq
  c.String();                                         // camera
  c.Skip(16);                                         // processing_time_s, pixel_digest
  c.Count(8 + 5 + 4 + 64 + 8 + 4 + 24 + 32 + 8 + 1);  // tag_detection_t, its family string at least 1 byte
  return c.ok();
}
inline bool CountsFit(std::span<const std::uint8_t> b, const object_poses_t*) {
  Cursor c(b);
  c.Skip(16);                                                // utime, frame_utime
  c.Count(8 + 5 + 24 + 32 + 8 + 8 + 1 + 1 + 1 + 4 + 8 + 1);  // object_pose_t
  return c.ok();
}
inline bool CountsFit(std::span<const std::uint8_t> b, const visual_events_t*) {
  Cursor c(b);
  c.Skip(32);                          // utime, frame_utime, frame_seq, latency_s
  c.Count(8 + 5 + 4 + 8 + 8 + 1 + 1);  // visual_event_t
  return c.ok();
}
inline bool CountsFit(std::span<const std::uint8_t> b, const controller_cycle_t*) {
  Cursor c(b);
  c.Skip(119);                 // utime .. link_fault_code (controller_cycle_t.lcm)
  c.String();                  // link_fault
  c.Skip(17);                  // have_frame, frame_capture_ns, frame_seq
  c.Count(4 + 1 + 1 + 8 + 8);  // ray, state, crossed, signed_distance_px, stddev_px
  return c.ok();
}
inline bool CountsFit(std::span<const std::uint8_t>, const void*) { return true; }  // no variable-length array

}  // namespace safe_decode_detail

/// Decodes `bytes` as M; false if they are not a valid M (wrong type, damaged, truncated). Never throws.
template <class M>
bool SafeDecode(std::span<const std::uint8_t> bytes, M& message) {
  if (!safe_decode_detail::CountsFit(bytes, static_cast<const M*>(nullptr))) return false;
  try {
    return message.decode(bytes.data(), 0, static_cast<int>(bytes.size())) >= 0;
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace visco::replay

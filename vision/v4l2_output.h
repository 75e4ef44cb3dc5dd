#pragma once
// A V4L2 video *output* device written directly: grey pictures go out as frames, as a simulated world's camera
// image would leave a camera. With vivid's output looped back to its capture (docs/camera.md), what is written here
// arrives through the real V4L2 capture path (`visco capture`, `visco track --v4l2`). Buffers are mapped once; a
// write copies the picture into a free buffer and queues it (nothing allocated per frame). vivid keeps showing the
// last frame queued until the next one arrives, so frames can be written at any rate up to the device's.
// No V4L2 header here.

#include <cstdint>
#include <memory>
#include <string>

#include "vision/image.h"

namespace visco::vision {

struct V4l2OutputOptions {
  std::string device = "/dev/video1";
  int output = -1;                    ///< VIDIOC_S_OUTPUT index; -1: the device's current output
  int width = 0, height = 0;          ///< pixels (required: the pictures' size)
  std::string pixel_format = "GREY";  ///< "GREY" (the picture as is) or "YUYV" (its luma, neutral chroma)
  int buffers = 4;                    ///< mmap buffers (2..32)
};

class V4l2Output {
 public:
  /// Opens the device, selects the output, sets the format and size, maps the buffers. Streaming starts with the
  /// first frame written. @throws InputError(device, object, ...) (exit 2): no such device, not a video output
  /// device, an output index, pixel format or size it cannot take (the message says what it offers).
  explicit V4l2Output(const V4l2OutputOptions& options);
  ~V4l2Output();
  V4l2Output(const V4l2Output&) = delete;
  V4l2Output& operator=(const V4l2Output&) = delete;

  /// Writes one picture of the configured size, waiting up to `timeout_ms` for a free buffer. Returns false with
  /// `error` (naming the device) when the picture's size is wrong, no buffer came free in time or the driver refused.
  bool Write(const GrayImageView& picture, int timeout_ms, std::string& error);

  /// Frames queued so far.
  std::int64_t written() const;
  const std::string& device() const;
  /// The device's name (VIDIOC_QUERYCAP) and the fourcc it takes.
  const std::string& card() const;
  const std::string& fourcc() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace visco::vision

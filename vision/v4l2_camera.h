#pragma once
// A live camera through the Linux video interface (V4L2) used directly: the driver's frame sequence number, its
// buffer error flag and its capture timestamps are what tell lost, damaged and late frames apart, and the user-space
// grabbers of OpenCV and ViSP hide them. Always the newest frame (older ones waiting in the queue are skipped and
// reported), buffers mapped once (nothing allocated per frame), faults instead of exceptions once streaming, and a
// device that disappears is reopened when it comes back. No V4L2 or OpenCV header here.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "vision/image.h"

namespace visco::vision {

/// What to ask of the device. Zero or empty: keep what the device has.
struct V4l2Options {
  std::string device = "/dev/video0";
  int input = -1;             ///< VIDIOC_S_INPUT index; -1: the device's current input
  int width = 0, height = 0;  ///< pixels
  /// "GREY", "YUYV" or "MJPG" (V4L2 fourcc); empty: the first of these the device offers.
  std::string pixel_format;
  double fps = 0;         ///< frames per second (VIDIOC_S_PARM)
  int exposure = -1;      ///< manual exposure, the device's unit (V4L2_CID_EXPOSURE_ABSOLUTE: 100 µs); -1: as is
  int gain = -1;          ///< manual gain, the device's unit (V4L2_CID_GAIN); -1: as is
  int buffers = 4;        ///< mmap buffers in the driver's queue (2..32)
  int timeout_ms = 1000;  ///< no frame for this long: a time-out fault (and again each further time-out)
  int reopen_interval_ms = 500;  ///< while the device is gone: how often to try to open it again
};

/// The pixel formats the camera delivers (V4L2_PIX_FMT_GREY, _YUYV, _MJPEG).
enum class V4l2PixelFormat { kGrey, kYuyv, kMjpeg };

/// What the device actually streams after negotiation.
struct V4l2Stream {
  std::string card;  ///< the device's name (VIDIOC_QUERYCAP)
  std::string driver;
  int input = 0;
  std::string input_name;
  int width = 0, height = 0;
  int bytes_per_line = 0;  ///< 0 for compressed formats
  V4l2PixelFormat format = V4l2PixelFormat::kGrey;
  std::string fourcc;
  double fps = 0;  ///< the device's frame interval as a rate (0: it does not say)
  int buffers = 0;
};

/// One frame, pointing into the driver's mapped buffer: valid until the next Grab.
struct V4l2Frame {
  const std::uint8_t* data = nullptr;
  std::size_t bytes = 0;   ///< bytes used in the buffer
  std::int64_t seq = 0;    ///< the driver's sequence number (extended past 32 bits); restarts at 0 after a reopen
  std::int64_t utime = 0;  ///< capture time (buffer timestamp, CLOCK_MONOTONIC) mapped to microseconds since the epoch
  std::int64_t monotonic_us = 0;           ///< the buffer timestamp itself
  std::int64_t dequeued_monotonic_us = 0;  ///< when Grab took it from the driver (CLOCK_MONOTONIC)
};

/// A stream fault, with the frame numbers it concerns.
struct V4l2Fault {
  enum class Kind {
    kDropped,      ///< the driver's sequence jumped: frames first_seq..last_seq never arrived
    kSkipped,      ///< frames first_seq..last_seq arrived but a newer one was waiting: not delivered (stale)
    kBufferError,  ///< frame first_seq came with V4L2_BUF_FLAG_ERROR (damaged data): not delivered
    kRepeated,     ///< a second frame numbered first_seq (or one numbered below the last): the older copy not delivered
    kTimeout,      ///< no frame for timeout_ms after frame first_seq (-1: none yet)
    kDisconnected,  ///< the device went away after frame first_seq; it is closed and reopened when it returns
    kReopened,      ///< the device is back and streaming again (its sequence numbers restart)
  };
  Kind kind = Kind::kDropped;
  std::int64_t first_seq = -1, last_seq = -1;
  std::int64_t utime = 0;  ///< when it was detected, microseconds since the epoch
  std::string message;     ///< in words, naming the device and the frames
};

/// One camera. Not thread-safe.
class V4l2Camera {
 public:
  /// Opens the device, negotiates input, format, size, rate, exposure and gain, maps the buffers and starts
  /// streaming. @throws InputError(device, object, ...) for bad input (exit 2): no such device, not a video capture
  /// device, an input, pixel format, size, rate or control value it cannot give (the message lists what it offers).
  explicit V4l2Camera(const V4l2Options& options);
  ~V4l2Camera();
  V4l2Camera(const V4l2Camera&) = delete;
  V4l2Camera& operator=(const V4l2Camera&) = delete;

  enum class Status { kFrame, kFault, kNothing };
  /// Waits up to `timeout_ms` for the newest frame. kFrame: `frame` is set. kFault: `fault` says what happened
  /// (faults are reported before the frame that revealed them; call again for it). kNothing: no frame yet.
  Status Grab(int timeout_ms, V4l2Frame& frame, V4l2Fault& fault);

  const V4l2Stream& stream() const;
  bool connected() const;
  /// Counters since the start: frames delivered, dropped (by the driver), skipped (stale), with the error flag.
  std::int64_t delivered() const;
  std::int64_t dropped() const;
  std::int64_t skipped() const;
  std::int64_t errors() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Converts a frame of `stream` to 8-bit grey into `out` (reusing its storage: no allocation once sized): GREY is
/// copied, YUYV gives its luma, MJPEG is decoded. Returns false with `error` for a frame that cannot be converted
/// (short buffer, undecodable JPEG, decoded size not the stream's).
bool V4l2FrameToGray(const V4l2Stream& stream, const V4l2Frame& frame, GrayImage& out, std::string& error);

class FrameSource;
/// The camera as a frame source of the vision pipeline (vision/pipeline.h): grey frames named `camera_name`; each
/// fault is an unusable frame (SourceStatus::kBadFrame) with the fault's message. @throws InputError as V4l2Camera.
std::unique_ptr<FrameSource> MakeV4l2Source(const V4l2Options& options, const std::string& camera_name);

/// The fourcc names of a V4l2PixelFormat.
const char* V4l2FourccName(V4l2PixelFormat format);

}  // namespace visco::vision

#include "vision/v4l2_camera.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "common/error.h"
#include "vision/pipeline.h"
#include "vision/v4l2_ioctl.h"

namespace visco::vision {
namespace {

using internal::FourccText;
using internal::Xioctl;

std::int64_t ClockUs(clockid_t clock) {
  timespec ts{};
  clock_gettime(clock, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
}

// The system clock's offset from the monotonic one, from a read of the system clock between two of the monotonic
// clock: of three tries, the one with the shortest bracket (a thread preempted between two reads, milliseconds on a
// loaded or emulated CPU, would put that time into the offset). `mono` is the first monotonic read of that try.
std::int64_t RealMinusMonotonicUs(std::int64_t& mono) {
  std::int64_t best_offset = 0, best_bracket = std::numeric_limits<std::int64_t>::max();
  for (int i = 0; i < 3; ++i) {
    const std::int64_t before = ClockUs(CLOCK_MONOTONIC);
    const std::int64_t real = ClockUs(CLOCK_REALTIME);
    const std::int64_t after = ClockUs(CLOCK_MONOTONIC);
    if (after - before < best_bracket) {
      best_bracket = after - before;
      best_offset = real - (before + after) / 2;
      mono = before;
    }
    if (best_bracket <= 20) break;  // a read without a preemption
  }
  return best_offset;
}

std::uint32_t FourccOf(V4l2PixelFormat f) {
  switch (f) {
    case V4l2PixelFormat::kGrey:
      return V4L2_PIX_FMT_GREY;
    case V4l2PixelFormat::kYuyv:
      return V4L2_PIX_FMT_YUYV;
    case V4l2PixelFormat::kMjpeg:
      return V4L2_PIX_FMT_MJPEG;
  }
  return 0;
}

std::string Rate(double fps) {
  std::ostringstream s;
  s.precision(4);
  s << fps;
  return s.str();
}

double FpsOf(const v4l2_fract& interval) {
  return interval.numerator == 0 ? 0 : static_cast<double>(interval.denominator) / interval.numerator;
}

// What a device offers for one pixel format, as text for error messages: "640x480 (30, 15 fps), 1280x720 (...)".
std::string SizesAndRates(int fd, std::uint32_t fourcc) {
  std::string out;
  v4l2_frmsizeenum size{};
  size.pixel_format = fourcc;
  for (size.index = 0; Xioctl(fd, VIDIOC_ENUM_FRAMESIZES, &size) == 0; ++size.index) {
    if (!out.empty()) out += ", ";
    if (size.type != V4L2_FRMSIZE_TYPE_DISCRETE) {
      const auto& s = size.stepwise;
      out += std::to_string(s.min_width) + "x" + std::to_string(s.min_height) + " to " + std::to_string(s.max_width) +
             "x" + std::to_string(s.max_height) + " in steps of " + std::to_string(s.step_width) + "x" +
             std::to_string(s.step_height);
      break;
    }
    out += std::to_string(size.discrete.width) + "x" + std::to_string(size.discrete.height);
    v4l2_frmivalenum ival{};
    ival.pixel_format = fourcc;
    ival.width = size.discrete.width;
    ival.height = size.discrete.height;
    std::string rates;
    for (ival.index = 0; Xioctl(fd, VIDIOC_ENUM_FRAMEINTERVALS, &ival) == 0; ++ival.index) {
      if (ival.type != V4L2_FRMIVAL_TYPE_DISCRETE) {
        rates = Rate(FpsOf(ival.stepwise.max)) + " to " + Rate(FpsOf(ival.stepwise.min));
        break;
      }
      rates += (rates.empty() ? "" : ", ") + Rate(FpsOf(ival.discrete));
    }
    if (!rates.empty()) out += " (" + rates + " fps)";
  }
  return out;
}

}  // namespace

const char* V4l2FourccName(V4l2PixelFormat format) {
  switch (format) {
    case V4l2PixelFormat::kGrey:
      return "GREY";
    case V4l2PixelFormat::kYuyv:
      return "YUYV";
    case V4l2PixelFormat::kMjpeg:
      return "MJPG";
  }
  return "?";
}

struct V4l2Camera::Impl {
  V4l2Options options;
  V4l2Stream stream;
  int fd = -1;
  struct Buffer {
    void* start = MAP_FAILED;
    std::size_t length = 0;
  };
  std::vector<Buffer> buffers;
  int held = -1;  // the buffer handed out by the last Grab, queued again at the next
  bool streaming = false;
  // Sequence numbers: the driver's are 32 bits; `wraps` extends them.
  std::int64_t last_seq = -1;
  std::uint32_t last_raw = 0;
  std::int64_t wraps = 0;
  std::int64_t last_frame_mono = 0;  // when the last frame (or the stream's start) was seen, CLOCK_MONOTONIC us
  int timeouts_reported = 0;         // time-outs reported since the last frame
  std::int64_t next_reopen_mono = 0;
  std::int64_t delivered = 0, dropped = 0, skipped = 0, errors = 0;
  // Faults found while draining the queue, reported before the frame that revealed them.
  static constexpr int kMaxPending = 8;
  V4l2Fault pending[kMaxPending];
  int pending_count = 0, pending_read = 0;
  v4l2_buffer ready{};  // the newest good buffer of the last drain, if have_ready
  std::int64_t ready_seq = 0;
  bool have_ready = false;

  // Opening and negotiation, with bad input as InputError (first open) or a failure text (reopen).
  void Open();
  void Close();
  [[noreturn]] void Bad(const std::string& object, const std::string& what) const {
    throw InputError(options.device, object, what);
  }
  void SelectInput();
  void SelectFormat();
  void SelectRate();
  void SetControl(std::uint32_t id, const char* name, int value);
  void StartStreaming();

  void Push(V4l2Fault::Kind kind, std::int64_t first, std::int64_t last, std::string message) {
    if (pending_count == kMaxPending) return;  // more faults in one drain than fit: the counters still count them
    V4l2Fault& f = pending[pending_count++];
    f.kind = kind;
    f.first_seq = first;
    f.last_seq = last;
    f.utime = ClockUs(CLOCK_REALTIME);
    f.message = std::move(message);
  }
  std::int64_t Extend(std::uint32_t raw) {
    if (last_seq >= 0 && raw < last_raw && last_raw - raw > 0x80000000u) ++wraps;
    last_raw = raw;
    return wraps * (std::int64_t{1} << 32) + raw;
  }
  void Requeue(v4l2_buffer& b) {
    if (Xioctl(fd, VIDIOC_QBUF, &b) != 0) Disconnected(errno);
  }
  void Disconnected(int err);
  bool Drain();
  std::string Frames(std::int64_t a, std::int64_t b) const {
    return a == b ? "frame " + std::to_string(a) : "frames " + std::to_string(a) + ".." + std::to_string(b);
  }
};

void V4l2Camera::Impl::Open() {
  const std::string& dev = options.device;
  struct stat st {};
  if (stat(dev.c_str(), &st) != 0) Bad("", "no such device (" + std::string(std::strerror(errno)) + ")");
  if (!S_ISCHR(st.st_mode)) Bad("", "not a device (a V4L2 capture device such as /dev/video0 is needed)");
  fd = open(dev.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) Bad("", "cannot open: " + std::string(std::strerror(errno)));
  v4l2_capability cap{};
  if (Xioctl(fd, VIDIOC_QUERYCAP, &cap) != 0) Bad("", "not a V4L2 device (VIDIOC_QUERYCAP failed)");
  const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? cap.device_caps : cap.capabilities;
  stream.card = reinterpret_cast<const char*>(cap.card);
  stream.driver = reinterpret_cast<const char*>(cap.driver);
  if ((caps & V4L2_CAP_VIDEO_CAPTURE) == 0) {
    std::string is = (caps & V4L2_CAP_VIDEO_OUTPUT) != 0 ? "a video output" : "no single-planar video capture";
    Bad("", "not a video capture device ('" + stream.card + "' is " + is + " device)");
  }
  if ((caps & V4L2_CAP_STREAMING) == 0) Bad("", "'" + stream.card + "' does not stream (no V4L2_CAP_STREAMING)");
  SelectInput();
  SelectFormat();
  SelectRate();
  if (options.gain >= 0) SetControl(V4L2_CID_GAIN, "gain", options.gain);
  if (options.exposure >= 0) SetControl(V4L2_CID_EXPOSURE_ABSOLUTE, "exposure", options.exposure);
  StartStreaming();
}

void V4l2Camera::Impl::SelectInput() {
  std::string inputs;
  v4l2_input in{};
  for (in.index = 0; Xioctl(fd, VIDIOC_ENUMINPUT, &in) == 0; ++in.index) {
    inputs +=
        (inputs.empty() ? "" : ", ") + std::to_string(in.index) + " '" + reinterpret_cast<const char*>(in.name) + "'";
  }
  if (options.input >= 0) {
    int index = options.input;
    if (Xioctl(fd, VIDIOC_S_INPUT, &index) != 0) {
      Bad("input " + std::to_string(options.input),
          "cannot be selected (" + std::string(std::strerror(errno)) +
              "); the device's inputs: " + (inputs.empty() ? "none listed" : inputs));
    }
  }
  int current = 0;
  stream.input = Xioctl(fd, VIDIOC_G_INPUT, &current) == 0 ? current : 0;
  v4l2_input now{};
  now.index = static_cast<std::uint32_t>(stream.input);
  stream.input_name = Xioctl(fd, VIDIOC_ENUMINPUT, &now) == 0 ? reinterpret_cast<const char*>(now.name) : "";
}

void V4l2Camera::Impl::SelectFormat() {
  // What the device offers.
  std::vector<std::uint32_t> offered;
  std::string offered_text;
  v4l2_fmtdesc desc{};
  desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  for (desc.index = 0; Xioctl(fd, VIDIOC_ENUM_FMT, &desc) == 0; ++desc.index) {
    offered.push_back(desc.pixelformat);
    offered_text += (offered_text.empty() ? "" : ", ") + FourccText(desc.pixelformat);
  }
  const V4l2PixelFormat supported[] = {V4l2PixelFormat::kGrey, V4l2PixelFormat::kYuyv, V4l2PixelFormat::kMjpeg};
  auto offers = [&](std::uint32_t f) {
    for (std::uint32_t o : offered) {
      if (o == f) return true;
    }
    return false;
  };
  bool found = false;
  if (options.pixel_format.empty()) {
    for (V4l2PixelFormat f : supported) {
      if (offers(FourccOf(f))) {
        stream.format = f;
        found = true;
        break;
      }
    }
    if (!found) {
      Bad("pixel format", "the device offers none of GREY, YUYV, MJPG (it offers: " + offered_text + ")");
    }
  } else {
    for (V4l2PixelFormat f : supported) {
      if (options.pixel_format == V4l2FourccName(f) ||
          (options.pixel_format == "MJPEG" && f == V4l2PixelFormat::kMjpeg)) {
        stream.format = f;
        found = true;
      }
    }
    if (!found) Bad("pixel format", "'" + options.pixel_format + "' is not one visco reads (GREY, YUYV, MJPG)");
    if (!offers(FourccOf(stream.format))) {
      Bad("pixel format", "the device does not offer " + std::string(V4l2FourccName(stream.format)) +
                              " (it offers: " + offered_text + ")");
    }
  }
  const std::uint32_t fourcc = FourccOf(stream.format);
  stream.fourcc = V4l2FourccName(stream.format);
  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (Xioctl(fd, VIDIOC_G_FMT, &fmt) != 0) Bad("format", "VIDIOC_G_FMT failed: " + std::string(std::strerror(errno)));
  const int want_w = options.width > 0 ? options.width : static_cast<int>(fmt.fmt.pix.width);
  const int want_h = options.height > 0 ? options.height : static_cast<int>(fmt.fmt.pix.height);
  fmt.fmt.pix.width = static_cast<std::uint32_t>(want_w);
  fmt.fmt.pix.height = static_cast<std::uint32_t>(want_h);
  fmt.fmt.pix.pixelformat = fourcc;
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  fmt.fmt.pix.bytesperline = 0;
  if (Xioctl(fd, VIDIOC_S_FMT, &fmt) != 0) {
    Bad("format", std::string("VIDIOC_S_FMT ") + stream.fourcc + " " + std::to_string(want_w) + "x" +
                      std::to_string(want_h) + " failed: " + std::strerror(errno));
  }
  // Drivers adjust what they cannot give instead of failing: compare.
  if (fmt.fmt.pix.pixelformat != fourcc || static_cast<int>(fmt.fmt.pix.width) != want_w ||
      static_cast<int>(fmt.fmt.pix.height) != want_h) {
    const std::string sizes = SizesAndRates(fd, fourcc);
    Bad("format", "cannot give " + stream.fourcc + " " + std::to_string(want_w) + "x" + std::to_string(want_h) +
                      " (it gives " + FourccText(fmt.fmt.pix.pixelformat) + " " + std::to_string(fmt.fmt.pix.width) +
                      "x" + std::to_string(fmt.fmt.pix.height) +
                      "; offered: " + (sizes.empty() ? "sizes not listed by the device" : sizes) + ")");
  }
  if (fmt.fmt.pix.field != V4L2_FIELD_NONE && fmt.fmt.pix.field != V4L2_FIELD_ANY) {
    Bad("format", "the device gives interlaced fields (field order " + std::to_string(fmt.fmt.pix.field) +
                      "): progressive frames are needed");
  }
  stream.width = want_w;
  stream.height = want_h;
  stream.bytes_per_line = stream.format == V4l2PixelFormat::kMjpeg ? 0 : static_cast<int>(fmt.fmt.pix.bytesperline);
  const int min_line = stream.format == V4l2PixelFormat::kYuyv ? 2 * want_w : want_w;
  if (stream.format != V4l2PixelFormat::kMjpeg && stream.bytes_per_line < min_line) {
    stream.bytes_per_line = min_line;  // drivers that leave it 0 pack the rows
  }
}

void V4l2Camera::Impl::SelectRate() {
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  const bool can_get = Xioctl(fd, VIDIOC_G_PARM, &parm) == 0;
  if (options.fps > 0) {
    const std::string offered = SizesAndRates(fd, FourccOf(stream.format));
    // Settable if the driver says so, or lists frame intervals for the format (some drivers do not say).
    const bool settable = (can_get && (parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME) != 0) ||
                          offered.find(" fps)") != std::string::npos;
    if (!settable) {
      const double now = can_get ? FpsOf(parm.parm.capture.timeperframe) : 0;
      // A device that runs at the rate asked for anyway (an HDMI input at its timing's rate) is fine.
      if (!(now > 0 && std::abs(now - options.fps) <= 0.01 * options.fps)) {
        Bad("frame rate", "the device does not set its frame rate on input " + std::to_string(stream.input) +
                              " (it runs at " + (now > 0 ? Rate(now) + " fps" : "a rate it does not say") +
                              "); leave the rate out");
      }
    } else {
      parm = {};
      parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      // A rational close to 1/fps: 1000/(1000 fps) keeps 29.97 and 59.94 exact enough.
      parm.parm.capture.timeperframe.numerator = 1000;
      parm.parm.capture.timeperframe.denominator = static_cast<std::uint32_t>(std::lround(options.fps * 1000));
      if (Xioctl(fd, VIDIOC_S_PARM, &parm) != 0) {
        Bad("frame rate", "VIDIOC_S_PARM failed: " + std::string(std::strerror(errno)));
      }
      double got = FpsOf(parm.parm.capture.timeperframe);
      if (got == 0) {
        parm = {};
        parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        if (Xioctl(fd, VIDIOC_G_PARM, &parm) == 0) got = FpsOf(parm.parm.capture.timeperframe);
      }
      if (!(std::abs(got - options.fps) <= 0.01 * options.fps)) {
        Bad("frame rate", "cannot give " + Rate(options.fps) + " fps at " + stream.fourcc + " " +
                              std::to_string(stream.width) + "x" + std::to_string(stream.height) + " (it gives " +
                              Rate(got) + " fps; offered: " + (offered.empty() ? "rates not listed" : offered) + ")");
      }
    }
  }
  parm = {};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  stream.fps = Xioctl(fd, VIDIOC_G_PARM, &parm) == 0 ? FpsOf(parm.parm.capture.timeperframe) : 0;
}

void V4l2Camera::Impl::SetControl(std::uint32_t id, const char* name, int value) {
  v4l2_queryctrl q{};
  q.id = id;
  if (Xioctl(fd, VIDIOC_QUERYCTRL, &q) != 0 || (q.flags & V4L2_CTRL_FLAG_DISABLED) != 0) {
    Bad(name, "the device has no " + std::string(name) + " control");
  }
  if (value < q.minimum || value > q.maximum) {
    Bad(name, std::to_string(value) + " is outside the device's range " + std::to_string(q.minimum) + ".." +
                  std::to_string(q.maximum));
  }
  // Manual: switch the automatic mode off first (an automatic mode makes the value inactive or read-only).
  v4l2_control automatic{};
  if (id == V4L2_CID_EXPOSURE_ABSOLUTE) {
    automatic.id = V4L2_CID_EXPOSURE_AUTO;
    automatic.value = V4L2_EXPOSURE_MANUAL;
  } else {
    automatic.id = V4L2_CID_AUTOGAIN;
    automatic.value = 0;
  }
  v4l2_queryctrl qa{};
  qa.id = automatic.id;
  if (Xioctl(fd, VIDIOC_QUERYCTRL, &qa) == 0 && (qa.flags & V4L2_CTRL_FLAG_DISABLED) == 0 &&
      Xioctl(fd, VIDIOC_S_CTRL, &automatic) != 0) {
    Bad(name, std::string("cannot switch automatic ") + name + " off: " + std::strerror(errno));
  }
  v4l2_control c{};
  c.id = id;
  c.value = value;
  if (Xioctl(fd, VIDIOC_S_CTRL, &c) != 0) Bad(name, "cannot be set: " + std::string(std::strerror(errno)));
}

void V4l2Camera::Impl::StartStreaming() {
  if (options.buffers < 2 || options.buffers > 32) Bad("buffers", "must be 2..32");
  v4l2_requestbuffers req{};
  req.count = static_cast<std::uint32_t>(options.buffers);
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (Xioctl(fd, VIDIOC_REQBUFS, &req) != 0) {
    Bad("buffers", "VIDIOC_REQBUFS (mmap) failed: " + std::string(std::strerror(errno)));
  }
  if (req.count < 2) Bad("buffers", "the driver gave " + std::to_string(req.count) + " buffer(s); 2 are needed");
  buffers.assign(req.count, Buffer{});
  for (std::uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = i;
    if (Xioctl(fd, VIDIOC_QUERYBUF, &b) != 0)
      Bad("buffers", "VIDIOC_QUERYBUF failed: " + std::string(std::strerror(errno)));
    buffers[i].length = b.length;
    buffers[i].start = mmap(nullptr, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd, b.m.offset);
    if (buffers[i].start == MAP_FAILED) Bad("buffers", "mmap failed: " + std::string(std::strerror(errno)));
    if (Xioctl(fd, VIDIOC_QBUF, &b) != 0) Bad("buffers", "VIDIOC_QBUF failed: " + std::string(std::strerror(errno)));
  }
  stream.buffers = static_cast<int>(req.count);
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (Xioctl(fd, VIDIOC_STREAMON, &type) != 0) Bad("", "VIDIOC_STREAMON failed: " + std::string(std::strerror(errno)));
  streaming = true;
  held = -1;
  have_ready = false;
  last_seq = -1;
  wraps = 0;
  last_frame_mono = ClockUs(CLOCK_MONOTONIC);
  timeouts_reported = 0;
}

void V4l2Camera::Impl::Close() {
  if (fd >= 0 && streaming) {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    Xioctl(fd, VIDIOC_STREAMOFF, &type);
  }
  streaming = false;
  for (Buffer& b : buffers) {
    if (b.start != MAP_FAILED) munmap(b.start, b.length);
  }
  buffers.clear();
  if (fd >= 0) {
    // Free the driver's buffers so that the device can be opened again (and its module unloaded).
    v4l2_requestbuffers req{};
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    Xioctl(fd, VIDIOC_REQBUFS, &req);
    close(fd);
  }
  fd = -1;
  held = -1;
  have_ready = false;
}

void V4l2Camera::Impl::Disconnected(int err) {
  if (fd < 0) return;
  Push(V4l2Fault::Kind::kDisconnected, last_seq, last_seq,
       options.device + " disconnected after frame " + std::to_string(last_seq) + " (" + std::strerror(err) +
           "); reopening every " + std::to_string(options.reopen_interval_ms) + " ms");
  Close();
  next_reopen_mono = ClockUs(CLOCK_MONOTONIC) + options.reopen_interval_ms * 1000LL;
}

// Takes every finished buffer from the driver: the newest good one becomes `ready`, older ones go back at once
// (skipped), damaged ones are reported. Returns false if the device went away.
bool V4l2Camera::Impl::Drain() {
  while (true) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    if (Xioctl(fd, VIDIOC_DQBUF, &b) != 0) {
      if (errno == EAGAIN) return true;
      Disconnected(errno);
      return false;
    }
    const std::int64_t seq = Extend(b.sequence);
    if (last_seq >= 0 && seq <= last_seq) {
      // The driver numbered two frames alike (vivid does when its thread runs late) or went back: numbers must
      // increase, so the older copy is not delivered.
      if (have_ready && seq == ready_seq && (b.flags & V4L2_BUF_FLAG_ERROR) == 0) {
        Push(V4l2Fault::Kind::kRepeated, seq, seq,
             options.device + ": frame " + std::to_string(seq) +
                 " came twice (the driver repeated its number): " + "the older copy skipped");
        std::swap(ready, b);
      } else {
        Push(V4l2Fault::Kind::kRepeated, seq, seq,
             options.device + ": a frame numbered " + std::to_string(seq) + " came after frame " +
                 std::to_string(last_seq) + " (the driver repeated or went back): not delivered");
      }
      ++skipped;
      Requeue(b);
      if (fd < 0) return false;
      continue;
    }
    if (last_seq >= 0 && seq > last_seq + 1) {
      dropped += seq - last_seq - 1;
      Push(V4l2Fault::Kind::kDropped, last_seq + 1, seq - 1,
           options.device + ": " + Frames(last_seq + 1, seq - 1) + " dropped by the driver (sequence " +
               std::to_string(last_seq) + " -> " + std::to_string(seq) + ")");
    }
    last_seq = seq;
    if ((b.flags & V4L2_BUF_FLAG_ERROR) != 0) {
      ++errors;
      Push(V4l2Fault::Kind::kBufferError, seq, seq,
           options.device + ": frame " + std::to_string(seq) + " came with the error flag (damaged data): dropped");
      Requeue(b);
      if (fd < 0) return false;
      continue;
    }
    if (have_ready) {
      // An older good frame waiting: not delivered (the newest wins).
      ++skipped;
      const std::int64_t old = ready_seq;
      Push(V4l2Fault::Kind::kSkipped, old, old,
           options.device + ": frame " + std::to_string(old) + " skipped: frame " + std::to_string(seq) +
               " was already waiting (the reader fell behind)");
      Requeue(ready);
      if (fd < 0) return false;
    }
    ready = b;
    ready_seq = seq;
    have_ready = true;
  }
}

V4l2Camera::V4l2Camera(const V4l2Options& options) : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  try {
    impl_->Open();
  } catch (...) {
    impl_->Close();
    throw;
  }
}

V4l2Camera::~V4l2Camera() { impl_->Close(); }

V4l2Camera::Status V4l2Camera::Grab(int timeout_ms, V4l2Frame& frame, V4l2Fault& fault) {
  Impl& m = *impl_;
  auto pop_fault = [&]() {
    if (m.pending_read >= m.pending_count) return false;
    fault = m.pending[m.pending_read++];
    if (m.pending_read == m.pending_count) m.pending_read = m.pending_count = 0;
    return true;
  };
  if (pop_fault()) return Status::kFault;
  // Disconnected: try to open the device again.
  if (m.fd < 0) {
    const std::int64_t now = ClockUs(CLOCK_MONOTONIC);
    if (now < m.next_reopen_mono) {
      const std::int64_t wait_ms = std::min<std::int64_t>(timeout_ms, (m.next_reopen_mono - now) / 1000 + 1);
      timespec ts{static_cast<time_t>(wait_ms / 1000), static_cast<long>(wait_ms % 1000) * 1000000};
      nanosleep(&ts, nullptr);
      return Status::kNothing;
    }
    try {
      m.Open();
    } catch (const InputError&) {
      m.Close();
      m.next_reopen_mono = ClockUs(CLOCK_MONOTONIC) + m.options.reopen_interval_ms * 1000LL;
      return Status::kNothing;
    }
    m.Push(V4l2Fault::Kind::kReopened, -1, -1,
           m.options.device + " is back ('" + m.stream.card + "', " + m.stream.fourcc + " " +
               std::to_string(m.stream.width) + "x" + std::to_string(m.stream.height) +
               "): streaming again, frame numbers restart at 0");
    pop_fault();
    return Status::kFault;
  }
  // The frame handed out last time goes back to the driver.
  if (m.held >= 0) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = static_cast<std::uint32_t>(m.held);
    m.held = -1;
    m.Requeue(b);
    if (pop_fault()) return Status::kFault;
  }
  if (!m.have_ready) {
    pollfd p{m.fd, POLLIN, 0};
    const int r = poll(&p, 1, timeout_ms);
    if (r < 0 && errno != EINTR) m.Disconnected(errno);
    if (m.fd >= 0 && r > 0) m.Drain();
    if (pop_fault()) return Status::kFault;
  }
  if (m.fd < 0) return Status::kNothing;
  if (!m.have_ready) {
    const std::int64_t now = ClockUs(CLOCK_MONOTONIC);
    if (now - m.last_frame_mono >= static_cast<std::int64_t>(m.timeouts_reported + 1) * m.options.timeout_ms * 1000) {
      ++m.timeouts_reported;
      fault = {};
      fault.kind = V4l2Fault::Kind::kTimeout;
      fault.first_seq = fault.last_seq = m.last_seq;
      fault.utime = ClockUs(CLOCK_REALTIME);
      fault.message = m.options.device + ": no frame for " + std::to_string((now - m.last_frame_mono) / 1000) +
                      " ms after " + (m.last_seq >= 0 ? "frame " + std::to_string(m.last_seq) : "the stream started");
      return Status::kFault;
    }
    return Status::kNothing;
  }
  // Deliver the newest good frame.
  const v4l2_buffer& b = m.ready;
  m.have_ready = false;
  m.held = static_cast<int>(b.index);
  frame.data = static_cast<const std::uint8_t*>(m.buffers[b.index].start);
  frame.bytes = std::min<std::size_t>(b.bytesused, m.buffers[b.index].length);
  frame.seq = m.ready_seq;
  // The epoch offset at this frame (the system clock may be stepped or slewed).
  std::int64_t mono = 0;
  const std::int64_t real_minus_mono = RealMinusMonotonicUs(mono);
  frame.dequeued_monotonic_us = mono;
  frame.monotonic_us = static_cast<std::int64_t>(b.timestamp.tv_sec) * 1000000 + b.timestamp.tv_usec;
  // A driver whose timestamps are not CLOCK_MONOTONIC: the time it was taken from the driver instead.
  if ((b.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) != V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC) frame.monotonic_us = mono;
  frame.utime = frame.monotonic_us + real_minus_mono;
  m.last_frame_mono = mono;
  m.timeouts_reported = 0;
  ++m.delivered;
  return Status::kFrame;
}

const V4l2Stream& V4l2Camera::stream() const { return impl_->stream; }
bool V4l2Camera::connected() const { return impl_->fd >= 0; }
std::int64_t V4l2Camera::delivered() const { return impl_->delivered; }
std::int64_t V4l2Camera::dropped() const { return impl_->dropped; }
std::int64_t V4l2Camera::skipped() const { return impl_->skipped; }
std::int64_t V4l2Camera::errors() const { return impl_->errors; }

bool V4l2FrameToGray(const V4l2Stream& stream, const V4l2Frame& frame, GrayImage& out, std::string& error) {
  const int w = stream.width, h = stream.height;
  if (out.width != w || out.height != h) out = GrayImage(w, h);
  switch (stream.format) {
    case V4l2PixelFormat::kGrey:
    case V4l2PixelFormat::kYuyv: {
      const std::size_t line = static_cast<std::size_t>(stream.bytes_per_line);
      const std::size_t need = line * static_cast<std::size_t>(h - 1) +
                               static_cast<std::size_t>(w) * (stream.format == V4l2PixelFormat::kYuyv ? 2 : 1);
      if (frame.bytes < need) {
        error = "frame " + std::to_string(frame.seq) + " has " + std::to_string(frame.bytes) + " bytes, " +
                std::to_string(need) + " expected";
        return false;
      }
      for (int v = 0; v < h; ++v) {
        const std::uint8_t* row = frame.data + line * static_cast<std::size_t>(v);
        std::uint8_t* dst = out.pixels.data() + static_cast<std::size_t>(v) * static_cast<std::size_t>(w);
        if (stream.format == V4l2PixelFormat::kGrey) {
          std::memcpy(dst, row, static_cast<std::size_t>(w));
        } else {
          for (int u = 0; u < w; ++u) dst[u] = row[2 * u];  // Y0 U Y1 V: the luma is every other byte
        }
      }
      return true;
    }
    case V4l2PixelFormat::kMjpeg: {
      const cv::Mat encoded(1, static_cast<int>(frame.bytes), CV_8UC1, const_cast<std::uint8_t*>(frame.data));
      cv::Mat decoded(h, w, CV_8UC1, out.pixels.data());  // decoded in place when the size is right
      try {
        cv::imdecode(encoded, cv::IMREAD_GRAYSCALE, &decoded);
      } catch (const cv::Exception& e) {
        error = "frame " + std::to_string(frame.seq) + ": JPEG not decodable: " + e.err;
        return false;
      }
      if (decoded.empty()) {
        error = "frame " + std::to_string(frame.seq) + ": JPEG not decodable";
        return false;
      }
      if (decoded.cols != w || decoded.rows != h) {
        error = "frame " + std::to_string(frame.seq) + ": JPEG is " + std::to_string(decoded.cols) + "x" +
                std::to_string(decoded.rows) + ", the stream's size is " + std::to_string(w) + "x" + std::to_string(h);
        return false;
      }
      if (decoded.data != out.pixels.data()) {
        for (int v = 0; v < h; ++v) std::memcpy(out.pixels.data() + static_cast<std::size_t>(v) * w, decoded.ptr(v), w);
      }
      return true;
    }
  }
  error = "unknown pixel format";
  return false;
}

namespace {

// The camera as a FrameSource of the pipeline: grey frames; each fault becomes an unusable frame carrying the
// fault's last frame number, so that the pipeline counts the numbers as seen and reports the fault's own words.
class V4l2Source : public FrameSource {
 public:
  V4l2Source(const V4l2Options& options, std::string camera_name) : camera_(options), name_(std::move(camera_name)) {}
  SourceStatus Next(Frame& frame, std::string& error, int timeout_ms) override {
    frame.camera = name_;
    frame.origin = camera_.stream().card;
    switch (camera_.Grab(timeout_ms, v4l2_frame_, fault_)) {
      case V4l2Camera::Status::kNothing:
        return SourceStatus::kNoFrameYet;
      case V4l2Camera::Status::kFault:
        frame.seq = fault_.last_seq;
        frame.utime = fault_.utime;
        error = fault_.message;
        return SourceStatus::kBadFrame;
      case V4l2Camera::Status::kFrame:
        break;
    }
    frame.seq = v4l2_frame_.seq;
    frame.utime = v4l2_frame_.utime;
    return V4l2FrameToGray(camera_.stream(), v4l2_frame_, frame.image, error) ? SourceStatus::kFrame
                                                                              : SourceStatus::kBadFrame;
  }

 private:
  V4l2Camera camera_;
  std::string name_;
  V4l2Frame v4l2_frame_;
  V4l2Fault fault_;
};

}  // namespace

std::unique_ptr<FrameSource> MakeV4l2Source(const V4l2Options& options, const std::string& camera_name) {
  return std::make_unique<V4l2Source>(options, camera_name);
}

}  // namespace visco::vision

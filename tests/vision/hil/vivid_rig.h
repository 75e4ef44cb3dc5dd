// The test rig around the vivid virtual video driver in the HIL VM: its output looped back to its capture, frames
// written to the output, its error-injection controls. Its own V4L2 code: it shares nothing with the capture source
// under test (vision/v4l2_camera.cc).
#pragma once

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace visco::hil {

inline constexpr char kCaptureDevice[] = "/dev/video0";
inline constexpr char kOutputDevice[] = "/dev/video1";
inline constexpr int kWebcamInput = 0;
inline constexpr int kHdmiInput = 1;

inline int Ioctl(int fd, unsigned long request, void* arg) {
  int r;
  do {
    r = ioctl(fd, request, arg);
  } while (r == -1 && errno == EINTR);
  return r;
}

[[noreturn]] inline void Fail(const std::string& what) { throw std::runtime_error(what + ": " + std::strerror(errno)); }

inline int OpenOrFail(const char* path) {
  const int fd = open(path, O_RDWR | O_CLOEXEC);
  if (fd < 0) Fail(std::string("open ") + path);
  return fd;
}

// v4l2-ctl's control names: lower case, anything else an underscore ("Loop Video" -> loop_video).
inline std::string ControlName(const char* name) {
  std::string out;
  for (const char* p = name; *p != 0; ++p) {
    const unsigned char c = static_cast<unsigned char>(*p);
    if (std::isalnum(c) != 0) {
      out += static_cast<char>(std::tolower(c));
    } else if (!out.empty() && out.back() != '_') {
      out += '_';
    }
  }
  while (!out.empty() && out.back() == '_') out.pop_back();
  return out;
}

// Sets the control named `name` (v4l2-ctl's spelling) on the device at `path`; a button is pressed.
inline void SetControl(const char* path, const std::string& name, std::int64_t value) {
  const int fd = OpenOrFail(path);
  v4l2_query_ext_ctrl q{};
  q.id = V4L2_CTRL_FLAG_NEXT_CTRL;
  bool found = false;
  while (Ioctl(fd, VIDIOC_QUERY_EXT_CTRL, &q) == 0) {
    if (q.type != V4L2_CTRL_TYPE_CTRL_CLASS && ControlName(q.name) == name) {
      found = true;
      break;
    }
    q.id |= V4L2_CTRL_FLAG_NEXT_CTRL;
  }
  if (!found) {
    close(fd);
    throw std::runtime_error(std::string(path) + " has no control " + name);
  }
  v4l2_ext_control c{};
  c.id = q.id;
  if (q.type == V4L2_CTRL_TYPE_INTEGER64) {
    c.value64 = value;
  } else {
    c.value = static_cast<std::int32_t>(q.type == V4L2_CTRL_TYPE_BUTTON ? 1 : value);
  }
  v4l2_ext_controls cs{};
  cs.which = V4L2_CTRL_WHICH_CUR_VAL;
  cs.count = 1;
  cs.controls = &c;
  const int r = Ioctl(fd, VIDIOC_S_EXT_CTRLS, &cs);
  close(fd);
  if (r != 0) Fail(std::string("set ") + name + " on " + path);
}

// The HDMI input and output at the same timings (the first vivid offers: 640x480p59.94), the output in `fourcc` at
// that size, the capture looping the output without on-screen text.
inline void SetupLoop(std::uint32_t fourcc) {
  const int cap = OpenOrFail(kCaptureDevice);
  const int out = OpenOrFail(kOutputDevice);
  int input = kHdmiInput, output = 0;
  if (Ioctl(cap, VIDIOC_S_INPUT, &input) != 0) Fail("S_INPUT HDMI");
  if (Ioctl(out, VIDIOC_S_OUTPUT, &output) != 0) Fail("S_OUTPUT");
  for (int fd : {cap, out}) {
    v4l2_enum_dv_timings e{};
    e.index = 0;
    if (Ioctl(fd, VIDIOC_ENUM_DV_TIMINGS, &e) != 0) Fail("ENUM_DV_TIMINGS");
    v4l2_dv_timings t = e.timings;
    if (Ioctl(fd, VIDIOC_S_DV_TIMINGS, &t) != 0) Fail("S_DV_TIMINGS");
  }
  v4l2_format f{};
  f.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
  if (Ioctl(out, VIDIOC_G_FMT, &f) != 0) Fail("G_FMT output");
  f.fmt.pix.width = 640;
  f.fmt.pix.height = 480;
  f.fmt.pix.pixelformat = fourcc;
  f.fmt.pix.field = V4L2_FIELD_NONE;
  f.fmt.pix.bytesperline = 0;
  if (Ioctl(out, VIDIOC_S_FMT, &f) != 0) Fail("S_FMT output");
  close(cap);
  close(out);
  SetControl(kCaptureDevice, "loop_video", 1);
  SetControl(kCaptureDevice, "osd_text_mode", 2);
}

// Writes frames to vivid's output on its own thread, each frame `repeat` times, cycling through them until stopped:
// what a camera in front of a scene would see. The frames are whole images in the output's format (packed rows).
class OutputWriter {
 public:
  OutputWriter(std::vector<std::vector<std::uint8_t>> frames, int repeat)
      : frames_(std::move(frames)), repeat_(repeat) {
    fd_ = OpenOrFail(kOutputDevice);
    v4l2_requestbuffers req{};
    req.count = 4;
    req.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    req.memory = V4L2_MEMORY_MMAP;
    if (Ioctl(fd_, VIDIOC_REQBUFS, &req) != 0) Fail("REQBUFS output");
    for (std::uint32_t i = 0; i < req.count; ++i) {
      v4l2_buffer b{};
      b.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
      b.memory = V4L2_MEMORY_MMAP;
      b.index = i;
      if (Ioctl(fd_, VIDIOC_QUERYBUF, &b) != 0) Fail("QUERYBUF output");
      void* p = mmap(nullptr, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, b.m.offset);
      if (p == MAP_FAILED) Fail("mmap output");
      maps_.push_back({p, b.length});
    }
    thread_ = std::thread([this] { Run(); });
  }
  ~OutputWriter() {
    stop_ = true;
    thread_.join();
    int type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    Ioctl(fd_, VIDIOC_STREAMOFF, &type);
    for (auto& m : maps_) munmap(m.first, m.second);
    v4l2_requestbuffers req{};
    req.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    req.memory = V4L2_MEMORY_MMAP;
    Ioctl(fd_, VIDIOC_REQBUFS, &req);
    close(fd_);
  }
  std::int64_t written() const { return written_.load(); }
  std::string error() const { return error_; }

 private:
  void Run() {
    std::size_t frame = 0;
    int shown = 0;
    std::uint32_t fresh = 0;  // buffers not yet queued
    bool streaming = false;
    while (!stop_) {
      v4l2_buffer b{};
      b.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
      b.memory = V4L2_MEMORY_MMAP;
      if (fresh < maps_.size()) {
        b.index = fresh++;
      } else {
        pollfd p{fd_, POLLOUT, 0};
        if (poll(&p, 1, 100) <= 0) continue;
        if (Ioctl(fd_, VIDIOC_DQBUF, &b) != 0) {
          if (errno == EAGAIN) continue;
          error_ = std::string("DQBUF output: ") + std::strerror(errno);
          return;
        }
      }
      const auto& f = frames_[frame];
      std::memcpy(maps_[b.index].first, f.data(), std::min(f.size(), maps_[b.index].second));
      b.bytesused = static_cast<std::uint32_t>(f.size());
      b.field = V4L2_FIELD_NONE;
      if (Ioctl(fd_, VIDIOC_QBUF, &b) != 0) {
        error_ = std::string("QBUF output: ") + std::strerror(errno);
        return;
      }
      ++written_;
      if (++shown == repeat_) {
        shown = 0;
        frame = (frame + 1) % frames_.size();
      }
      if (!streaming && fresh == maps_.size()) {
        int type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
        if (Ioctl(fd_, VIDIOC_STREAMON, &type) != 0) {
          error_ = std::string("STREAMON output: ") + std::strerror(errno);
          return;
        }
        streaming = true;
      }
    }
  }
  std::vector<std::vector<std::uint8_t>> frames_;
  int repeat_;
  int fd_ = -1;
  std::vector<std::pair<void*, std::size_t>> maps_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<std::int64_t> written_{0};
  std::string error_;
};

}  // namespace visco::hil

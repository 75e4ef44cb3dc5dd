#include "vision/v4l2_output.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <utility>
#include <vector>

#include "common/error.h"
#include "vision/v4l2_ioctl.h"

namespace visco::vision {
namespace {

using internal::FourccText;
using internal::Xioctl;

std::string Errno() { return std::strerror(errno); }

}  // namespace

struct V4l2Output::Impl {
  V4l2OutputOptions options;
  int fd = -1;
  std::string card, fourcc_name;
  std::uint32_t fourcc = 0;
  std::uint32_t bytes_per_line = 0, image_bytes = 0;
  std::vector<std::pair<void*, std::size_t>> maps;
  std::uint32_t fresh = 0;  // buffers never queued yet (taken first, in order)
  bool streaming = false;
  std::int64_t written = 0;

  [[noreturn]] void Bad(const std::string& object, const std::string& what) {
    Close();
    throw InputError(options.device, object, what);
  }
  void Open();
  void Close();
  // The picture into buffer `index`, in the device's format and row pitch.
  void Fill(std::uint32_t index, const GrayImageView& picture);
};

void V4l2Output::Impl::Open() {
  const std::string& dev = options.device;
  struct stat st {};
  if (stat(dev.c_str(), &st) != 0) Bad("", "no such device (" + Errno() + ")");
  if (!S_ISCHR(st.st_mode)) Bad("", "not a device (a V4L2 video output device such as /dev/video1 is needed)");
  if (options.width <= 0 || options.height <= 0) Bad("", "the frames' width and height are needed");
  if (options.buffers < 2 || options.buffers > 32) Bad("buffers", "must be in 2..32");
  if (options.pixel_format == "GREY") {
    fourcc = V4L2_PIX_FMT_GREY;
  } else if (options.pixel_format == "YUYV") {
    fourcc = V4L2_PIX_FMT_YUYV;
  } else {
    Bad("pixel format " + options.pixel_format, "not one this writer gives (GREY or YUYV)");
  }
  fd = open(dev.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) Bad("", "cannot open: " + Errno());
  v4l2_capability cap{};
  if (Xioctl(fd, VIDIOC_QUERYCAP, &cap) != 0) Bad("", "not a V4L2 device (VIDIOC_QUERYCAP failed)");
  const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? cap.device_caps : cap.capabilities;
  card = reinterpret_cast<const char*>(cap.card);
  if ((caps & V4L2_CAP_VIDEO_OUTPUT) == 0) {
    const std::string is = (caps & V4L2_CAP_VIDEO_CAPTURE) != 0 ? "a video capture" : "no single-planar video output";
    Bad("", "not a video output device ('" + card + "' is " + is + " device)");
  }
  if ((caps & V4L2_CAP_STREAMING) == 0) Bad("", "'" + card + "' does not stream (no V4L2_CAP_STREAMING)");
  if (options.output >= 0) {
    std::string outputs;
    v4l2_output o{};
    for (o.index = 0; Xioctl(fd, VIDIOC_ENUMOUTPUT, &o) == 0; ++o.index) {
      outputs +=
          (outputs.empty() ? "" : ", ") + std::to_string(o.index) + " '" + reinterpret_cast<const char*>(o.name) + "'";
    }
    int index = options.output;
    if (Xioctl(fd, VIDIOC_S_OUTPUT, &index) != 0) {
      Bad("output " + std::to_string(options.output),
          "cannot be selected (" + Errno() + "); the device's outputs: " + (outputs.empty() ? "none listed" : outputs));
    }
  }
  // The format: what is asked, or what the device offers instead.
  std::string offered;
  v4l2_fmtdesc desc{};
  desc.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
  for (desc.index = 0; Xioctl(fd, VIDIOC_ENUM_FMT, &desc) == 0; ++desc.index) {
    offered += (offered.empty() ? "" : ", ") + FourccText(desc.pixelformat);
  }
  v4l2_format f{};
  f.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
  if (Xioctl(fd, VIDIOC_G_FMT, &f) != 0) Bad("format", "cannot be read (" + Errno() + ")");
  f.fmt.pix.width = static_cast<std::uint32_t>(options.width);
  f.fmt.pix.height = static_cast<std::uint32_t>(options.height);
  f.fmt.pix.pixelformat = fourcc;
  f.fmt.pix.field = V4L2_FIELD_NONE;
  f.fmt.pix.bytesperline = 0;
  if (Xioctl(fd, VIDIOC_S_FMT, &f) != 0) Bad("format", "cannot be set (" + Errno() + ")");
  const std::string asked = std::to_string(options.width) + "x" + std::to_string(options.height);
  if (f.fmt.pix.pixelformat != fourcc) {
    Bad("pixel format " + options.pixel_format,
        "not taken (it offers " + (offered.empty() ? std::string("nothing listed") : offered) + ")");
  }
  if (f.fmt.pix.width != static_cast<std::uint32_t>(options.width) ||
      f.fmt.pix.height != static_cast<std::uint32_t>(options.height)) {
    Bad("size " + asked, "not taken: it gives " + std::to_string(f.fmt.pix.width) + "x" +
                             std::to_string(f.fmt.pix.height) +
                             " (an HDMI output's size follows its timings: set them first, e.g. v4l2-ctl -d " +
                             options.device + " --set-dv-bt-timings index=0 for 640x480)");
  }
  fourcc_name = FourccText(fourcc);
  const std::uint32_t bytes_per_pixel = fourcc == V4L2_PIX_FMT_YUYV ? 2 : 1;
  bytes_per_line = std::max(f.fmt.pix.bytesperline, f.fmt.pix.width * bytes_per_pixel);
  image_bytes = bytes_per_line * f.fmt.pix.height;
  v4l2_requestbuffers req{};
  req.count = static_cast<std::uint32_t>(options.buffers);
  req.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
  req.memory = V4L2_MEMORY_MMAP;
  if (Xioctl(fd, VIDIOC_REQBUFS, &req) != 0) Bad("buffers", "cannot be allocated (" + Errno() + ")");
  if (req.count < 2) Bad("buffers", "the driver gave " + std::to_string(req.count) + ", at least 2 are needed");
  for (std::uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = i;
    if (Xioctl(fd, VIDIOC_QUERYBUF, &b) != 0) Bad("buffers", "cannot be queried (" + Errno() + ")");
    if (b.length < image_bytes) Bad("buffers", "smaller than a frame");
    void* p = mmap(nullptr, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd, b.m.offset);
    if (p == MAP_FAILED) Bad("buffers", "cannot be mapped (" + Errno() + ")");
    maps.emplace_back(p, b.length);
  }
}

void V4l2Output::Impl::Close() {
  if (fd < 0) return;
  if (streaming) {
    int type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    Xioctl(fd, VIDIOC_STREAMOFF, &type);
  }
  for (auto& m : maps) munmap(m.first, m.second);
  maps.clear();
  v4l2_requestbuffers req{};
  req.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
  req.memory = V4L2_MEMORY_MMAP;
  Xioctl(fd, VIDIOC_REQBUFS, &req);
  close(fd);
  fd = -1;
  streaming = false;
}

void V4l2Output::Impl::Fill(std::uint32_t index, const GrayImageView& picture) {
  auto* out = static_cast<std::uint8_t*>(maps[index].first);
  for (int v = 0; v < picture.height; ++v) {
    const std::uint8_t* row = picture.data + static_cast<std::size_t>(v) * picture.stride;
    std::uint8_t* dst = out + static_cast<std::size_t>(v) * bytes_per_line;
    if (fourcc == V4L2_PIX_FMT_GREY) {
      std::memcpy(dst, row, static_cast<std::size_t>(picture.width));
    } else {  // YUYV: Y0 U Y1 V; the chroma neutral
      for (int u = 0; u < picture.width; ++u) {
        dst[2 * u] = row[u];
        dst[2 * u + 1] = 128;
      }
    }
  }
}

V4l2Output::V4l2Output(const V4l2OutputOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  impl_->Open();
}

V4l2Output::~V4l2Output() { impl_->Close(); }

bool V4l2Output::Write(const GrayImageView& picture, int timeout_ms, std::string& error) {
  Impl& m = *impl_;
  const std::string& dev = m.options.device;
  if (m.fd < 0) {
    error = dev + ": closed after an earlier failure";
    return false;
  }
  if (picture.empty() || picture.width != m.options.width || picture.height != m.options.height) {
    error = dev + ": a picture of " + std::to_string(picture.width) + "x" + std::to_string(picture.height) +
            " for a stream of " + std::to_string(m.options.width) + "x" + std::to_string(m.options.height);
    return false;
  }
  v4l2_buffer b{};
  b.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
  b.memory = V4L2_MEMORY_MMAP;
  if (m.fresh < m.maps.size()) {
    b.index = m.fresh++;
  } else {
    // A buffer the driver has shown and handed back (vivid holds the newest until the next one is queued).
    pollfd p{m.fd, POLLOUT, 0};
    const int r = poll(&p, 1, timeout_ms);
    if (r <= 0) {
      error = dev + (r == 0 ? ": no free output buffer within " + std::to_string(timeout_ms) + " ms"
                            : ": poll failed (" + Errno() + ")");
      return false;
    }
    if ((p.revents & POLLERR) != 0 && (p.revents & POLLOUT) == 0) {
      error = dev + ": the device reports an error (POLLERR)";
      return false;
    }
    if (Xioctl(m.fd, VIDIOC_DQBUF, &b) != 0) {
      error = dev + ": VIDIOC_DQBUF failed (" + Errno() + ")";
      return false;
    }
  }
  m.Fill(b.index, picture);
  b.bytesused = m.image_bytes;
  b.field = V4L2_FIELD_NONE;
  if (Xioctl(m.fd, VIDIOC_QBUF, &b) != 0) {
    error = dev + ": VIDIOC_QBUF failed (" + Errno() + ")";
    return false;
  }
  if (!m.streaming) {
    int type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    if (Xioctl(m.fd, VIDIOC_STREAMON, &type) != 0) {
      error = dev + ": VIDIOC_STREAMON failed (" + Errno() + ")";
      return false;
    }
    m.streaming = true;
  }
  ++m.written;
  return true;
}

std::int64_t V4l2Output::written() const { return impl_->written; }
const std::string& V4l2Output::device() const { return impl_->options.device; }
const std::string& V4l2Output::card() const { return impl_->card; }
const std::string& V4l2Output::fourcc() const { return impl_->fourcc_name; }

}  // namespace visco::vision

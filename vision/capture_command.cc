// `visco capture`: the camera process. Reads a V4L2 device (vision/v4l2_camera.h) and publishes its frames as
// image_t on VISCO_CAMERA_IMAGE, its calibration as camera_info_t on VISCO_CAMERA_INFO (at start and periodically)
// and its faults on VISCO_FAULT.

#include <sys/resource.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <ctime>
#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>
#include <vector>

#include "common/error.h"
#include "lcmtypes/channels.h"
#include "visco/fault_t.hpp"
#include "visco/image_t.hpp"
#include "vision/camera_info.h"
#include "vision/commands.h"
#include "vision/image_png.h"
#include "vision/v4l2_camera.h"

namespace visco::vision {
namespace {

std::atomic<bool> g_stop{false};
extern "C" void OnCaptureSignal(int) { g_stop = true; }

struct CaptureArgs {
  V4l2Options v4l2;
  std::string camera, camera_name, extrinsics, name;
  double info_period_s = 1.0;
  bool decode_mjpeg = false;
  int png_level = -1;  // >= 0: grey frames published as PNG at this zlib level
  std::string lcm_url;
  std::int64_t max_frames = 0;
  double duration_s = 0;
  double max_fps = 0;  // > 0: publish at most this many frames per second (the newest each time)
};

std::int64_t MonotonicUs() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
}

double CpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec) * 1e-6;
}

double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  const auto k = static_cast<std::size_t>(p * static_cast<double>(v.size() - 1) + 0.5);
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

// The calibration the process publishes: from the files, checked against the stream.
CameraCalibration LoadCalibration(const CaptureArgs& a, const V4l2Stream& stream) {
  CameraCalibration c;
  if (a.camera.empty()) {
    if (!a.extrinsics.empty()) throw InputError("command line", "--extrinsics", "needs --camera (the intrinsics)");
    return c;
  }
  c.camera = LoadCamera(a.camera, a.camera_name);
  c.source = a.camera;
  if ((c.camera.width > 0 || c.camera.height > 0) &&
      (c.camera.width != stream.width || c.camera.height != stream.height)) {
    throw InputError(a.camera, "image size",
                     "the calibration is for " + std::to_string(c.camera.width) + "x" +
                         std::to_string(c.camera.height) + " but " + a.v4l2.device + " streams " +
                         std::to_string(stream.width) + "x" + std::to_string(stream.height));
  }
  // A calibration without a size is for this stream.
  c.camera.width = stream.width;
  c.camera.height = stream.height;
  if (!a.extrinsics.empty()) {
    c.extrinsics = LoadExtrinsicsWithUncertainty(a.extrinsics);
    c.source += ", " + a.extrinsics;
  }
  return c;
}

void RunCapture(const CaptureArgs& a) {
  if (!(a.info_period_s > 0)) throw InputError("command line", "--info-period", "must be positive (seconds)");
  if (a.v4l2.timeout_ms <= 0) throw InputError("command line", "--timeout-ms", "must be positive");
  if (!(a.max_fps >= 0)) throw InputError("command line", "--max-fps", "must be >= 0 (0: every frame)");
  lcm::LCM bus(a.lcm_url);
  if (!bus.good()) throw InputError("command line", "--lcm-url", "cannot open LCM bus '" + a.lcm_url + "'");
  V4l2Camera camera(a.v4l2);
  const V4l2Stream& stream = camera.stream();
  CameraCalibration calibration = LoadCalibration(a, stream);
  const std::string name = !a.name.empty()                    ? a.name
                           : !calibration.camera.name.empty() ? calibration.camera.name
                                                              : "camera";
  calibration.camera.name = name;
  std::fprintf(stderr, "capture: %s '%s' input %d '%s': %s %dx%d at %.4g fps, %d buffers; publishing '%s' on %s%s\n",
               a.v4l2.device.c_str(), stream.card.c_str(), stream.input, stream.input_name.c_str(),
               stream.fourcc.c_str(), stream.width, stream.height, stream.fps, stream.buffers, name.c_str(),
               channels::kCameraImage,
               a.camera.empty() ? " (no calibration: nothing on VISCO_CAMERA_INFO)" : " and VISCO_CAMERA_INFO");

  // Sized once: nothing is allocated per frame in the steady state (but in libpng, with --png-level).
  const bool passthrough = stream.format == V4l2PixelFormat::kMjpeg && !a.decode_mjpeg;
  const bool png = a.png_level >= 0;
  if (png && passthrough) {
    throw InputError("command line", "--png-level",
                     "the stream is MJPEG, which is published as it comes (already compressed); add --decode-mjpeg "
                     "to publish it decoded, as PNG");
  }
  const std::size_t pixels = static_cast<std::size_t>(stream.width) * static_cast<std::size_t>(stream.height);
  visco::image_t image{};
  image.camera = name;
  image.width = stream.width;
  image.height = stream.height;
  image.row_stride = stream.width;
  image.pixel_format =
      passthrough ? std::int32_t{visco::image_t::PIXEL_FORMAT_MJPEG} : std::int32_t{visco::image_t::PIXEL_FORMAT_GRAY8};
  // An MJPEG frame is at most what the driver's buffers hold; generously, 4 bytes per pixel. A PNG of a grey frame
  // is at most its pixels plus the format's overhead (stored blocks, filter bytes): as ample.
  image.data.reserve(passthrough || png ? 4 * pixels : pixels);
  image.data.resize(passthrough || png ? 0 : pixels);
  std::vector<std::uint8_t> encoded(image.data.capacity() + 4096 + name.size());
  GrayImage gray(stream.width, stream.height);

  auto publish_info = [&] {
    if (a.camera.empty()) return;
    timespec ts{};
    clock_gettime(CLOCK_REALTIME, &ts);
    const visco::camera_info_t info =
        EncodeCameraInfo(calibration, static_cast<std::int64_t>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000);
    bus.publish(channels::kCameraInfo, &info);
  };
  std::int64_t timeouts = 0, disconnects = 0, reopens = 0, bad = 0;
  auto publish_fault = [&](const V4l2Fault& f) {
    visco::fault_t m{};
    m.utime = f.utime;
    m.source = "camera";
    m.code = visco::fault_t::CODE_CAMERA;
    const bool lost = f.kind == V4l2Fault::Kind::kTimeout || f.kind == V4l2Fault::Kind::kDisconnected;
    m.severity = f.kind == V4l2Fault::Kind::kReopened ? visco::fault_t::SEVERITY_INFO
                 : lost                               ? visco::fault_t::SEVERITY_ERROR
                                                      : visco::fault_t::SEVERITY_WARNING;
    m.cleared = f.kind == V4l2Fault::Kind::kReopened;
    m.robot_stopped = false;
    m.message = f.message;
    bus.publish(channels::kFault, &m);
    static const char* const kKinds[] = {"dropped", "skipped",      "buffer_error", "repeated",
                                         "timeout", "disconnected", "reopened"};
    nlohmann::json j;
    j["fault"] = {{"kind", kKinds[static_cast<int>(f.kind)]},
                  {"first_seq", f.first_seq},
                  {"last_seq", f.last_seq},
                  {"utime", f.utime},
                  {"message", f.message}};
    std::printf("%s\n", j.dump().c_str());
    std::fflush(stdout);
    timeouts += f.kind == V4l2Fault::Kind::kTimeout ? 1 : 0;
    disconnects += f.kind == V4l2Fault::Kind::kDisconnected ? 1 : 0;
    reopens += f.kind == V4l2Fault::Kind::kReopened ? 1 : 0;
  };

  // Per-frame figures, for the summary (reserved: the measurement allocates nothing per frame either).
  std::vector<double> capture_to_publish_ms, dequeue_to_publish_ms;
  capture_to_publish_ms.reserve(1 << 16);
  dequeue_to_publish_ms.reserve(1 << 16);
  g_stop = false;
  std::signal(SIGINT, OnCaptureSignal);
  std::signal(SIGTERM, OnCaptureSignal);
  publish_info();
  const std::int64_t start = MonotonicUs();
  std::int64_t next_info = start + static_cast<std::int64_t>(a.info_period_s * 1e6);
  const double cpu_start = CpuSeconds();
  std::int64_t published = 0;
  // --max-fps: the next frame due for publication (the stream's frames before it are held back, counted).
  // image_t.seq is the driver's number less the frames held back since the stream (re)started: +1 a published frame,
  // so that its gaps are frames lost (vision reads a gap as lost frames and voids its tracking prediction).
  const std::int64_t publish_period_us = a.max_fps > 0 ? static_cast<std::int64_t>(1e6 / a.max_fps) : 0;
  std::int64_t next_publish_us = 0, held_back = 0, seq_offset = 0;
  std::int64_t last_driver_seq = -1;  // the driver counts from 0; -1: no frame yet
  std::uint64_t image_bytes = 0;      // image_t.data published
  V4l2Frame frame;
  V4l2Fault fault;
  std::string error;
  while (!g_stop) {
    const std::int64_t now = MonotonicUs();
    if (a.duration_s > 0 && now - start >= static_cast<std::int64_t>(a.duration_s * 1e6)) break;
    if (now >= next_info) {
      publish_info();
      next_info = now + static_cast<std::int64_t>(a.info_period_s * 1e6);
    }
    const V4l2Camera::Status status = camera.Grab(100, frame, fault);
    if (status == V4l2Camera::Status::kFault) {
      publish_fault(fault);
      if (fault.kind == V4l2Fault::Kind::kReopened) {
        publish_info();
        seq_offset = 0;  // the driver counts from its own start again
        last_driver_seq = -1;
      }
      continue;
    }
    if (status != V4l2Camera::Status::kFrame) continue;
    const bool counter_advanced = frame.seq > last_driver_seq;
    last_driver_seq = frame.seq;
    if (publish_period_us > 0) {
      if (frame.dequeued_monotonic_us < next_publish_us) {
        ++held_back;
        // A counter that does not advance (said by the camera as a fault) is passed on as it is.
        if (counter_advanced) ++seq_offset;
        continue;
      }
      // On the period's grid (a frame a little late does not shift it); after a gap, a new grid (no burst).
      const std::int64_t t = frame.dequeued_monotonic_us;
      next_publish_us = next_publish_us == 0 || next_publish_us + publish_period_us <= t
                            ? t + publish_period_us
                            : next_publish_us + publish_period_us;
    }
    image.utime = frame.utime;
    image.seq = frame.seq - seq_offset;
    auto bad_frame = [&](const std::string& why) {
      ++bad;
      V4l2Fault f;
      f.kind = V4l2Fault::Kind::kBufferError;
      f.first_seq = f.last_seq = frame.seq;
      f.utime = frame.utime;
      f.message = a.v4l2.device + ": " + why + ": dropped";
      publish_fault(f);
    };
    if (passthrough) {
      if (frame.bytes > image.data.capacity()) {
        bad_frame("MJPEG frame " + std::to_string(frame.seq) + " of " + std::to_string(frame.bytes) +
                  " bytes is larger than 4 bytes per pixel");
        continue;
      }
      image.data.assign(frame.data, frame.data + frame.bytes);
    } else {
      if (!V4l2FrameToGray(stream, frame, gray, error)) {
        bad_frame(error);
        continue;
      }
      if (png) {
        PackGrayPng(gray.view(), a.png_level, image);
        if (image.data.size() > 4 * pixels) {
          bad_frame("PNG of frame " + std::to_string(frame.seq) + " larger than 4 bytes per pixel");
          continue;
        }
      } else {
        std::copy(gray.pixels.begin(), gray.pixels.end(), image.data.begin());
      }
    }
    image.size = static_cast<std::int32_t>(image.data.size());
    const int length = image.encode(encoded.data(), 0, static_cast<int>(encoded.size()));
    if (length < 0 || bus.publish(channels::kCameraImage, encoded.data(), static_cast<unsigned>(length)) != 0) {
      throw JobFailed("cannot publish frame " + std::to_string(frame.seq) + " on " + channels::kCameraImage);
    }
    const std::int64_t done = MonotonicUs();
    ++published;
    image_bytes += image.data.size();
    if (capture_to_publish_ms.size() < capture_to_publish_ms.capacity()) {
      capture_to_publish_ms.push_back(static_cast<double>(done - frame.monotonic_us) * 1e-3);
      dequeue_to_publish_ms.push_back(static_cast<double>(done - frame.dequeued_monotonic_us) * 1e-3);
    }
    if (a.max_frames > 0 && published >= a.max_frames) break;
  }
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  const double cpu = CpuSeconds() - cpu_start;
  const double wall = static_cast<double>(MonotonicUs() - start) * 1e-6;
  nlohmann::json s;
  s["summary"] = {
      {"device", a.v4l2.device},
      {"format", stream.fourcc},
      {"width", stream.width},
      {"height", stream.height},
      {"fps", stream.fps},
      {"frames", published},
      {"held_back", held_back},
      {"published_as", passthrough ? "MJPEG"
                       : png       ? "PNG"
                                   : "GREY"},
      {"image_bytes_per_frame",
       published > 0 ? static_cast<double>(image_bytes) / static_cast<double>(published) : 0.0},
      {"dropped", camera.dropped()},
      {"skipped", camera.skipped()},
      {"buffer_errors", camera.errors()},
      {"bad_frames", bad},
      {"timeouts", timeouts},
      {"disconnects", disconnects},
      {"reopens", reopens},
      {"seconds", wall},
      {"cpu_ms_per_frame", published > 0 ? cpu * 1e3 / static_cast<double>(published) : 0.0},
      {"cpu_percent", wall > 0 ? 100 * cpu / wall : 0.0},
      // The buffer's timestamp to the end of publish (the driver's timestamp may be ahead of the clock: vivid's
      // end-of-frame stamps are), and from taking the buffer from the driver to the end of publish (this process).
      {"capture_to_publish_ms",
       {{"p50", Percentile(capture_to_publish_ms, 0.5)},
        {"p95", Percentile(capture_to_publish_ms, 0.95)},
        {"max", Percentile(capture_to_publish_ms, 1.0)}}},
      {"dequeue_to_publish_ms",
       {{"p50", Percentile(dequeue_to_publish_ms, 0.5)},
        {"p95", Percentile(dequeue_to_publish_ms, 0.95)},
        {"max", Percentile(dequeue_to_publish_ms, 1.0)}}}};
  std::printf("%s\n", s.dump().c_str());
  if (published == 0) throw JobFailed("no frame was captured from " + a.v4l2.device);
}

}  // namespace

void RegisterCaptureCommand(CLI::App& app) {
  auto a = std::make_shared<CaptureArgs>();
  CLI::App* c = app.add_subcommand(
      "capture",
      "The camera process: read a V4L2 camera (/dev/videoN) and publish its frames as image_t on VISCO_CAMERA_IMAGE "
      "(grey; MJPEG passed through), its calibration (--camera, --extrinsics) as camera_info_t on VISCO_CAMERA_INFO "
      "at start and every --info-period, and its faults (frames dropped, skipped or damaged, no frame in time, "
      "device gone or back) on VISCO_FAULT and as {\"fault\": ...} lines on stdout. Always the newest frame; "
      "image_t.seq is the driver's sequence number (less the frames --max-fps held back), utime the buffer's "
      "capture time. Ends on SIGINT/SIGTERM (or --max-frames, "
      "--duration) with a {\"summary\": ...} line: counts, CPU per frame and capture-to-publish latency. "
      "docs/camera.md.");
  c->add_option("--device", a->v4l2.device, "V4L2 capture device")->capture_default_str();
  c->add_option("--input", a->v4l2.input, "input index to select (VIDIOC_S_INPUT); default: the device's current");
  c->add_option("--width", a->v4l2.width, "image width in pixels (default: the device's current)");
  c->add_option("--height", a->v4l2.height, "image height in pixels (default: the device's current)");
  c->add_option("--pixel-format", a->v4l2.pixel_format,
                "GREY, YUYV or MJPG (default: the first of these the device offers)");
  c->add_option("--fps", a->v4l2.fps, "frame rate (default: the device's current)");
  c->add_option("--exposure", a->v4l2.exposure,
                "manual exposure in the device's unit (V4L2_CID_EXPOSURE_ABSOLUTE, usually 100 us); automatic "
                "exposure is switched off (default: as the device is)");
  c->add_option("--gain", a->v4l2.gain, "manual gain in the device's unit (V4L2_CID_GAIN); automatic gain off");
  c->add_option("--buffers", a->v4l2.buffers, "driver buffers (2..32)")->capture_default_str();
  c->add_option("--timeout-ms", a->v4l2.timeout_ms, "no frame for this long: a fault (repeated while it lasts)")
      ->capture_default_str();
  c->add_option("--reopen-ms", a->v4l2.reopen_interval_ms, "while the device is gone, try to reopen it this often")
      ->capture_default_str();
  c->add_option("--camera", a->camera,
                "calibration to publish beside the images: ViSP XML or OpenCV YAML; its image size must be the "
                "stream's");
  c->add_option("--camera-name", a->camera_name, "camera to use in a multi-camera ViSP XML file");
  c->add_option("--extrinsics", a->extrinsics, "the camera's pose in the world (JSON), published with the calibration");
  c->add_option("--name", a->name, "camera name in image_t.camera (default: the calibration's, else 'camera')");
  c->add_option("--info-period", a->info_period_s, "seconds between VISCO_CAMERA_INFO messages")->capture_default_str();
  c->add_flag("--decode-mjpeg", a->decode_mjpeg, "publish MJPEG frames decoded to grey instead of as they come");
  c->add_option("--png-level", a->png_level,
                "publish the grey frames as PNG (lossless; image_t PIXEL_FORMAT_PNG) at this zlib level, 0..9 (1: "
                "fast): smaller logs for CPU per frame (docs/camera.md); default: raw grey")
      ->check(CLI::Range(0, 9));
  c->add_option("--lcm-url", a->lcm_url, "LCM provider URL (default: LCM's default)");
  c->add_option("--max-fps", a->max_fps,
                "publish at most this many frames per second, the newest each time, for a device whose rate cannot "
                "be set (an HDMI input such as vivid's loop runs at its timings' 59.94 Hz); the frames in between are "
                "counted in the summary's held_back, not published, and not counted in image_t.seq (its gaps stay "
                "frames lost) (0: every frame)")
      ->capture_default_str();
  c->add_option("--max-frames", a->max_frames, "stop after publishing this many frames (0: no limit)");
  c->add_option("--duration", a->duration_s, "stop after this many seconds (0: no limit)");
  c->callback([a] { RunCapture(*a); });
}

}  // namespace visco::vision

// The per-frame work of the camera process (`visco capture`, vision/capture_command.cc) on a 640x480 frame, against
// the baseline of copying the frame once (memcpy), in the same run: the conversion to grey (GREY copied, YUYV's luma,
// MJPEG decoded), image_t's encoding into the reused buffer, and its publication on LCM (UDP multicast, ttl=0, no
// subscriber). Run on the host and in the VM (tests/vision/hil/run_in_vm.sh), it also tells how much the emulated CPU
// (QEMU TCG) slows this work down: docs/camera.md, "Figures". And PNG's cost (encoding at several zlib levels, its
// size, decoding), against the same baseline and raw grey's decoding.

#include <benchmark/benchmark.h>

#include <cstring>
#include <lcm/lcm-cpp.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "tests/vision/sliding_robot_world.h"
#include "visco/image_t.hpp"
#include "vision/image_png.h"
#include "vision/pipeline.h"
#include "vision/v4l2_camera.h"

namespace visco::vision {
namespace {

constexpr int kWidth = 640, kHeight = 480;

const std::vector<std::uint8_t>& Gray() {
  static const std::vector<std::uint8_t> pixels = test_world::SlidingRobotWorld().Render(5).pixels;
  return pixels;
}

std::vector<std::uint8_t> Yuyv() {
  std::vector<std::uint8_t> out(2 * Gray().size());
  for (std::size_t i = 0; i < Gray().size(); ++i) {
    out[2 * i] = Gray()[i];
    out[2 * i + 1] = 128;
  }
  return out;
}

std::vector<std::uint8_t> Jpeg() {
  std::vector<std::uint8_t> out;
  cv::imencode(".jpg", cv::Mat(kHeight, kWidth, CV_8UC1, const_cast<std::uint8_t*>(Gray().data())), out);
  return out;
}

void Convert(benchmark::State& state, V4l2PixelFormat format, const std::vector<std::uint8_t>& bytes) {
  V4l2Stream stream;
  stream.width = kWidth;
  stream.height = kHeight;
  stream.format = format;
  stream.bytes_per_line = format == V4l2PixelFormat::kYuyv ? 2 * kWidth : format == V4l2PixelFormat::kGrey ? kWidth : 0;
  V4l2Frame frame;
  frame.data = bytes.data();
  frame.bytes = bytes.size();
  GrayImage out(kWidth, kHeight);
  std::string error;
  for (auto _ : state) {
    if (!V4l2FrameToGray(stream, frame, out, error)) throw std::runtime_error(error);
    benchmark::DoNotOptimize(out.pixels.data());
  }
  if (format != V4l2PixelFormat::kMjpeg && out.pixels != Gray()) throw std::runtime_error("conversion is wrong");
}

// The baseline: one copy of the frame.
void BM_Memcpy(benchmark::State& state) {
  std::vector<std::uint8_t> out(Gray().size());
  for (auto _ : state) {
    std::memcpy(out.data(), Gray().data(), out.size());
    benchmark::DoNotOptimize(out.data());
  }
}
BENCHMARK(BM_Memcpy);

void BM_GreyToGray(benchmark::State& state) { Convert(state, V4l2PixelFormat::kGrey, Gray()); }
BENCHMARK(BM_GreyToGray);
void BM_YuyvToGray(benchmark::State& state) { Convert(state, V4l2PixelFormat::kYuyv, Yuyv()); }
BENCHMARK(BM_YuyvToGray);
void BM_MjpegToGray(benchmark::State& state) { Convert(state, V4l2PixelFormat::kMjpeg, Jpeg()); }
BENCHMARK(BM_MjpegToGray);

visco::image_t Message() {
  visco::image_t m{};
  m.camera = "camera";
  m.width = kWidth;
  m.height = kHeight;
  m.row_stride = kWidth;
  m.pixel_format = visco::image_t::PIXEL_FORMAT_GRAY8;
  m.data = Gray();
  m.size = static_cast<std::int32_t>(m.data.size());
  return m;
}

void BM_EncodeImage(benchmark::State& state) {
  const visco::image_t m = Message();
  std::vector<std::uint8_t> buffer(static_cast<std::size_t>(m.getEncodedSize()));
  for (auto _ : state) {
    benchmark::DoNotOptimize(m.encode(buffer.data(), 0, static_cast<int>(buffer.size())));
  }
}
BENCHMARK(BM_EncodeImage);

// Encoded and published as `visco capture` does (its own buffer, lcm_publish of the bytes).
void BM_EncodeAndPublishUdpm(benchmark::State& state) {
  lcm::LCM bus("udpm://239.255.76.67:7673?ttl=0");
  if (!bus.good()) {
    state.SkipWithError("no LCM UDP multicast here");
    return;
  }
  const visco::image_t m = Message();
  std::vector<std::uint8_t> buffer(static_cast<std::size_t>(m.getEncodedSize()));
  for (auto _ : state) {
    const int n = m.encode(buffer.data(), 0, static_cast<int>(buffer.size()));
    if (bus.publish("BENCH_CAMERA_IMAGE", buffer.data(), static_cast<unsigned>(n)) != 0) {
      state.SkipWithError("publish failed");
      return;
    }
  }
}
BENCHMARK(BM_EncodeAndPublishUdpm)->UseRealTime();

// Lossless compression (`visco capture --png-level`, `visco sim --png-level`): PNG encoding of the frame at zlib
// levels 0, 1, 3, 6, 9 (the counter `ratio`: raw bytes / PNG bytes), and its decoding as vision does it.
void BM_PngEncode(benchmark::State& state) {
  const GrayImageView view{Gray().data(), kWidth, kHeight, kWidth};
  visco::image_t m{};
  for (auto _ : state) {
    PackGrayPng(view, static_cast<int>(state.range(0)), m);
    benchmark::DoNotOptimize(m.data.data());
  }
  state.counters["ratio"] = static_cast<double>(Gray().size()) / static_cast<double>(m.data.size());
  state.counters["bytes"] = static_cast<double>(m.data.size());
}
BENCHMARK(BM_PngEncode)->Arg(0)->Arg(1)->Arg(3)->Arg(6)->Arg(9);

void BM_PngDecode(benchmark::State& state) {
  visco::image_t m{};
  PackGrayPng({Gray().data(), kWidth, kHeight, kWidth}, static_cast<int>(state.range(0)), m);
  Frame frame;
  std::string error;
  for (auto _ : state) {
    if (!DecodeImageMessage(m, frame, error)) throw std::runtime_error(error);
    benchmark::DoNotOptimize(frame.image.pixels.data());
  }
  if (frame.image.pixels != Gray()) throw std::runtime_error("PNG is not lossless");
}
BENCHMARK(BM_PngDecode)->Arg(1)->Arg(6);

// The baseline of the decoding: vision's taking a raw grey message.
void BM_RawDecode(benchmark::State& state) {
  const visco::image_t m = Message();
  Frame frame;
  std::string error;
  for (auto _ : state) {
    if (!DecodeImageMessage(m, frame, error)) throw std::runtime_error(error);
    benchmark::DoNotOptimize(frame.image.pixels.data());
  }
}
BENCHMARK(BM_RawDecode);

}  // namespace
}  // namespace visco::vision

BENCHMARK_MAIN();

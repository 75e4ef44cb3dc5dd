// visco's V4L2 capture source against the real kernel interface: the vivid driver in the HIL VM (scripts/hil-vm
// --vivid), its output looped back to its capture. Rendered AprilTag frames written to the output come back byte for
// byte with the driver's sequence numbers and timestamps; vivid's error injection (dropped buffers, the buffer error
// flag, no frames at all, a disconnect) each give their fault and the source recovers; bad input is refused with
// what the device offers. The rig (tests/vision/hil/vivid_rig.h) has its own V4L2 code.
//
//   v4l2_hil_test [gtest options]         in the VM; HIL_FRAMES names the frames file
//   v4l2_hil_test --render-frames FILE    on the host: renders the frames (the demo world, robot sliding)
//   v4l2_hil_test --write-frames FILE     in the VM: loops the frames through vivid until SIGTERM
//   v4l2_hil_test --setup-loop            in the VM: vivid's HDMI output looped to its input, 640x480 GREY

#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "common/error.h"
#include "tests/vision/hil/vivid_rig.h"
#include "tests/vision/sliding_robot_world.h"
#include "vision/v4l2_camera.h"

namespace visco::vision {
namespace {

constexpr int kWidth = 640, kHeight = 480;
constexpr std::size_t kFrameBytes = static_cast<std::size_t>(kWidth) * kHeight;

std::vector<std::vector<std::uint8_t>> ReadFrames(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<std::vector<std::uint8_t>> frames;
  std::vector<std::uint8_t> f(kFrameBytes);
  while (in.read(reinterpret_cast<char*>(f.data()), static_cast<std::streamsize>(f.size()))) frames.push_back(f);
  return frames;
}

const std::vector<std::vector<std::uint8_t>>& Frames() {
  static const auto frames = [] {
    const char* path = std::getenv("HIL_FRAMES");
    auto f = ReadFrames(path != nullptr ? path : "");
    if (f.empty()) throw std::runtime_error("no frames: HIL_FRAMES must name the rendered frames file");
    return f;
  }();
  return frames;
}

// YUYV with the grey frame as luma and neutral chroma.
std::vector<std::uint8_t> ToYuyv(const std::vector<std::uint8_t>& gray) {
  std::vector<std::uint8_t> out(2 * gray.size());
  for (std::size_t i = 0; i < gray.size(); ++i) {
    out[2 * i] = gray[i];
    out[2 * i + 1] = 128;
  }
  return out;
}

struct Captured {
  std::vector<std::uint8_t> gray;
  V4l2Frame frame;  // data pointer not valid after the next grab
};

struct Collected {
  std::vector<Captured> frames;
  std::vector<V4l2Fault> faults;
  bool Has(V4l2Fault::Kind k) const {
    return std::any_of(faults.begin(), faults.end(), [k](const V4l2Fault& f) { return f.kind == k; });
  }
};

// Grabs for `seconds` (or until `until` says stop), converting each frame with the source's own conversion.
template <typename Until>
Collected Collect(V4l2Camera& camera, double seconds, Until until) {
  Collected c;
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  V4l2Frame frame;
  V4l2Fault fault;
  GrayImage gray;
  std::string error;
  while (std::chrono::steady_clock::now() < end && !until(c)) {
    const auto status = camera.Grab(100, frame, fault);
    if (status == V4l2Camera::Status::kFault) {
      std::printf("  fault: %s\n", fault.message.c_str());
      c.faults.push_back(fault);
    } else if (status == V4l2Camera::Status::kFrame) {
      EXPECT_TRUE(V4l2FrameToGray(camera.stream(), frame, gray, error)) << error;
      c.frames.push_back({gray.pixels, frame});
    }
  }
  return c;
}
Collected Collect(V4l2Camera& camera, double seconds) {
  return Collect(camera, seconds, [](const Collected&) { return false; });
}

// Every number between the first and the last frame is either delivered or named by exactly one fault (dropped,
// skipped or damaged), and delivered numbers increase.
void ExpectEveryNumberAccountedFor(const Collected& c) {
  ASSERT_FALSE(c.frames.empty());
  std::map<std::int64_t, std::string> seen;
  for (std::size_t i = 0; i < c.frames.size(); ++i) {
    if (i > 0) {
      EXPECT_GT(c.frames[i].frame.seq, c.frames[i - 1].frame.seq);
    }
    seen[c.frames[i].frame.seq] = "delivered";
  }
  std::set<std::int64_t> repeated;  // a number the driver gave twice: one copy delivered, the other reported
  for (const V4l2Fault& f : c.faults) {
    if (f.kind == V4l2Fault::Kind::kRepeated) repeated.insert(f.first_seq);
  }
  for (const V4l2Fault& f : c.faults) {
    if (f.kind != V4l2Fault::Kind::kDropped && f.kind != V4l2Fault::Kind::kSkipped &&
        f.kind != V4l2Fault::Kind::kBufferError) {
      continue;
    }
    if (f.kind == V4l2Fault::Kind::kBufferError && repeated.count(f.first_seq) > 0) continue;
    EXPECT_LE(f.first_seq, f.last_seq);
    for (std::int64_t s = f.first_seq; s <= f.last_seq; ++s) {
      EXPECT_EQ(seen.count(s), 0u) << "frame " << s << " both " << seen[s] << " and in: " << f.message;
      seen[s] = f.message;
    }
  }
  const std::int64_t first = c.frames.front().frame.seq, last = c.frames.back().frame.seq;
  for (std::int64_t s = first; s <= last; ++s) EXPECT_EQ(seen.count(s), 1u) << "frame " << s << " silently lost";
}

// Timestamps: monotonic buffer times, at most a little ahead of the clock when taken (vivid stamps the end of the
// frame, 6-13 ms ahead), mapped to the epoch with the clocks' offset; over the run, the interval per sequence step is
// the frame period within 2% (single steps vary up to twice the period: vivid's thread runs late or early on the
// emulated CPU).
void ExpectTimestamps(const Collected& c, double fps) {
  const double period = 1e6 / fps;
  // The clocks' offset, read where no preemption came between the reads (the shortest bracket of 20 tries).
  std::int64_t offset = 0, bracket = std::numeric_limits<std::int64_t>::max();
  auto us = [](clockid_t clock) {
    timespec ts{};
    clock_gettime(clock, &ts);
    return static_cast<std::int64_t>(ts.tv_sec) * 1000000LL + ts.tv_nsec / 1000;
  };
  for (int i = 0; i < 20; ++i) {
    const std::int64_t before = us(CLOCK_MONOTONIC), real = us(CLOCK_REALTIME), after = us(CLOCK_MONOTONIC);
    if (after - before < bracket) bracket = after - before, offset = real - (before + after) / 2;
  }
  for (std::size_t i = 0; i < c.frames.size(); ++i) {
    const V4l2Frame& f = c.frames[i].frame;
    const std::int64_t age = f.dequeued_monotonic_us - f.monotonic_us;
    EXPECT_GT(age, -25000) << "frame " << f.seq << " stamped " << -age << " us in the future";
    EXPECT_LT(age, 2000000) << "frame " << f.seq << " is " << age << " us old when taken";
    EXPECT_NEAR(static_cast<double>(f.utime - f.monotonic_us), static_cast<double>(offset), 5000.0);
    if (i == 0) continue;
    const V4l2Frame& p = c.frames[i - 1].frame;
    EXPECT_GT(f.monotonic_us, p.monotonic_us) << "frames " << p.seq << " -> " << f.seq;
  }
  const V4l2Frame &first = c.frames.front().frame, &last = c.frames.back().frame;
  const double mean =
      static_cast<double>(last.monotonic_us - first.monotonic_us) / static_cast<double>(last.seq - first.seq);
  std::printf("  mean interval per sequence step %.1f us (period %.1f us)\n", mean, period);
  EXPECT_NEAR(mean, period, 0.02 * period);
}

class LoopBack : public ::testing::TestWithParam<const char*> {};

TEST_P(LoopBack, RenderedFramesComeBackByteForByteNumberedAndTimed) {
  const std::string fourcc = GetParam();
  const bool yuyv = fourcc == "YUYV";
  hil::SetupLoop(yuyv ? V4L2_PIX_FMT_YUYV : V4L2_PIX_FMT_GREY);
  std::vector<std::vector<std::uint8_t>> written;
  for (const auto& f : Frames()) written.push_back(yuyv ? ToYuyv(f) : f);
  hil::OutputWriter writer(written, 3);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the output streams before the capture starts
  V4l2Options o;
  o.input = hil::kHdmiInput;
  o.width = kWidth;
  o.height = kHeight;
  o.pixel_format = fourcc;
  V4l2Camera camera(o);
  EXPECT_EQ(camera.stream().fourcc, fourcc);
  EXPECT_EQ(camera.stream().input_name, "HDMI 0");
  const Collected c = Collect(camera, 4.0);
  std::printf("  %zu frames, %zu faults, %lld frames written\n", c.frames.size(), c.faults.size(),
              static_cast<long long>(writer.written()));
  ASSERT_GE(c.frames.size(), 10u);
  // Byte for byte: each captured frame is one of the written ones.
  std::map<std::vector<std::uint8_t>, int> index;
  for (std::size_t i = 0; i < Frames().size(); ++i) index[Frames()[i]] = static_cast<int>(i);
  std::set<int> shown;
  for (const Captured& f : c.frames) {
    const auto it = index.find(f.gray);
    EXPECT_NE(it, index.end()) << "frame " << f.frame.seq << " is none of the written frames";
    if (it != index.end()) shown.insert(it->second);
  }
  EXPECT_GE(shown.size(), 3u) << "the written frames should change while capturing";
  ExpectEveryNumberAccountedFor(c);
  // The HDMI input's rate is its timings' (640x480p59.94), which G_PARM need not report.
  ExpectTimestamps(c, camera.stream().fps > 0 ? camera.stream().fps : 60000.0 / 1001);
}

INSTANTIATE_TEST_SUITE_P(Formats, LoopBack, ::testing::Values("GREY", "YUYV"));

// The webcam input: vivid draws its test pattern at the rate asked for.
V4l2Options Webcam() {
  V4l2Options o;
  o.input = hil::kWebcamInput;
  o.width = 320;
  o.height = 180;
  o.pixel_format = "GREY";
  o.fps = 10;
  o.timeout_ms = 600;
  return o;
}

TEST(ErrorInjection, DroppedBuffersAreReportedWithTheirNumbers) {
  V4l2Camera camera(Webcam());
  Collect(camera, 0.5);
  hil::SetControl(hil::kCaptureDevice, "percentage_of_dropped_buffers", 50);
  const Collected c = Collect(camera, 3.0);
  hil::SetControl(hil::kCaptureDevice, "percentage_of_dropped_buffers", 0);
  ExpectEveryNumberAccountedFor(c);
  std::int64_t dropped = 0;
  for (const auto& f : c.faults) dropped += f.kind == V4l2Fault::Kind::kDropped ? f.last_seq - f.first_seq + 1 : 0;
  const std::int64_t span = c.frames.back().frame.seq - c.frames.front().frame.seq + 1;
  std::printf("  %lld of %lld frames dropped\n", static_cast<long long>(dropped), static_cast<long long>(span));
  EXPECT_GE(dropped, span / 5);
  // Recovered: frames keep coming.
  EXPECT_GE(Collect(camera, 1.0).frames.size(), 3u);
}

TEST(ErrorInjection, ABufferWithTheErrorFlagIsReportedAndNotDelivered) {
  V4l2Camera camera(Webcam());
  Collect(camera, 0.5);
  hil::SetControl(hil::kCaptureDevice, "inject_v4l2_buf_flag_error", 1);
  const Collected c = Collect(camera, 1.5);
  ExpectEveryNumberAccountedFor(c);
  int errors = 0;
  for (const auto& f : c.faults) {
    if (f.kind != V4l2Fault::Kind::kBufferError) continue;
    ++errors;
    EXPECT_EQ(f.first_seq, f.last_seq);
    EXPECT_NE(f.message.find("frame " + std::to_string(f.first_seq) + " came with the error flag"), std::string::npos);
    EXPECT_LT(f.first_seq, c.frames.back().frame.seq) << "frames follow the damaged one";
  }
  EXPECT_EQ(errors, 1);
  EXPECT_EQ(camera.errors(), 1);
}

TEST(ErrorInjection, NoFramesIsATimeOutAndTheGapIsReportedWhenFramesReturn) {
  V4l2Camera camera(Webcam());
  Collect(camera, 0.5);
  hil::SetControl(hil::kCaptureDevice, "percentage_of_dropped_buffers", 100);
  // Until the time-out (600 ms without a frame), for at most 5 s: on an emulated CPU under load the frames already
  // queued, the control's effect and the wait itself can take longer than a fixed window allowed (it failed once at
  // load 7).
  const Collected stalled = Collect(camera, 5.0, [](const Collected& c) { return c.Has(V4l2Fault::Kind::kTimeout); });
  hil::SetControl(hil::kCaptureDevice, "percentage_of_dropped_buffers", 0);
  ASSERT_TRUE(stalled.Has(V4l2Fault::Kind::kTimeout));
  std::int64_t before = -1;
  for (const auto& f : stalled.faults) {
    if (f.kind == V4l2Fault::Kind::kTimeout) before = f.first_seq;
  }
  EXPECT_GE(before, 0);
  const Collected back = Collect(camera, 5.0, [](const Collected& c) { return c.frames.size() >= 3; });
  ASSERT_GE(back.frames.size(), 3u);
  // The frames that never came are named.
  bool gap = false;
  for (const auto& f : back.faults) {
    if (f.kind == V4l2Fault::Kind::kDropped) {
      gap = true;
      EXPECT_GE(f.first_seq, before + 1);
      EXPECT_EQ(f.last_seq + 1, back.frames.front().frame.seq);
    }
  }
  EXPECT_TRUE(gap);
}

template <typename F>
std::string InputErrorOf(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "no InputError";
}

TEST(BadInput, ClearErrorsListingWhatTheDeviceOffers) {
  auto error = [](V4l2Options o) { return InputErrorOf([&] { V4l2Camera camera(o); }); };
  auto contains = [](const std::string& text, const std::string& part) {
    EXPECT_NE(text.find(part), std::string::npos) << text;
  };
  V4l2Options o = Webcam();
  o.device = "/dev/video7";
  contains(error(o), "/dev/video7: no such device");
  o.device = "/dev/null";
  contains(error(o), "/dev/null: not a V4L2 device");
  o.device = hil::kOutputDevice;
  contains(error(o), "/dev/video1: not a video capture device ('vivid");
  o = Webcam();
  o.input = 5;
  contains(error(o), "input 5: cannot be selected");
  contains(error(o), "0 'Webcam 0', 1 'HDMI 0'");
  o = Webcam();
  o.pixel_format = "MJPG";
  contains(error(o), "pixel format: the device does not offer MJPG (it offers: YUYV");
  o.pixel_format = "RGB3";
  contains(error(o), "'RGB3' is not one visco reads");
  o = Webcam();
  o.width = 333;
  contains(error(o), "format: cannot give GREY 333x180");
  contains(error(o), "offered: 320x180 (");
  o = Webcam();
  o.fps = 7;
  contains(error(o), "frame rate: cannot give 7 fps at GREY 320x180");
  o = Webcam();
  o.exposure = 100;
  contains(error(o), "exposure: the device has no exposure control");
  o = Webcam();
  o.gain = 100000;
  contains(error(o), "gain: 100000 is outside the device's range");
  // A gain in range is set (and automatic gain switched off).
  o.gain = 10;
  EXPECT_EQ(error(o), "no InputError");
}

// Last: the disconnect takes the device away; the module is loaded again as a replugged camera would come back.
TEST(ErrorInjection, ZDisconnectIsReportedAndTheDeviceIsReopenedWhenItComesBack) {
  V4l2Options o = Webcam();
  o.reopen_interval_ms = 200;
  V4l2Camera camera(o);
  Collect(camera, 0.5);
  hil::SetControl(hil::kCaptureDevice, "disconnect", 1);
  const Collected gone = Collect(camera, 3.0, [](const Collected& c) { return c.Has(V4l2Fault::Kind::kDisconnected); });
  ASSERT_TRUE(gone.Has(V4l2Fault::Kind::kDisconnected));
  EXPECT_FALSE(camera.connected());
  const char* params = std::getenv("HIL_VM_VIVID");
  ASSERT_NE(params, nullptr) << "not in the VM of scripts/hil-vm --vivid";
  const std::string reload = std::string("rmmod vivid && modprobe vivid ") + params;
  ASSERT_EQ(std::system(reload.c_str()), 0) << reload;
  const Collected back = Collect(camera, 10.0, [](const Collected& c) { return c.frames.size() >= 3; });
  ASSERT_TRUE(back.Has(V4l2Fault::Kind::kReopened));
  ASSERT_GE(back.frames.size(), 3u);
  EXPECT_LT(back.frames.front().frame.seq, 10) << "the reloaded driver numbers from 0";
  EXPECT_TRUE(camera.connected());
}

}  // namespace
}  // namespace visco::vision

namespace {
std::atomic<bool> g_stop{false};
extern "C" void OnStop(int) { g_stop = true; }
}  // namespace

int main(int argc, char** argv) {
  using visco::vision::kFrameBytes;
  if (argc == 3 && std::string(argv[1]) == "--render-frames") {
    const visco::vision::test_world::SlidingRobotWorld world;
    std::ofstream out(argv[2], std::ios::binary);
    for (int i = 0; i < world.kFrames; ++i) {
      const auto image = world.Render(i);
      out.write(reinterpret_cast<const char*>(image.pixels.data()), static_cast<std::streamsize>(kFrameBytes));
    }
    return out ? 0 : 1;
  }
  if (argc == 2 && std::string(argv[1]) == "--setup-loop") {
    visco::hil::SetupLoop(V4L2_PIX_FMT_GREY);
    // Until the first frame is written the capture shows vivid's test pattern: black (index 5, "100% Black") costs
    // vision nothing, where the colour bars cost it a long full detection on the emulated CPU.
    visco::hil::SetControl(visco::hil::kCaptureDevice, "test_pattern", 5);
    return 0;
  }
  if (argc == 3 && std::string(argv[1]) == "--write-frames") {
    const auto frames = visco::vision::ReadFrames(argv[2]);
    if (frames.empty()) return 2;
    visco::hil::SetupLoop(V4L2_PIX_FMT_GREY);
    std::signal(SIGTERM, OnStop);
    std::signal(SIGINT, OnStop);
    visco::hil::OutputWriter writer(frames, 3);
    while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    std::printf("vivid writer: %lld frames written\n", static_cast<long long>(writer.written()));
    return 0;
  }
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}

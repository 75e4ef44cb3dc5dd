// The pieces of `visco sim`: the motion-model robot behind the real driver logic (leaving the workspace raises the
// driver's bounds fault and stops the robot), the plant of simulated drives over UDP (contact decides the axes'
// positions), and the rendered camera seen by the real vision pipeline (AprilTag
// detection, poses, robot estimate and visual events against the true pose: ground truth), with occlusion, blur
// and noise.

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <deque>
#include <string>
#include <thread>
#include <vector>

#include "app/sim/camera.h"
#include "app/sim/plant.h"
#include "app/sim/world.h"
#include "common/error.h"
#include "drivers/can_protocol.h"
#include "drivers/driver.h"
#include "drivers/driver_transport.h"
#include "drivers/simulated_robot.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "visco/fault_t.hpp"
#include "vision/camera.h"
#include "vision/object_model.h"
#include "vision/pipeline.h"

namespace visco::sim {
namespace {

class FakeTransport final : public drivers::DriverTransport {
 public:
  void Wait(std::int64_t) override {}
  bool NextEvent(std::int64_t now_us, drivers::DriverEvent& out) override {
    if (events.empty()) return false;
    out = events.front();
    out.receive_us = now_us;
    events.pop_front();
    return true;
  }
  drivers::LinkResult SendStatus(const drivers::RobotStatus& status) override {
    last_status = status;
    return drivers::LinkResult::kOk;
  }
  drivers::LinkResult SendHeartbeat(drivers::NmtState) override { return drivers::LinkResult::kOk; }
  drivers::LinkResult SendFault(const drivers::DriverFault& fault) override {
    faults.push_back(fault);
    return drivers::LinkResult::kOk;
  }
  drivers::LinkResult SendSession(std::uint32_t nonce, std::uint32_t) override {
    if (nonce != session) {  // a new session: the controller numbers from 1 in it
      session = nonce;
      next = 1;
    }
    return drivers::LinkResult::kOk;
  }
  std::uint32_t sequence_modulus() const override { return 256; }
  drivers::LinkCounters counters() const override { return {}; }
  // The controller's next command in the driver's current session.
  void Command(double vx, double vy, bool reset = false) {
    drivers::DriverEvent e;
    e.kind = drivers::DriverEventKind::kCommand;
    e.seq = next++;
    e.session = session;
    e.command.velocity[0] = vx;
    e.command.velocity[1] = vy;
    e.command.reset = reset;
    events.push_back(e);
  }
  std::uint32_t session = 0;
  std::uint32_t next = 1;
  std::deque<drivers::DriverEvent> events;
  drivers::RobotStatus last_status;
  std::vector<drivers::DriverFault> faults;
};

TEST(SimulatedRobotInTheScene, LeavingTheBoundsStopsTheRobotWithTheBoundsFault) {
  const planning::Scene scene = planning::LoadScene("data/scenes/slot.json");  // bounds [0, 10] x [0, 8]
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    drivers::SimulatedRobotConfig config;
    config.world = MakeMotionWorld(scene);
    config.start = {9.0, 6.0};
    config.velocity_cone = scene.uncertainty.velocity_cone_rad;
    config.seed = seed;
    drivers::SimulatedRobot robot(config);
    FakeTransport transport;
    drivers::Driver driver(drivers::DriverConfig{}, transport, robot);
    std::int64_t now = 1'000'000;
    driver.Start(now);
    transport.Command(0.0, 0.0, true);  // the driver boots disabled: the controller's reset enables it
    int ms = 0;
    for (; ms < 4000 && driver.state() != drivers::RobotState::kStopped; ++ms) {
      if (ms % 2 == 0) transport.Command(0.5, 0.0);  // towards x = 10 at 0.5 m/s
      now += 1000;
      driver.Update(now);
    }
    ASSERT_EQ(driver.state(), drivers::RobotState::kStopped) << "seed " << seed;
    EXPECT_GT(ms, 1500) << "stopped before reaching the bound";  // 1 m at 0.5 m/s (+ the cone's slowing)
    EXPECT_EQ(driver.stats().bounds_stops, 1U);
    EXPECT_EQ(driver.stats().watchdog_stops, 0U);
    EXPECT_TRUE(driver.fault_bits() & drivers::fault_bits::kBounds);
    ASSERT_FALSE(transport.faults.empty());
    EXPECT_EQ(transport.faults.back().emcy_code, drivers::can::kEmcyBounds);
    EXPECT_EQ(transport.faults.back().code, fault_t::CODE_LIMIT);
    EXPECT_TRUE(transport.faults.back().robot_stopped);
    const drivers::RobotFeedback f = robot.Read();
    EXPECT_NEAR(f.position[0], 10.0, 1e-6);  // held on the border by the motion model
    for (int i = 0; i < 100; ++i) {
      now += 1000;
      driver.Update(now);
    }
    EXPECT_EQ(robot.Read().velocity[0], 0.0);
    EXPECT_EQ(transport.last_status.state, drivers::RobotState::kStopped);
    // After a reset (in the session the stop began) the robot moves back inside; a new episode needs a new exit.
    transport.Command(0.0, 0.0, true);
    for (int i = 0; i < 1000; ++i) {
      if (i % 2 == 0) transport.Command(-0.5, 0.0);
      now += 1000;
      driver.Update(now);
    }
    EXPECT_LT(robot.Read().position[0], 9.8);
    EXPECT_EQ(driver.state(), drivers::RobotState::kMoving);
    EXPECT_EQ(driver.stats().bounds_stops, 1U);
  }
}

// The rendered camera of the default scene's simulation set-up (data/sim), through vision's real pipeline.
struct RenderedSlot {
  RenderedCameraConfig Config() const {
    RenderedCameraConfig c;
    c.calibration_path = "data/sim/slot_camera.xml";
    c.extrinsics_path = "data/sim/slot_extrinsics.json";
    c.objects_path = "data/sim/slot_objects.json";
    c.noise_gray = 2.0;
    c.blur_sigma_px = 0.6;
    c.seed = 11;
    return c;
  }
  vision::PipelineOptions Options() const {
    vision::PipelineOptions o;
    o.tracker.mode = vision::TagTrackingMode::kDetectEveryFrame;
    return o;
  }
  vision::CameraModel camera = vision::LoadCamera("data/sim/slot_camera.xml");
  Eigen::Isometry3d wMc = vision::LoadExtrinsics("data/sim/slot_extrinsics.json");
  vision::ObjectModels models = vision::LoadObjectModels("data/sim/slot_objects.json");
};

TEST(RenderedCamera, VisionFindsTheTruePoseAndOcclusionHidesTheRobot) {
  const RenderedSlot slot;
  RenderedCamera camera(slot.Config());
  vision::VisionPipeline pipeline(slot.camera, slot.wMc, slot.models, slot.Options());
  const std::vector<control::Vec2> path = {{2.0, 5.2}, {3.0, 5.2}, {4.5, 5.0}, {6.0, 4.6},
                                           {5.0, 3.2}, {4.1, 2.1}, {4.1, 1.0}};
  std::int64_t seq = 0;
  double worst = 0;
  for (const control::Vec2 q : path) {
    image_t image;
    const std::int64_t utime = 1'700'000'000'000'000 + seq * 66'000;
    camera.Capture(q, utime, ++seq, {}, image);
    ASSERT_EQ(image.width, 640);
    ASSERT_EQ(image.height, 480);
    ASSERT_EQ(image.pixel_format, image_t::PIXEL_FORMAT_GRAY8);
    ASSERT_EQ(image.size, 640 * 480);
    vision::Frame frame;
    std::string error;
    ASSERT_TRUE(vision::DecodeImageMessage(image, frame, error)) << error;
    const vision::PipelineOutput out = pipeline.Process(frame, utime + 10'000);
    ASSERT_TRUE(out.processed);
    ASSERT_TRUE(out.robot.valid) << "robot not seen at (" << q.x << ", " << q.y << ")";
    const double error_m = std::hypot(out.robot.position[0] - q.x, out.robot.position[1] - q.y);
    worst = std::max(worst, error_m);
    EXPECT_LT(error_m, 0.05) << "at (" << q.x << ", " << q.y << ")";  // the scene's eps_p
    EXPECT_EQ(out.robot.frame_seq, seq);
    EXPECT_EQ(out.robot.utime, utime);
    EXPECT_EQ(out.detections.detections.size(), 3U);  // robot, left, right
    EXPECT_EQ(out.events.events.size(), slot.models.events.size());
  }
  RecordProperty("worst_position_error_mm", static_cast<int>(worst * 1000));

  // Occluded: the frame is processed, the robot is reported lost (estimate invalid, events unknown).
  image_t image;
  camera.Capture({4.5, 5.0}, 1'700'000'000'900'000, ++seq, CaptureConditions{true}, image);
  vision::Frame frame;
  std::string error;
  ASSERT_TRUE(vision::DecodeImageMessage(image, frame, error)) << error;
  const vision::PipelineOutput out = pipeline.Process(frame, 1'700'000'000'910'000);
  EXPECT_FALSE(out.robot.valid);
  EXPECT_EQ(out.detections.detections.size(), 2U);
  for (const auto& e : out.events.events) EXPECT_EQ(e.state, visual_event_t::STATE_UNKNOWN);
}

TEST(RenderedCamera, DeterministicPerSeedAndFrame) {
  const RenderedSlot slot;
  RenderedCamera a(slot.Config()), b(slot.Config());
  image_t ia, ib, ic;
  a.Capture({3.0, 5.0}, 1, 7, {}, ia);
  b.Capture({3.0, 5.0}, 1, 7, {}, ib);
  a.Capture({3.0, 5.0}, 1, 8, {}, ic);
  EXPECT_EQ(ia.data, ib.data);
  EXPECT_NE(ia.data, ic.data);  // the noise of the next frame differs
}

TEST(RenderedCamera, BadFilesAreInputErrors) {
  RenderedSlot slot;
  RenderedCameraConfig c = slot.Config();
  c.objects_path = "data/scenes/slot.json";  // a scene, not object models
  EXPECT_THROW(RenderedCamera{c}, InputError);
  c = slot.Config();
  c.supersample = 0;
  EXPECT_THROW(RenderedCamera{c}, InputError);
}

// A drive of the plant, speaking its wire format (app/sim/plant.h) on its own socket.
class PlantDrive {
 public:
  PlantDrive(int port, int axis) : axis_(axis) {
    fd_ = socket(AF_INET, SOCK_DGRAM, 0);
    to_.sin_family = AF_INET;
    to_.sin_port = htons(static_cast<std::uint16_t>(port));
    inet_pton(AF_INET, "127.0.0.1", &to_.sin_addr);
  }
  ~PlantDrive() { close(fd_); }
  void SendRaw(const void* data, std::size_t size) {
    sendto(fd_, data, size, 0, reinterpret_cast<const sockaddr*>(&to_), sizeof to_);
  }
  // Sends the axis's velocity, returns the plant's answer: position, velocity (false: none within 1 s).
  bool Exchange(double velocity, double& position, double& actual) {
    unsigned char out[16] = {'V', 'P', 'L', '1', static_cast<unsigned char>(axis_)};
    std::memcpy(out + 8, &velocity, 8);
    SendRaw(out, sizeof out);
    pollfd p{fd_, POLLIN, 0};
    if (poll(&p, 1, 1000) != 1) return false;
    unsigned char in[64];
    if (recv(fd_, in, sizeof in, 0) != 24 || std::memcmp(in, "VPL1", 4) != 0 || in[4] != axis_) return false;
    std::memcpy(&position, in + 8, 8);
    std::memcpy(&actual, in + 16, 8);
    return true;
  }

 private:
  int fd_;
  int axis_;
  sockaddr_in to_{};
};

TEST(UdpPlant, TheDrivesVelocitiesMoveTheRobotAndContactStopsIt) {
  // The default scene's world: the peg above the left block (its top face is y = 2 for the reference point).
  drivers::SimulatedRobotConfig config;
  config.world = MakeMotionWorld(planning::LoadScene("data/scenes/slot.json"));
  config.start = {2.0, 2.5};
  config.max_acceleration = 100.0;
  drivers::SimulatedRobot robot(config);
  PlantOptions options;
  options.address = "127.0.0.1:0";  // a free port: tests of other builds may run beside this one
  options.axis_timeout_s = 0.1;
  UdpPlant plant(options, robot);
  std::atomic<bool> stop{false};
  std::thread thread([&] { plant.Run(stop); });
  PlantDrive x(plant.port(), 0), y(plant.port(), 1);
  double px = 0, vx = 0, py = 0, vy = 0;
  ASSERT_TRUE(x.Exchange(0.0, px, vx));
  ASSERT_TRUE(y.Exchange(0.0, py, vy));
  EXPECT_DOUBLE_EQ(px, 2.0);
  EXPECT_DOUBLE_EQ(py, 2.5);
  // Down at 0.5 m/s for 1.6 s: free for 1 s (0.5 m), then against the block's top face.
  double lowest = INFINITY;
  for (auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(1600);
       std::chrono::steady_clock::now() < end;) {
    ASSERT_TRUE(x.Exchange(0.0, px, vx));
    ASSERT_TRUE(y.Exchange(-0.5, py, vy));
    lowest = std::min(lowest, py);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_NEAR(py, 2.0, 1e-6);     // the drive pushes, the block holds: the encoder says so
  EXPECT_GE(lowest, 2.0 - 1e-6);  // never into the block
  EXPECT_NEAR(vy, 0.0, 1e-6);
  EXPECT_NEAR(px, 2.0, 1e-9);
  EXPECT_TRUE(plant.Stats().last.contact);
  // The y drive falls silent: its axis is braked; x slides along the face.
  for (auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(500);
       std::chrono::steady_clock::now() < end;) {
    ASSERT_TRUE(x.Exchange(0.2, px, vx));
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_GT(px, 2.05);
  EXPECT_NEAR(vx, 0.2, 0.02);
  const char junk[5] = {'V', 'P', 'L', '1', 7};
  x.SendRaw(junk, sizeof junk);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  stop.store(true);
  thread.join();
  const PlantStats s = plant.Stats();
  EXPECT_EQ(s.axis_losses, 1u);
  EXPECT_EQ(s.malformed, 1u);
  EXPECT_GT(s.datagrams, 200u);
  EXPECT_NEAR(s.last.position[1], 2.0, 1e-6);
}

TEST(UdpPlant, BadAddressesAreInputErrors) {
  drivers::SimulatedRobot robot;
  for (const char* address : {"47000", "127.0.0.1:", "nohost:47000", "127.0.0.1:70000", "127.0.0.1:-1"}) {
    PlantOptions options;
    options.address = address;
    EXPECT_THROW(UdpPlant(options, robot), InputError) << address;
  }
}

}  // namespace
}  // namespace visco::sim

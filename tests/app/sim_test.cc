// The pieces of `visco sim`: the motion-model robot behind the real driver logic (leaving the workspace raises the
// driver's bounds fault and stops the robot), and the rendered camera seen by the real vision pipeline (AprilTag
// detection, poses, robot estimate and visual events against the true pose: ground truth), with occlusion, blur
// and noise.

#include <gtest/gtest.h>

#include <cmath>
#include <deque>
#include <string>
#include <vector>

#include "app/sim/camera.h"
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
  const RenderedCamera camera(slot.Config());
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
  const RenderedCamera a(slot.Config()), b(slot.Config());
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

}  // namespace
}  // namespace visco::sim

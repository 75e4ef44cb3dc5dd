#pragma once
// `visco sim`: the simulated robot (docs/semantics.md's motion model behind the robot driver of drivers/, over LCM or
// SocketCAN) and a simulated camera. The camera either renders the AprilTags of robot and obstacles from the true
// poses (camera.h) and publishes image_t on VISCO_CAMERA_IMAGE for the real vision pipeline (`visco track
// --lcm`), or -- without object models -- publishes what vision would: visual_events_t for every CVC ray (the
// signed image distance of its CM vertex to its VC line, control/synthetic_camera.h) and robot_estimate_t. Noise, blur,
// latency, frame drops, occlusion, black-outs and stale frames on request. Not real-time code; part of
// visco::sim.

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

#include "app/sim/camera.h"
#include "app/sim/plant.h"
#include "control/synthetic_camera.h"
#include "control/task.h"
#include "drivers/driver.h"
#include "drivers/simulated_robot.h"

namespace visco::sim {

/// A time window of an injected camera fault, seconds after SimSession::Start (start < 0: never).
struct FaultWindow {
  double start_s = -1.0;
  double duration_s = 0.0;
  bool Active(double t) const { return start_s >= 0 && t >= start_s && t < start_s + duration_s; }
};

struct SimOptions {
  std::string scene_path;     // required: the contract's scene file
  std::string rays_path;      // optional: `visco vcrays` output; without it no visual events are published
  std::string lcm_url;        // "" = LCM's default
  std::string can_interface;  // non-empty: the driver listens on SocketCAN instead of LCM
  int node_id = 1;
  bool have_start = false;
  control::Vec2 start;  // metres; default: the centroid of the scene's start region
  // The simulated robot's parameters (seed, adversary, rates); its world, cone and start come from the scene.
  // robot.seed also seeds the camera noise.
  drivers::SimulatedRobotConfig robot;
  double camera_hz = 30.0;
  double latency_s = 0.02;        // capture to publication
  double noise_px = 0.0;          // 1-sigma noise of the signed distances
  double position_noise_m = 0.0;  // 1-sigma noise of the robot estimate (per axis)
  double drop_rate = 0.0;         // probability that a frame is dropped
  double focal_px = 800.0;        // the simulated camera's focal length (pixels per unit tangent)
  double on_line_band_px = 1.0;   // |d| within this reports STATE_ON_LINE
  // Rendered camera: when render.objects_path is set, frames are rendered images (image_t) instead of events.
  RenderedCameraConfig render;
  // Injected camera faults.
  FaultWindow occlude;   // the robot is hidden (rendered camera) / reported not seen (synthetic camera)
  FaultWindow blackout;  // no frames at all
  FaultWindow stale;     // frames carry a capture time `stale_s` in the past
  double stale_s = 0.5;
  drivers::DriverConfig driver;
  // The rendered camera's frames go to this V4L2 video output device (e.g. vivid's, looped back to its capture)
  // instead of onto VISCO_CAMERA_IMAGE: a capture process (`visco capture`) brings them back through V4L2.
  std::string v4l2_output;
  int v4l2_output_index = -1;               // VIDIOC_S_OUTPUT; -1: the device's current output
  std::string v4l2_output_format = "GREY";  // GREY or YUYV
  // The camera alone: no robot and no driver here; the robot is simulated by a driver process (`visco-rt driver
  // --truth-hz`), whose true state (VISCO_SIM_TRUTH of node node_id) the camera renders.
  bool no_driver = false;
  // The robot's plant for simulated drives (plant.h): set, the robot here is moved by the velocities that drives in
  // other processes send over UDP, and no driver runs here.
  PlantOptions plant;
};

struct SimSummary {
  control::Vec2 position;
  bool contact = false;
  std::uint64_t frames = 0;
  std::uint64_t dropped_frames = 0;
  bool rendered = false;
  double mean_render_ms = 0.0;
  std::string v4l2_output;  // the device the frames went to ("" = onto LCM)
  std::uint64_t write_failures = 0;
  drivers::DriverStats driver;
  std::string driver_state;
  bool have_driver = true;  // false: --no-driver (then `truths` counts the truth messages received) or --plant
  std::uint64_t truths = 0;
  bool plant = false;  // --plant: plant_stats says what the drives did
  PlantStats plant_stats;
  std::string ToJson() const;
};

class SimSession {
 public:
  /// Loads the scene (planner's validating loader), builds the motion model, opens the driver's transport.
  /// @throws InputError for a bad scene, rays file or option; JobFailed if LCM / the CAN socket cannot be opened.
  explicit SimSession(const SimOptions& options);
  ~SimSession();
  SimSession(const SimSession&) = delete;
  SimSession& operator=(const SimSession&) = delete;

  /// Starts the driver thread and the camera thread.
  void Start();
  /// Stops both (the robot is left where it is).
  void Stop();
  /// Stops only the driver (a killed driver process: no more status or heartbeat); the camera keeps going.
  void KillDriver();
  /// The operator's e-stop release at the driver (drivers::Driver::RequestOperatorRelease). Async-signal-safe.
  void ReleaseEStop();
  /// Turns the camera off (no frames at all) or on.
  void SetCameraOn(bool on) { camera_on_.store(on); }

  /// Where the robot is and what the driver did, as of the driver's last update. Any thread, also while the session
  /// runs (through drivers::Driver::Snapshot; the driver's thread is never blocked).
  SimSummary Summary() const;
  const control::Task& rays() const { return rays_; }

 private:
  struct Impl;
  void CameraLoop();
  void WriteToDevice(const image_t& image, std::int64_t render_utime);
  std::unique_ptr<Impl> impl_;
  control::Task rays_;  // the CVC rays with robot vertex offsets (for the synthetic camera)
  SimOptions options_;
  std::atomic<bool> stop_driver_{false};
  std::atomic<bool> stop_camera_{false};
  std::atomic<bool> camera_on_{true};
  std::atomic<std::uint64_t> frames_{0};
  std::atomic<std::uint64_t> dropped_{0};
  std::atomic<std::uint64_t> render_us_{0};
  std::atomic<std::uint64_t> write_failures_{0};
  std::thread driver_thread_;
  std::thread camera_thread_;
};

}  // namespace visco::sim

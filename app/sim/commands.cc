#include "app/sim/commands.h"

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <memory>
#include <thread>
#include <utility>
#include <vector>

#include "app/sim/lockstep.h"
#include "app/sim/session.h"
#include "app/sim/world.h"
#include "common/error.h"
#include "common/event_log.h"
#include "common/stop_signals.h"
#include "common/write_output.h"
#include "control/run.h"
#include "drivers/commands.h"
#include "drivers/simulated_robot_options.h"
#include "planning/scene.h"
#include "planning/scene_file.h"

namespace visco::sim {
namespace {

std::atomic<bool> g_stop{false};  // SIGINT, SIGTERM

struct SimCli {
  SimOptions sim;
  drivers::SimulatedRobotOptions robot;  // its world, cone and start come from the scene
  std::vector<double> start;
  double latency_ms = 20;
  drivers::DriverOptions driver;
  double duration_s = 0;
  std::vector<double> occlude, blackout, stale;
  double stale_ms = 500;
  std::string log;
  std::string write_world;
  bool lockstep = false;
  std::string strategy;
  double plant_period_ms = 1.0;
  double plant_axis_timeout_ms = 100.0;
};

FaultWindow Window(const std::vector<double>& v, const char* option) {
  if (v.empty()) return {};
  if (!(v[0] >= 0) || !(v[1] > 0)) {
    throw InputError("command line", option, "give START and DURATION in seconds, START >= 0, DURATION > 0");
  }
  return {v[0], v[1]};
}

// --lockstep: the closed loop in this process on a simulated clock (app/sim/lockstep.h).
void RunLockstepSim(SimCli& cli) {
  const SimOptions& s = cli.sim;
  // What only a live run has: another process's robot, a real bus, CAN, injected camera faults.
  const std::pair<bool, const char*> refused[] = {{s.no_driver, "--no-driver"},
                                                  {!s.can_interface.empty(), "--can"},
                                                  {!s.lcm_url.empty(), "--lcm-url"},
                                                  {!cli.occlude.empty(), "--occlude"},
                                                  {!cli.blackout.empty(), "--blackout"},
                                                  {!cli.stale.empty(), "--stale"},
                                                  {s.drop_rate != 0, "--drop-rate"},
                                                  {!s.plant.address.empty(), "--plant"},
                                                  {!s.v4l2_output.empty(), "--v4l2-output"}};
  for (const auto& [given, option] : refused) {
    if (given) {
      throw InputError("command line", option,
                       "not with --lockstep (one process on a simulated clock: its bus is private, its camera has "
                       "no injected faults)");
    }
  }
  LockstepOptions o;
  o.scene_path = s.scene_path;
  o.strategy_path = cli.strategy;
  o.rays_path = s.rays_path;
  if (!cli.start.empty()) {
    o.have_start = true;
    o.start = {cli.start[0], cli.start[1]};
  }
  o.robot = cli.robot.robot;
  o.driver = drivers::ToDriverConfig(cli.driver);
  o.node_id = cli.driver.node;
  o.render = s.render;
  o.camera_hz = s.camera_hz;
  o.latency_s = cli.latency_ms / 1000.0;
  o.max_duration_s = cli.duration_s > 0 ? cli.duration_s : o.max_duration_s;
  std::unique_ptr<EventLogTap> log = OpenEventLogFile(cli.log);
  o.log = log.get();
  StopOnSignals(g_stop);
  o.stop = &g_stop;
  const LockstepResult result = RunLockstep(o);
  std::printf("%s\n", result.ToJson().c_str());
  std::fflush(stdout);
  if (log) {
    const std::string report = log->Close();
    std::fprintf(stderr, "sim: %s\n", report.c_str());
    if (report.find("; 0 dropped") == std::string::npos) throw JobFailed("the lockstep log is incomplete: " + report);
  }
  if (!result.reached()) {
    throw JobFailed(result.mode == control::Mode::kDone
                        ? "the controller recognised the goal, but the robot is not in it"
                        : "run stopped: " + result.reason);
  }
}

void RunSim(SimCli& cli) {
  drivers::LogToStderr();  // stdout carries only the JSON summary
  if (cli.lockstep) {
    RunLockstepSim(cli);
    return;
  }
  if (!cli.strategy.empty()) throw InputError("command line", "--strategy", "only with --lockstep");
  SimOptions& o = cli.sim;
  o.robot = cli.robot.robot;
  if (!cli.write_world.empty()) {
    // The scene's physics for a driver process (`visco-rt driver --world`), which links no planner.
    drivers::WorldFile world = MakeWorldFile(planning::LoadScene(o.scene_path));
    if (!cli.start.empty()) {
      world.have_start = true;
      world.start = {cli.start[0], cli.start[1]};
    }
    WriteTextOutput(drivers::WorldFileJson(world), cli.write_world);
    return;
  }
  if (!cli.start.empty()) {
    o.have_start = true;
    o.start = {cli.start[0], cli.start[1]};
  }
  o.latency_s = cli.latency_ms / 1000.0;
  o.occlude = Window(cli.occlude, "--occlude");
  o.blackout = Window(cli.blackout, "--blackout");
  o.stale = Window(cli.stale, "--stale");
  o.stale_s = cli.stale_ms / 1000.0;
  o.plant.period_s = cli.plant_period_ms / 1000.0;
  o.plant.axis_timeout_s = cli.plant_axis_timeout_ms / 1000.0;
  const RenderedCameraConfig& r = o.render;
  if (!r.objects_path.empty() && (r.calibration_path.empty() || r.extrinsics_path.empty())) {
    throw InputError("command line", "--objects", "the rendered camera also needs --camera and --extrinsics");
  }
  if (r.objects_path.empty() && (!r.calibration_path.empty() || !r.extrinsics_path.empty())) {
    throw InputError("command line", "--camera", "give --objects too (the models of what the camera renders)");
  }
  o.driver = drivers::ToDriverConfig(cli.driver);
  o.node_id = cli.driver.node;
  std::unique_ptr<EventLogTap> log = OpenEventLog(cli.log, o.lcm_url);
  SimSession session(o);
  StopOnSignals(g_stop);
  // SIGUSR1: the operator's e-stop release at the simulated robot's driver (drivers/README.md).
  ReleaseOnSignal([](void* s) { static_cast<SimSession*>(s)->ReleaseEStop(); }, &session);
  session.Start();
  const auto start = std::chrono::steady_clock::now();
  while (!g_stop.load()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if (cli.duration_s > 0 &&
        std::chrono::steady_clock::now() - start > std::chrono::duration<double>(cli.duration_s)) {
      break;
    }
  }
  IgnoreReleaseSignal();
  session.Stop();
  std::printf("%s\n", session.Summary().ToJson().c_str());
  std::fflush(stdout);
  if (log) std::fprintf(stderr, "sim: %s\n", log->Close().c_str());
}

}  // namespace

void RegisterCommands(CLI::App& app) {
  auto cli = std::make_shared<SimCli>();
  SimOptions& o = cli->sim;
  CLI::App* cmd = app.add_subcommand(
      "sim",
      "Simulated robot and camera for `visco run`: the robot driver (LCM, or SocketCAN with --can) drives a robot "
      "that obeys docs/semantics.md's motion model (actual direction inside the velocity cone chosen by a seeded "
      "random "
      "adversary, Coulomb friction on the C-obstacles, sticking, bounds, a workspace-bounds fault when it leaves "
      "them). The simulated camera either renders the AprilTags of robot and obstacles from the true poses "
      "(--objects, --camera, --extrinsics: the files of `visco track`) and publishes image_t on "
      "VISCO_CAMERA_IMAGE for the vision pipeline (`visco track --lcm`), with blur, image noise and frame drops on "
      "request; or, without --objects, publishes VISCO_VISUAL_EVENTS (signed image distance of each CVC ray's CM "
      "vertex to its VC line) and VISCO_ROBOT_ESTIMATE directly. Camera faults can be injected (--occlude, "
      "--blackout, --stale). A latched e-stop is released by the operator with SIGUSR1. Runs until SIGINT/SIGTERM or "
      "--duration; prints a JSON summary on exit.");
  cmd->add_option("scene", o.scene_path, "scene file (docs/formats.md)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--rays", o.rays_path,
                  "synthetic events: `visco vcrays` output, the CVC rays to report visual events for")
      ->check(CLI::ExistingFile);
  cmd->add_option("--start", cli->start, "initial reference point X Y, metres (default: the start region's centroid)")
      ->expected(2);
  drivers::AddSimulatedRobotOptions(*cmd, cli->robot, /*with_world=*/false);  // --seed also seeds the camera noise
  cmd->add_option("--lcm-url", o.lcm_url, "LCM provider URL (LCM's default when empty)");
  cmd->add_option("--log", cli->log,
                  "write an LCM event log (lcm-logger format) of the bus: every channel it publishes and receives "
                  "(needs a udpm:// bus; with --lockstep: every message of its private bus, the controller's period "
                  "records and configuration, stamped with the simulated time; docs/replay.md)");
  cmd->add_option("--can", o.can_interface, "the driver listens on this SocketCAN interface instead of LCM");
  drivers::AddDriverOptions(*cmd, cli->driver);  // the same options as `visco driver`
  cmd->add_option("--camera-hz", o.camera_hz, "camera frame rate, Hz")->capture_default_str();
  cmd->add_option("--latency-ms", cli->latency_ms, "capture-to-publication latency, ms")->capture_default_str();
  cmd->add_option("--noise-px", o.noise_px, "synthetic events: 1-sigma noise of the signed image distances, px")
      ->capture_default_str();
  cmd->add_option("--position-noise", o.position_noise_m, "synthetic events: 1-sigma noise of the robot estimate, m")
      ->capture_default_str();
  cmd->add_option("--drop-rate", o.drop_rate, "probability of dropping a frame (both camera kinds)")
      ->capture_default_str();
  cmd->add_option("--focal-px", o.focal_px,
                  "synthetic events only: the planar camera's focal length, px (give `visco run` the same --focal-px; "
                  "the rendered camera's comes from --camera)")
      ->capture_default_str();
  cmd->add_option("--objects", o.render.objects_path,
                  "render images: vision's object models (robot and obstacles with their AprilTags; obstacle "
                  "polygons in world coordinates, the robot in its own frame)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--camera", o.render.calibration_path, "rendered camera: calibration (ViSP XML or OpenCV YAML)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--camera-name", o.render.camera_name, "rendered camera: camera in a multi-camera file");
  cmd->add_option("--extrinsics", o.render.extrinsics_path, "rendered camera: camera pose wMc (JSON)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--blur-px", o.render.blur_sigma_px, "rendered camera: Gaussian blur sigma, px")
      ->capture_default_str();
  cmd->add_option("--image-noise", o.render.noise_gray, "rendered camera: 1-sigma pixel noise, grey levels")
      ->capture_default_str();
  cmd->add_option("--supersample", o.render.supersample, "rendered camera: sub-samples per pixel side")
      ->capture_default_str();
  cmd->add_option("--png-level", o.render.png_level,
                  "rendered camera: publish its frames as PNG (lossless; image_t PIXEL_FORMAT_PNG) at this zlib level, "
                  "0..9 (what it costs and saves: docs/camera.md); default: raw grey")
      ->check(CLI::Range(0, 9));
  cmd->add_option("--v4l2-output", o.v4l2_output,
                  "rendered camera: write its frames to this V4L2 video output device (e.g. /dev/video1, vivid's "
                  "output looped back to its capture) instead of publishing them: `visco capture` brings them back "
                  "through the kernel's capture path. Each frame written is recorded on VISCO_SIM_FRAME (its pixel "
                  "digest, render and write times). Not with --png-level, --drop-rate, --blackout, --stale "
                  "(docs/camera.md)");
  cmd->add_option("--v4l2-output-index", o.v4l2_output_index,
                  "with --v4l2-output: the device's output to select (VIDIOC_S_OUTPUT; default: its current one)");
  cmd->add_option("--v4l2-output-format", o.v4l2_output_format,
                  "with --v4l2-output: the pixel format written, GREY or YUYV (the capture must ask for the same)")
      ->capture_default_str()
      ->check(CLI::IsMember({"GREY", "YUYV"}));
  cmd->add_option("--occlude", cli->occlude,
                  "fault: hide the robot from the camera from START for DURATION seconds (after start-up)")
      ->expected(2);
  cmd->add_option("--blackout", cli->blackout, "fault: no camera frames from START for DURATION seconds")->expected(2);
  cmd->add_option("--stale", cli->stale, "fault: frames from START for DURATION seconds carry an old capture time")
      ->expected(2);
  cmd->add_option("--stale-ms", cli->stale_ms, "age of the stale frames' capture time, ms")->capture_default_str();
  cmd->add_flag("--no-driver", o.no_driver,
                "the camera alone: the robot and its driver run in another process (`visco-rt driver --world FILE "
                "--truth-hz HZ`), whose true state on VISCO_SIM_TRUTH the camera renders (node --node)")
      ->excludes("--can");
  const std::string plant_group = "Plant of simulated drives (app/sim/plant.h, docs/your_own_robot.md)";
  cmd->add_option("--plant", o.plant.address,
                  "the robot is moved by simulated drives in other processes instead of a driver here: listen on "
                  "UDP HOST:PORT for each axis's actual velocity (the drives'), step the robot's physics with it "
                  "(the scene's C-obstacles, friction, the velocity cone) and answer each drive with its axis's "
                  "position and velocity (its encoder); the camera renders the robot there")
      ->excludes("--can")
      ->excludes("--no-driver")
      ->group(plant_group);
  cmd->add_option("--plant-period-ms", cli->plant_period_ms, "the plant's physics step, ms")
      ->capture_default_str()
      ->group(plant_group);
  cmd->add_option("--plant-axis-timeout-ms", cli->plant_axis_timeout_ms,
                  "an axis whose drive sent nothing for this long is commanded 0 (braked), ms")
      ->capture_default_str()
      ->group(plant_group);
  cmd->add_option("--plant-trace", o.plant.trace_path,
                  "write the robot's state every 10 ms to FILE: lines \"t x y vx vy contact\" (t: CLOCK_MONOTONIC "
                  "seconds)")
      ->group(plant_group);
  cmd->add_option("--write-world", cli->write_world,
                  "write the scene's world file (C-obstacles, bounds, friction, velocity cone; the start with "
                  "--start) for `visco-rt driver --world`, and exit");
  cmd->add_option("--duration", cli->duration_s,
                  "stop after this many seconds (0: until a signal; --lockstep: simulated seconds, then an e-stop, "
                  "0: 120)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--lockstep", cli->lockstep,
                "the whole closed loop of `visco demo` in this one process, on one thread, on a simulated clock: the "
                "driver and the simulated robot, the rendered camera (--objects, --camera, --extrinsics), the vision "
                "pipeline of `visco track` and the controller of `visco run` (--strategy, --rays; the demo's "
                "settings), talking LCM on a private in-process bus. Nothing reads the wall clock and nothing runs "
                "concurrently, so the same options and --seed give the same messages bit for bit. --log writes "
                "every message, the controller's period records and its configuration, stamped with the simulated "
                "time: `visco replay LOG --check` replays it. Runs until the strategy ends (or --duration); exit 0 "
                "only when the controller recognised the goal and the robot is in it (docs/replay.md)")
      ->excludes("--write-world");
  cmd->add_option("--strategy", cli->strategy, "--lockstep: the motion strategy to execute (`visco plan` output)")
      ->check(CLI::ExistingFile);
  cmd->callback([cli] { RunSim(*cli); });
}

}  // namespace visco::sim

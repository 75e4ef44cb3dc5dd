#pragma once
// One closed-loop run of the demo: the driver (visco-rt) with the simulated robot, the camera, vision, the controller
// and lcm-logger as processes on one LCM bus (or `visco sim --lockstep`, one process on a simulated clock),
// supervised until the controller ends, the run's time-out, a process that ends early, or Ctrl-C; then the run's
// outcome from what they wrote and the log.

#include <Eigen/Core>
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "app/demo/trace.h"
#include "app/netns_hosts.h"
#include "planning/cspace.h"
#include "planning/scene.h"
#include "planning/strategy.h"

namespace visco::app::demo {

// The command line of `visco demo`.
struct Options {
  std::string out;
  std::string scene;
  std::uint64_t seed = 1;
  bool can = false;
  int runs = 1;
  int jobs = 1;
  bool keep_logs = false;
  double timeout_s = 120;
  double speed = 0.6;
  bool netns = false;
  bool lockstep = false;   // one process on a simulated clock (`visco sim --lockstep`) instead of the five
  double slow = 1;         // --slow-machine: time limits times this, camera rate and speed divided by it
  int png_level = -1;      // >= 0: the rendered camera publishes PNG at this zlib level
  double image_noise = 2;  // the rendered camera's pixel noise (grey levels, 1 sigma) and blur (pixels)
  double blur_px = 0.5;
  std::string plan;           // a strategy made earlier for the scene (plan.json): no planning
  std::vector<double> start;  // X Y: the run starts there instead of a start drawn from the start region
  // The camera through the kernel's video interface: the rendered frames written to a V4L2 output device
  // (`visco sim --v4l2-output`), captured from a capture device that shows them (`visco capture`: vivid's loop).
  std::string v4l2_output, v4l2_capture;
  int v4l2_input = -1;  // the capture device's input (vivid's HDMI input: 1)
};

// What every run of one demo shares.
struct Setup {
  const Options* options = nullptr;
  const planning::Scene* scene = nullptr;
  const planning::CSpace* cspace = nullptr;
  const planning::Strategy* strategy = nullptr;
  std::filesystem::path dir;  // scene.json, world.json, rays.json and plan.json are here
  std::string self;           // this visco executable
  std::string rt;             // visco-rt beside it (the driver process)
  bool rendered = false;
  std::vector<std::string> cam;             // camera files of the rendered default scene
  int image_width = 0, image_height = 0;    // the rendered camera's image size (its calibration's)
  const std::atomic<bool>* stop = nullptr;  // Ctrl-C: no new run, the running one stopped
};

struct RunOutcome {
  nlohmann::json item;  // the run's entry of summary.json
  Trace trace;
  bool ok = false;  // the controller recognised the goal and the robot is in it
};

/// Run `r` (seed `seed`, from `start`), its files in `rd`, its processes on the LCM bus `url`. With `hosts`, each
/// process runs on a host of its own (a network namespace; NetnsHosts). `print` guards stderr between jobs.
RunOutcome ExecuteRun(const Setup& su, int r, std::uint64_t seed, const Eigen::Vector2d& start,
                      const std::filesystem::path& rd, const std::string& url, const NetnsHosts* hosts,
                      std::mutex& print);

}  // namespace visco::app::demo

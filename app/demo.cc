// `visco demo`: the whole system on the embedded default scene (or --scene FILE). It plans (`visco plan`), then
// executes the strategy in closed loop as separate processes talking LCM, as on real hardware:
//   visco-rt driver  the robot driver driving the simulated robot (drivers/simulated_robot.h: the motion model of
//                docs/semantics.md with a seeded adversary) among the scene's C-obstacles (DIR/world.json), with
//                the robot's true state on VISCO_SIM_TRUTH;
//   visco sim --no-driver  the rendered camera (the AprilTags of robot and obstacles at that true state, as images);
//   visco track  the vision pipeline (detection, tracking, poses, CM vertices, visual events);
//   visco run    the controller (visual guarded and compliant motions, contact, goal);
//   lcm-logger   every channel into DIR/run.lcmlog.
// The demo supervises them: Ctrl-C or any failure stops all of them (they also die with the demo: PR_SET_PDEATHSIG).
// Outputs in DIR: scene.json, world.json, rays.json, plan.json, plan.svg, run.svg, run.lcmlog, summary.json, and each
// process's output and log.

#include "app/demo.h"

#include <fmt/format.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "app/demo/closed_loop.h"
#include "app/demo/monte_carlo.h"
#include "app/demo/pictures.h"
#include "app/demo/processes.h"
#include "app/netns_hosts.h"
#include "app/paths.h"
#include "app/sim/world.h"
#include "common/error.h"
#include "common/stop_signals.h"
#include "common/write_output.h"
#include "drivers/simulated_robot_options.h"
#include "planning/cspace.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "planning/strategy.h"
#include "planning/vc_rays.h"
#include "vision/camera.h"

#ifndef VISCO_SOURCE_DATA_DIR
#define VISCO_SOURCE_DATA_DIR "data"
#endif

namespace visco::app {
namespace {

using namespace demo;  // NOLINT: this file is the demo's command
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// Ctrl-C (SIGINT) or SIGTERM: no new run starts, the running ones are stopped, exit 130.
std::atomic<bool> g_stop{false};

// Absolute: the parameter files and summary.json name the outputs, and must work from any directory.
fs::path FreshDir(const std::string& requested) {
  if (!requested.empty()) {
    fs::create_directories(requested);
    return fs::absolute(requested).lexically_normal();
  }
  for (int k = 1;; ++k) {
    const fs::path p = fmt::format("visco-demo-{}", k);
    if (!fs::exists(p)) {
      fs::create_directories(p);
      return fs::absolute(p).lexically_normal();
    }
  }
}

void Progress(const char* what) {
  std::fprintf(stderr, "visco demo: %s\n", what);
  std::fflush(stderr);
}

// The options' checks: a clear error before anything runs.
void CheckOptions(const Options& a) {
  if (a.runs < 1) throw InputError("command line", "--runs", "must be at least 1");
  if (!(a.speed > 0) || a.speed > 1.0) throw InputError("command line", "--speed", "must be in (0, 1] m/s");
  if (!(a.slow >= 1) || a.slow > 100) throw InputError("command line", "--slow-machine", "must be in [1, 100]");
  if (a.jobs < 1 || a.jobs > 8) throw InputError("command line", "--jobs", "must be between 1 and 8");
  if (!(a.image_noise >= 0)) throw InputError("command line", "--image-noise", "must be >= 0");
  if (!(a.blur_px >= 0)) throw InputError("command line", "--blur-px", "must be >= 0");
  if (a.lockstep && (a.can || a.netns)) {
    throw InputError("command line", a.can ? "--can" : "--netns",
                     "not with --lockstep (one process on a simulated clock, its bus in memory)");
  }
  if (a.lockstep && !a.scene.empty()) {
    throw InputError("command line", "--lockstep",
                     "runs the rendered camera, which only the embedded default scene has (data/sim/); not with "
                     "--scene");
  }
  if (a.can && !fs::exists("/sys/class/net/vcan0")) {
    throw InputError("command line", "--can",
                     "no vcan0 interface on this machine: create one (modprobe vcan; ip link add vcan0 type vcan; ip "
                     "link set up vcan0) or use the HIL VM (README, \"Hardware-in-the-loop on virtual CAN\")");
  }
  if (a.can && a.jobs > 1) throw InputError("command line", "--jobs", "runs over --can share vcan0: use --jobs 1");
  if (a.v4l2_output.empty() != a.v4l2_capture.empty()) {
    throw InputError("command line", a.v4l2_output.empty() ? "--v4l2-capture" : "--v4l2-output",
                     "give both --v4l2-output and --v4l2-capture (the device the frames are written to and the one "
                     "that shows them)");
  }
  if (!a.v4l2_output.empty()) {
    if (a.lockstep)
      throw InputError("command line", "--v4l2-output", "not with --lockstep (the devices run on the wall clock)");
    if (!a.scene.empty()) {
      throw InputError("command line", "--v4l2-output",
                       "needs the rendered camera, which only the embedded default scene has (data/sim/); not with "
                       "--scene");
    }
    if (a.jobs > 1) throw InputError("command line", "--jobs", "runs through one video device: use --jobs 1");
  }
  if (!a.start.empty() && a.runs > 1) throw InputError("command line", "--start", "one run only (not with --runs)");
  if (!a.plan.empty() && a.runs > 1) throw InputError("command line", "--plan", "one run only (not with --runs)");
  if (a.netns) {
    std::string why;
    if (!NetnsHosts::Available(&why)) throw InputError("command line", "--netns", why);
    if (a.can)
      throw InputError("command line", "--netns", "cannot be combined with --can (vcan0 lives in one namespace)");
  }
}

// The plan and its files in `dir` (scene.json, rays.json, plan.json, plan.svg), as `visco vcrays` and `visco plan`
// write them. @throws visco::JobFailed when there is no strategy (plan.json says why).
struct Plan {
  planning::Scene scene;
  std::unique_ptr<planning::CSpace> cspace;
  planning::Strategy strategy;  // with --plan: only its step count
  bool given = false;           // --plan
};
Plan MakePlan(const Options& a, const fs::path& dir) {
  // The scene: the embedded default (no file needed) or the user's.
  std::string scene_text = a.scene.empty() ? std::string(planning::DefaultSceneJson()) : ReadText(a.scene);
  if (!a.scene.empty() && scene_text.empty()) throw InputError(a.scene, "", "cannot read the scene file");
  Plan plan;
  plan.scene = a.scene.empty() ? planning::DefaultScene() : planning::LoadScene(a.scene);
  const planning::Scene& scene = plan.scene;
  if (!scene.start)
    throw InputError(a.scene.empty() ? "<embedded slot.json>" : a.scene, "start", "the demo needs a start region");
  if (!a.start.empty()) {
    if (!scene.bounds.Contains(planning::Point(a.start[0], a.start[1]))) {
      throw InputError("command line", "--start", "must lie within the scene's bounds");
    }
  }
  WriteTextOutput(scene_text, (dir / "scene.json").string());
  plan.cspace = std::make_unique<planning::CSpace>(scene);
  const planning::CSpace& cspace = *plan.cspace;
  planning::VcRays rays;
  if (scene.camera) rays = planning::ComputeVcRays(scene, cspace);
  WriteTextOutput(planning::VcRaysToJson(scene, rays), (dir / "rays.json").string());

  if (!a.plan.empty()) {
    // A strategy made earlier (`visco plan`, or an earlier demo's plan.json): `visco run` checks that it was made
    // for this scene. Only its step count is read here: no plan.svg, no run.svg.
    const std::string text = ReadText(a.plan);
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(text);
    } catch (const std::exception& e) {
      throw InputError(a.plan, "", std::string("not JSON: ") + e.what());
    }
    if (!j.is_object() || !j.value("feasible", false) || !j.contains("steps") || !j["steps"].is_array()) {
      throw InputError(a.plan, "steps", "not a feasible strategy (`visco plan` output)");
    }
    plan.strategy.feasible = true;
    plan.strategy.steps.resize(j["steps"].size());
    plan.given = true;
    WriteTextOutput(text, (dir / "plan.json").string());
    return plan;
  }
  Progress("planning (visco plan)");
  planning::PlanOptions po;
  po.threads = 2;
  plan.strategy = planning::PlanStrategy(scene, po);
  const planning::Strategy& strategy = plan.strategy;
  WriteTextOutput(planning::StrategyToJson(scene, strategy, a.speed / a.slow), (dir / "plan.json").string());
  WriteTextOutput(planning::StrategyToSvg(scene, cspace, strategy), (dir / "plan.svg").string());
  if (!strategy.feasible) throw JobFailed("no strategy: " + strategy.reason);
  return plan;
}

// The runs, `a.jobs` at a time, each job on its own LCM port (and, with --netns, its own hosts). Runs not started
// because of Ctrl-C are not in the result.
std::vector<RunOutcome> ExecuteRuns(const Options& a, const Setup& su) {
  const fs::path& dir = su.dir;
  // Starts are drawn before any run, so the outcome of run k does not depend on --jobs.
  std::vector<Eigen::Vector2d> starts = SampleStarts(su.scene->start->polygon, a.runs, a.seed);
  if (!a.start.empty()) starts[0] = Eigen::Vector2d(a.start[0], a.start[1]);
  std::vector<RunOutcome> outcomes(static_cast<size_t>(a.runs));
  std::vector<bool> finished(static_cast<size_t>(a.runs), false);
  std::atomic<int> next{0};
  std::mutex print;
  int completed = 0, successes = 0;
  // --netns: per job, a host per process (made here, on the main thread: a failure is an error, not a crash).
  std::vector<std::unique_ptr<NetnsHosts>> job_hosts(static_cast<size_t>(std::min(a.jobs, a.runs)));
  if (a.netns) {
    for (size_t j = 0; j < job_hosts.size(); ++j) {
      job_hosts[j] = std::make_unique<NetnsHosts>(
          fmt::format("visco{}j{}", getpid(), j),
          std::vector<std::string>{"robot", "camera", "vision", "controller", "logger"}, static_cast<int>(j) + 1);
    }
    std::fprintf(stderr,
                 "visco demo: every process on a host of its own (network namespaces such as %s at %s, LCM "
                 "multicast over a bridge, ttl=1)\n",
                 job_hosts[0]->Namespace("robot").c_str(), job_hosts[0]->Address("robot").c_str());
  }
  auto worker = [&](int job) {
    // Each job talks on its own multicast port, so simultaneous runs do not hear each other. Across hosts the
    // datagrams must leave the host: ttl=1 (one link; ttl=0 keeps them on the host).
    const std::string url =
        fmt::format("udpm://239.255.76.67:{}?ttl={}", 20000 + (getpid() % 5000) * 8 + job, a.netns ? 1 : 0);
    const NetnsHosts* hosts = job_hosts[static_cast<size_t>(job)].get();
    if (!a.lockstep) {  // (a lockstep run's bus is in its process's memory)
      std::lock_guard<std::mutex> lock(print);
      std::fprintf(stderr, "visco demo: %s talks LCM on %s (watch it: visco spy --lcm-url '%s')\n",
                   a.runs == 1 ? "the run" : fmt::format("job {}", job + 1).c_str(), url.c_str(), url.c_str());
    }
    for (int r = next++; r < a.runs && !g_stop; r = next++) {
      const std::uint64_t seed = a.seed + static_cast<std::uint64_t>(r);
      const fs::path rd = a.runs == 1 ? dir : dir / fmt::format("run{:03d}", r);
      RunOutcome o = ExecuteRun(su, r, seed, starts[static_cast<size_t>(r)], rd, url, hosts, print);
      std::lock_guard<std::mutex> lock(print);
      ++completed;
      successes += o.ok;
      if (a.runs > 1) {
        std::fprintf(stderr, "visco demo: run %d/%d (seed %llu): %s in %.1f s; %d of %d reached the goal so far\n",
                     completed, a.runs, static_cast<unsigned long long>(seed), o.ok ? "goal reached" : "FAILED",
                     o.item["time_s"].get<double>(), successes, completed);
      }
      outcomes[static_cast<size_t>(r)] = std::move(o);
      finished[static_cast<size_t>(r)] = true;
    }
  };
  std::vector<std::thread> jobs;
  for (int j = 0; j < std::min(a.jobs, a.runs); ++j) jobs.emplace_back(worker, j);
  for (auto& t : jobs) t.join();
  std::vector<RunOutcome> done_runs;
  for (int r = 0; r < a.runs; ++r) {
    if (finished[static_cast<size_t>(r)]) done_runs.push_back(std::move(outcomes[static_cast<size_t>(r)]));
  }
  return done_runs;
}

// summary.json, montecarlo.svg (Monte Carlo) and the report on stdout: every failed run (every run when there is
// one), the Monte Carlo figures, the count of runs that reached the goal.
void Report(const Options& a, const Setup& su, const std::vector<RunOutcome>& done_runs, double plan_s,
            double total_s) {
  const fs::path& dir = su.dir;
  const planning::Strategy& strategy = *su.strategy;
  nlohmann::json runs = nlohmann::json::array();
  int successes = 0;
  for (const auto& o : done_runs) {
    runs.push_back(o.item);
    successes += o.ok;
  }
  std::vector<double> motion, commands, events;
  for (const auto& o : done_runs) {
    if (!o.ok) continue;
    if (o.item["motion_s"].is_number()) motion.push_back(o.item["motion_s"].get<double>());
    commands.push_back(o.item["commands_sent"].get<double>());
    events.push_back(o.item["visual_events"].get<double>());
  }
  nlohmann::json summary = {
      {"scene", su.scene->name},
      {"steps", strategy.steps.size()},
      {"plan_s", plan_s},
      {"total_s", total_s},
      {"runs", runs},
      {"successes", successes},
      {"success_rate", runs.empty() ? 0.0 : successes / static_cast<double>(runs.size())},
      {"motion_s", Quantiles(motion)},
      {"commands_sent", Quantiles(commands)},
      {"visual_events", Quantiles(events)},
      {"jobs", a.jobs},
      {"speed", a.plan.empty() ? nlohmann::json(a.speed / a.slow) : nlohmann::json(nullptr)},  // --plan: the file's
      {"slow_machine", a.slow},
      {"camera", su.rendered ? "rendered" : "events"},
      {"transport", a.can ? "can" : "lcm"},
      {"netns", a.netns},
      {"lockstep", a.lockstep},
      {"png_level", a.png_level >= 0 ? nlohmann::json(a.png_level) : nlohmann::json(nullptr)},
      {"image_noise", a.image_noise},
      {"blur_px", a.blur_px},
      {"plan", a.plan.empty() ? nlohmann::json(nullptr) : nlohmann::json(a.plan)},
      {"v4l2", a.v4l2_output.empty()
                   ? nlohmann::json(nullptr)
                   : nlohmann::json({{"output", a.v4l2_output}, {"capture", a.v4l2_capture}, {"input", a.v4l2_input}})},
      {"interrupted", g_stop.load()}};
  WriteTextOutput(summary.dump(2) + "\n", (dir / "summary.json").string());
  if (a.runs > 1) WriteTextOutput(MonteCarloSvg(su, done_runs), (dir / "montecarlo.svg").string());
  for (const auto& item : runs) {
    if (a.runs > 1 && item["success"].get<bool>()) continue;  // Monte Carlo: the failures one by one, then the figures
    std::printf(
        "run seed %llu: %s (%s), %d/%zu steps, %d visual events, %d commands, %d faults, %.1f s, final error "
        "%s m\n",
        static_cast<unsigned long long>(item["seed"].get<std::uint64_t>()),
        item["success"].get<bool>() ? "goal reached" : "FAILED", item["reason"].get<std::string>().c_str(),
        item["steps_completed"].get<int>(), strategy.steps.size(), item["visual_events"].get<int>(),
        item["commands_sent"].get<int>(), item["faults_published"].get<int>(), item["time_s"].get<double>(),
        item["goal_error_m"].is_null() ? "?" : fmt::format("{:.3f}", item["goal_error_m"].get<double>()).c_str());
  }
  if (a.runs > 1 && !motion.empty()) {
    std::printf(
        "visco demo: time in motion median %.2f s (5-95 %%: %.2f-%.2f s), commands median %.0f, visual events "
        "median %.0f; figure: %s\n",
        Quantile(motion, 0.5), Quantile(motion, 0.05), Quantile(motion, 0.95), Quantile(commands, 0.5),
        Quantile(events, 0.5), (dir / "montecarlo.svg").c_str());
  }
  std::printf("visco demo: %d of %zu run(s) reached the goal recognisably; %.1f s in all; outputs in %s\n", successes,
              runs.size(), total_s, dir.c_str());
}

int Run(const Options& a) {
  CheckOptions(a);
  const auto t0 = Clock::now();
  const fs::path dir = FreshDir(a.out);
  const Plan plan = MakePlan(a, dir);
  const planning::Scene& scene = plan.scene;
  const double plan_s = std::chrono::duration<double>(Clock::now() - t0).count();
  if (plan.given) {
    std::fprintf(stderr, "visco demo: %zu step(s) from %s\n", plan.strategy.steps.size(), a.plan.c_str());
  } else {
    std::fprintf(stderr, "visco demo: %zu step(s), planned in %.1f s\n", plan.strategy.steps.size(), plan_s);
  }

  Setup su;
  su.options = &a;
  su.stop = &g_stop;
  su.scene = &scene;
  su.cspace = plan.cspace.get();
  su.strategy = &plan.strategy;
  su.dir = dir;
  su.self = (ExecutableDir() / "visco").string();
  su.rt = (ExecutableDir() / "visco-rt").string();
  WriteTextOutput(drivers::WorldFileJson(sim::MakeWorldFile(scene)), (dir / "world.json").string());
  // The rendered camera for the default scene; other scenes get the synthetic camera (visual events without images).
  const fs::path data = VISCO_SOURCE_DATA_DIR;
  su.rendered = a.scene.empty() && fs::exists(data / "sim" / "slot_camera.xml");
  if (su.rendered) {
    su.cam = {"--camera",     (data / "sim" / "slot_camera.xml").string(),
              "--extrinsics", (data / "sim" / "slot_extrinsics.json").string(),
              "--objects",    (data / "sim" / "slot_objects.json").string()};
    const vision::CameraModel camera = vision::LoadCamera(su.cam[1], "");
    su.image_width = camera.width;
    su.image_height = camera.height;
  }
  StopOnSignals(g_stop);

  const std::vector<RunOutcome> done_runs = ExecuteRuns(a, su);
  if (a.runs == 1 && !done_runs.empty() && !plan.given) {
    WriteTextOutput(RunSvg(scene, *su.cspace, *su.strategy, done_runs.front().trace), (dir / "run.svg").string());
  }
  Report(a, su, done_runs, plan_s, std::chrono::duration<double>(Clock::now() - t0).count());
  if (g_stop) return 130;
  int successes = 0;
  for (const auto& o : done_runs) successes += o.ok;
  return successes == static_cast<int>(done_runs.size()) && static_cast<int>(done_runs.size()) == a.runs ? 0 : 1;
}
}  // namespace

void RegisterDemoCommand(CLI::App& app) {
  auto args = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "demo",
      "The main job: plans the embedded default scene (or --scene FILE) with `visco plan`, then executes the "
      "strategy in closed loop as separate processes over LCM (the simulated robot and its driver, the rendered "
      "camera, the vision pipeline, the controller, lcm-logger), and writes plan.svg, run.svg, run.lcmlog and "
      "summary.json into DIR. Exit 0 only when the goal is recognisably reached (the controller recognised it and "
      "the simulated robot is in the goal).");
  cmd->add_option("--out", args->out, "output directory (default: a fresh ./visco-demo-N)");
  cmd->add_option("--scene", args->scene, "scene file instead of the embedded default (docs/formats.md)");
  cmd->add_option("--seed", args->seed, "seed of the adversary and the camera noise")->capture_default_str();
  cmd->add_flag("--can", args->can, "the controller talks to the driver over SocketCAN vcan0 instead of LCM");
  cmd->add_option("--runs", args->runs, "Monte Carlo: runs from seeded random starts in the start region")
      ->capture_default_str();
  cmd->add_option("--speed", args->speed,
                  "commanded speed of the strategy's motions, m/s (the controller's limit is 1)")
      ->capture_default_str();
  cmd->add_option("--jobs", args->jobs, "Monte Carlo: runs at the same time (each on its own LCM port), 1-8")
      ->capture_default_str();
  cmd->add_flag("--keep-logs", args->keep_logs,
                "Monte Carlo: keep every run's LCM logs (default: only the failed runs' logs)");
  cmd->add_option("--timeout", args->timeout_s, "give up a run after this many seconds")->capture_default_str();
  cmd->add_option("--png-level", args->png_level,
                  "the rendered camera publishes PNG (lossless) at this zlib level, 0..9, instead of raw grey: smaller "
                  "logs (run.lcmlog, controller.lcmlog) for CPU per frame (docs/camera.md)")
      ->check(CLI::Range(0, 9));
  cmd->add_option("--image-noise", args->image_noise,
                  "the rendered camera's pixel noise, grey levels (1 sigma): drawn over every pixel of every frame, "
                  "the renderer's largest cost per frame (0 on an emulated CPU: docs/camera.md)")
      ->capture_default_str();
  cmd->add_option("--blur-px", args->blur_px, "the rendered camera's Gaussian blur, pixels (sigma)")
      ->capture_default_str();
  cmd->add_option("--slow-machine", args->slow,
                  "the machine is this many times slower than a 2-core PC (e.g. 10 in the HIL VM's emulated CPU): "
                  "the processes' time limits (vision age, hold, start-up, status, heartbeat, watchdog, --timeout) "
                  "are multiplied by it; the commanded speed, the camera rate, the controller's rate and telemetry, "
                  "the driver's robot update and true-state rates divided by it; no supersampling; vision's full "
                  "detections at half resolution (visco track --decimate 2); with --v4l2-output, visco capture at the "
                  "camera's rate (not twice it)")
      ->capture_default_str();
  cmd->add_flag("--lockstep", args->lockstep,
                "run the closed loop as one process on a simulated clock (`visco sim --lockstep`: the same driver, "
                "simulated robot, rendered camera, vision pipeline and controller, one thread, a private in-process "
                "bus) instead of five processes on the wall clock: the same --seed gives a bit-identical run.lcmlog, "
                "which `visco replay --check` replays (docs/replay.md)");
  cmd->add_option("--plan", args->plan,
                  "execute this strategy (`visco plan` output for the scene, or an earlier demo's plan.json) instead "
                  "of planning: its speed is the file's (`visco plan --speed`); no plan.svg or run.svg; one run")
      ->check(CLI::ExistingFile);
  cmd->add_option("--start", args->start,
                  "start the run with the robot's reference point at X Y instead of a start drawn from the start "
                  "region (a start outside the first step's preimage is not covered by the strategy); one run")
      ->expected(2);
  cmd->add_option("--v4l2-output", args->v4l2_output,
                  "the camera through the kernel's video interface: the rendered frames are written to this V4L2 "
                  "output device (`visco sim --v4l2-output`) and `visco capture` reads them back from "
                  "--v4l2-capture and publishes them, as a real camera's process does (vivid's output looped to its "
                  "capture: docs/camera.md, \"The closed loop through V4L2\"). --png-level then applies to the "
                  "capture; --jobs 1");
  cmd->add_option("--v4l2-capture", args->v4l2_capture,
                  "with --v4l2-output: the V4L2 capture device that shows what is written to the output (e.g. "
                  "/dev/video0)");
  cmd->add_option("--v4l2-input", args->v4l2_input,
                  "with --v4l2-capture: the capture device's input to select (vivid's HDMI input: 1; default: its "
                  "current one)");
  cmd->add_flag("--netns", args->netns,
                "run every process on a host of its own: a network namespace each, joined by veth to a bridge, LCM "
                "multicast with ttl=1 between them, as on several machines (needs root; summary.json records where "
                "each process ran)");
  cmd->callback([args] {
    const int status = Run(*args);
    if (status == 130) throw JobFailed("interrupted");
    if (status != 0) throw JobFailed("the goal was not reached in every run (see summary.json)");
  });
}

}  // namespace visco::app

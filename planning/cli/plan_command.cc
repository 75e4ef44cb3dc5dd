// `visco plan SCENE [--max-steps K] [--kernel-only] [--no-camera] [--out FILE] [--svg FILE] [--lcm-url URL]
// [--threads N] [--check N]` (docs/formats.md): a motion strategy by backchaining preimages.

#include "planning/cli/plan_command.h"

#include <fmt/format.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <string>

#include "common/error.h"
#include "common/write_output.h"
#include "lcmtypes/channels.h"
#include "planning/cspace.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "planning/strategy.h"
#include "planning/threads.h"
#include "planning/vc_rays.h"
#include "visco/motion_strategy_t.hpp"

namespace visco::planning {
namespace {

struct Args {
  std::string scene;
  int max_steps = 3;
  bool kernel_only = false;
  bool no_camera = false;
  std::string out, svg, lcm_url;
  int threads = MachineThreads();
  int check = 0;
  double speed = 0.25;
  int max_backprojections = 60;
  double max_memory = -1;  // MiB; < 0: half the machine's memory
  std::string search = "lean";
};

// Half the machine's physical memory (MiB): the default memory limit of the search.
double HalfTheMachinesMemory() {
  const double pages = static_cast<double>(sysconf(_SC_PHYS_PAGES));
  const double page = static_cast<double>(sysconf(_SC_PAGESIZE));
  return pages > 0 && page > 0 ? 0.5 * pages * page / (1024.0 * 1024.0) : 0.0;
}

}  // namespace

namespace {

void Run(const Args& a) {
  if (a.threads < 1) throw InputError("command line", "--threads", "must be at least 1");
  if (a.check < 0) throw InputError("command line", "--check", "must not be negative");
  if (!(a.speed > 0)) throw InputError("command line", "--speed", "must be positive");
  if (a.max_backprojections < 1) throw InputError("command line", "--max-backprojections", "must be at least 1");
  if (a.search != "lean" && a.search != "baseline")
    throw InputError("command line", "--search", "must be lean or baseline, not '" + a.search + "'");
  const Scene scene = LoadScene(a.scene);
  if (!scene.start) throw InputError(a.scene, "start", "planning needs a start region");
  PlanOptions options;
  options.max_steps = a.max_steps;
  options.kernel_only = a.kernel_only;
  options.use_camera = !a.no_camera;
  options.threads = a.threads;
  options.max_nondirectional = a.max_backprojections;
  options.max_memory_mib = a.max_memory >= 0 ? a.max_memory : HalfTheMachinesMemory();
  options.search = a.search == "baseline" ? SearchMode::kBaseline : SearchMode::kLean;
  const bool tty = isatty(fileno(stderr)) != 0;
  // On a terminal: the level (steps tried), the child targets done of that level's, the time so far and an estimate
  // of the level's rest; nothing otherwise.
  std::size_t shown = 0;
  if (tty) {
    options.search_progress = [&](const PlanProgress& p) {
      std::string line = p.level == 1
                             ? fmt::format("planning: 1 step, {:.0f} s", p.elapsed_s)
                             : fmt::format("planning: {} of at most {} steps, {} of {} child targets, {:.0f} s",
                                           p.level, p.max_steps, p.done, p.total, p.elapsed_s);
      if (p.level_left_s > 0) line += fmt::format(", about {:.0f} s left for this level", p.level_left_s);
      std::fprintf(stderr, "\r%-*s", static_cast<int>(std::max(shown, line.size())), line.c_str());
      shown = line.size();
      std::fflush(stderr);
    };
  }
  const Strategy strategy = PlanStrategy(scene, options);
  if (tty && shown > 0) std::fprintf(stderr, "\r%*s\r", static_cast<int>(shown), "");
  std::string json = StrategyToJson(scene, strategy, a.speed);
  if (a.check > 0 && strategy.feasible) {
    const CSpace cspace(scene);
    VcRays rays;
    if (scene.camera) rays = ComputeVcRays(scene, cspace);
    const StrategyCheck check = CheckStrategy(scene, cspace, rays, strategy, a.check, 1);
    std::fprintf(stderr, "checked by simulation: %d of %d start configurations reach the goal\n", check.successes,
                 check.starts);
    for (const auto& f : check.failures) std::fprintf(stderr, "  %s\n", f.c_str());
    if (check.successes != check.starts) {
      WriteTextOutput(json, a.out);
      throw JobFailed(a.scene + ": the strategy failed in simulation (a planner bug; please report it)");
    }
  }
  WriteTextOutput(json, a.out);
  if (!a.svg.empty()) WriteTextOutput(StrategyToSvg(scene, CSpace(scene), strategy), a.svg);
  if (!a.lcm_url.empty()) {
    lcm::LCM lcm(a.lcm_url);
    if (!lcm.good()) throw JobFailed("cannot open LCM at " + a.lcm_url);
    const motion_strategy_t m = StrategyToLcm(scene, strategy, a.speed);
    if (lcm.publish(visco::channels::kStrategy, &m) != 0) throw JobFailed("publishing the strategy on LCM failed");
  }
  if (!strategy.feasible) throw JobFailed(a.scene + ": " + strategy.reason);
}

}  // namespace

void RegisterPlanCommand(CLI::App& app) {
  auto args = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "plan",
      "Plan a motion strategy from the scene's start region to its goal by backchaining preimages (LMT; Fox & "
      "Hutchinson sections IV-A and VIII): the last step ends when the sensed position is recognisably in the goal "
      "(the goal kernel), earlier steps end by visual guarded termination on a CVC ray whose piece lies in the next "
      "step's preimage, or by contact termination (the motion sticks on a face or in a corner of the C-obstacles, "
      "all of whose sticking places lie in the next step's preimage). Commanded directions come from the critical "
      "orientations (never sampled). Fewest "
      "steps win, then the largest margin. Prints JSON {\"feasible\", \"steps\": [{\"theta_deg\", \"active_rays\", "
      "\"terminate\": {\"kind\", \"ref\"}, \"preimage\": REGION, \"guarantee\", \"interval_deg\", \"margin\"}]} in "
      "execution order (docs/formats.md), which `visco run` executes as it is. Exit 1 when no strategy within "
      "--max-steps exists, with the reason on stderr.");
  cmd->add_option("SCENE", args->scene, "scene file (JSON, see docs/formats.md); needs a start region")->required();
  cmd->add_option("--max-steps", args->max_steps, "the most steps a strategy may have")->capture_default_str();
  cmd->add_flag("--kernel-only", args->kernel_only,
                "goal-terminated steps only (no visual guarded subgoals): one step from the start region or none");
  cmd->add_flag("--no-camera", args->no_camera, "plan as if the scene had no camera (no visual constraints)");
  cmd->add_option("--out", args->out, "write the JSON to FILE instead of stdout");
  cmd->add_option("--svg", args->svg, "draw the nested preimages, commanded directions and rays into FILE (SVG)");
  cmd->add_option("--lcm-url", args->lcm_url, "also publish the strategy as visco.motion_strategy_t on VISCO_STRATEGY");
  cmd->add_option("--speed", args->speed, "commanded speed for `visco run` (JSON \"speed\" and the LCM message), m/s")
      ->capture_default_str();
  cmd->add_option("--max-backprojections", args->max_backprojections,
                  "stop the search after this many nondirectional backprojections (a few seconds each)")
      ->capture_default_str();
  cmd->add_option("--max-memory", args->max_memory,
                  "stop the search when the process uses more than this much memory (MiB; default: half the "
                  "machine's memory; 0: no limit): exit 1 with what was explored")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--threads", args->threads,
                  "worker threads: the child targets of a multi-step search are computed this many at a time, a "
                  "single backprojection's slices too (default: the machine's cores; the result does not depend on it)")
      ->capture_default_str();
  cmd->add_option("--search", args->search,
                  "lean (default) or baseline: the multi-step search before (one child target at a time, each "
                  "keeping its whole nondirectional backprojection), kept to compare; the same strategies")
      ->capture_default_str();
  cmd->add_option("--check", args->check,
                  "simulate the strategy from N sampled start configurations with adversarial velocities; exit 1 if "
                  "any fails");
  cmd->callback([args] { Run(*args); });
}

}  // namespace visco::planning

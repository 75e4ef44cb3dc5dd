#include "planning/cli/backproject_command.h"

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "common/error.h"
#include "common/write_output.h"
#include "planning/backprojection_output.h"
#include "planning/cspace.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "planning/scene_problem.h"
#include "planning/vc_rays.h"

namespace visco::planning {
namespace {

struct Args {
  std::string scene;
  double theta_deg = 0;
  bool kernel = false;
  int exact_limit = kExactRaySelectionLimit;
  std::string method = "track";
  std::string out, svg;
};

void WriteText(const std::string& text, const std::string& path) { WriteTextOutput(text, path); }

void Run(const Args& a) {
  if (!std::isfinite(a.theta_deg)) throw InputError("command line", "--theta", "must be a finite number of degrees");
  const Scene scene = LoadScene(a.scene);
  const CSpace cspace(scene);
  const double theta = a.theta_deg * M_PI / 180.0;
  const VcRays rays = ComputeVcRays(scene, cspace);
  const BackprojectionProblem pr = ProblemFromScene(scene, cspace, &rays, theta, a.kernel);
  if (pr.goal.empty()) {
    throw JobFailed(a.scene +
                    ": goal: the goal kernel is empty (the goal is narrower than twice the position "
                    "uncertainty)");
  }
  VcSelectionOptions options;
  options.exact_limit = a.exact_limit;
  options.method = a.method == "exact"    ? RaySelection::kExact
                   : a.method == "greedy" ? RaySelection::kGreedy
                                          : RaySelection::kTrack;
  const VcBackprojection vc = VcEnlargedBackprojection(pr, options);
  const Region& classic = vc.classic;
  WriteText(BackprojectionToJson(a.theta_deg, classic, vc), a.out);
  if (!a.svg.empty()) WriteText(BackprojectionToSvg(scene, cspace, pr, classic, vc), a.svg);
}

}  // namespace

void RegisterBackprojectCommand(CLI::App& app) {
  auto args = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "backproject",
      "Directional backprojections of the scene's goal for commanded direction THETA (Fox & Hutchinson sections IV-V): "
      "the classic B_theta(G) (Donald-Canny plane sweep) and the VC-enlarged B_vctheta(G), with the CVC rays the "
      "robot complies to chosen so that the region stays sound and contains the classic one (by default: every "
      "reliable candidate ray minus those whose compliance leads to failure, then the dropped ones one at a time; "
      "--ray-selection exact sweeps every subset up to --exact-limit candidates). Prints JSON "
      "{\"theta_deg\", \"classic\": REGION, \"vc\": REGION + {\"active_rays\", \"ray_selection\": {\"method\", "
      "\"candidates\", \"sweeps\"}}}, REGION = {\"area\", \"regions\": "
      "[{\"outer\": {\"vertices\", \"edges\": [{\"kind\", \"ref\"}]}, \"holes\"}]} (docs/formats.md).");
  cmd->add_option("SCENE", args->scene, "scene file (JSON, see docs/formats.md)")->required();
  cmd->add_option("--theta", args->theta_deg, "commanded direction, degrees counter-clockwise from +x")->required();
  cmd->add_flag("--kernel", args->kernel,
                "backproject the goal kernel (the goal eroded by the position uncertainty) instead of the goal");
  cmd->add_option("--ray-selection", args->method,
                  "how to choose the active rays: track (at most 3k + 1 sweeps for k candidates), exact (every "
                  "subset, 2^k sweeps) or greedy")
      ->check(CLI::IsMember({"track", "exact", "greedy"}))
      ->capture_default_str();
  cmd->add_option(
         "--exact-limit", args->exact_limit,
         "with --ray-selection exact: search all subsets of the reliable candidate rays when there are at most "
         "N of them, else choose greedily")
      ->capture_default_str();
  cmd->add_option("--out", args->out, "write the JSON to FILE instead of stdout");
  cmd->add_option("--svg", args->svg, "draw classic and VC-enlarged side by side (Fig. 13 style) into FILE (SVG)");
  cmd->callback([args] { Run(*args); });
}

}  // namespace visco::planning

#include "planning/cli/commands.h"

#include <CLI/CLI.hpp>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>

#include "common/error.h"
#include "common/write_output.h"
#include "planning/cli/backproject_command.h"
#include "planning/cli/camera_command.h"
#include "planning/cli/critical_command.h"
#include "planning/cli/plan_command.h"
#include "planning/cspace.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "planning/scene_problem.h"
#include "planning/strategy.h"
#include "planning/vc_rays.h"

namespace visco::planning {
namespace {

struct VcRaysArgs {
  std::string scene;
  std::string out;
  std::string svg;
};

void WriteText(const std::string& text, const std::string& path) { WriteTextOutput(text, path); }

void RunVcRays(const VcRaysArgs& a) {
  const Scene scene = LoadScene(a.scene);
  const CSpace cspace(scene);
  const VcRays rays = ComputeVcRays(scene, cspace);
  // The scene is valid, but no strategy can end in its goal: say so now rather than only in `visco plan`.
  if (ProblemFromScene(scene, cspace, nullptr, 0.0, /*kernel=*/true).goal.empty()) {
    std::fprintf(stderr, "visco: warning: %s: %s\n", a.scene.c_str(), kEmptyGoalKernel);
  }
  WriteText(VcRaysToJson(scene, rays), a.out);
  if (!a.svg.empty()) WriteText(VcRaysToSvg(scene, cspace, rays), a.svg);
}

}  // namespace

void RegisterCommands(CLI::App& app) {
  auto args = std::make_shared<VcRaysArgs>();
  CLI::App* vcrays = app.add_subcommand(
      "vcrays",
      "Compute the visual constraint rays of a scene (Fox & Hutchinson section III): workspace VC rays from the "
      "unoccluded obstacle vertices in the field of view to the camera centre, and C-space VC rays (one per CM "
      "vertex of the robot, cut where they enter the C-obstacles and clipped to the bounds), with their crossings. "
      "Prints JSON {\"vc_rays\": [{\"id\", \"obstacle\", \"vertex\", \"from\", \"to\"}], \"cvc_rays\": [{\"id\", "
      "\"vc_ray\", \"cm_vertex\", \"segments\"}], \"cvc_crossings\": [...]}. Ids are stable: \"vc<k>\" for the k-th "
      "obstacle vertex of the file, \"vc<k>.cm<j>\" for robot vertex j.");
  vcrays->add_option("SCENE", args->scene, "scene file (JSON, see docs/formats.md)")->required();
  vcrays->add_option("--out", args->out, "write the JSON to FILE instead of stdout");
  vcrays->add_option("--svg", args->svg,
                     "draw obstacles, C-obstacles, camera, VC rays and labelled CVC rays into FILE (SVG)");
  vcrays->callback([args] { RunVcRays(*args); });
  RegisterBackprojectCommand(app);
  RegisterCriticalCommand(app);
  RegisterPlanCommand(app);
  RegisterCameraCommand(app);
}

}  // namespace visco::planning

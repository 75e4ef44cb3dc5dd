// `visco critical SCENE [--kernel] [--slices] [--svg FILE] [--threads N] [--method kinetic|baseline] [--out FILE]`
// (docs/formats.md): the critical orientations of the scene's backprojections, and with --slices the nondirectional
// backprojection (one slice per orientation and per open interval) and where the start region fits.

#include "planning/cli/critical_command.h"

#include <fmt/format.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "common/error.h"
#include "common/write_output.h"
#include "planning/area_profile.h"
#include "planning/backprojection_output.h"
#include "planning/cspace.h"
#include "planning/nondirectional.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "planning/scene_problem.h"
#include "planning/svg.h"
#include "planning/threads.h"
#include "planning/vc_rays.h"

namespace visco::planning {
namespace {

double Deg(double rad) { return rad * 180.0 / M_PI; }

struct Args {
  std::string scene;
  bool kernel = false;
  bool slices = false;
  std::string svg, out;
  int threads = MachineThreads();
  int samples = 240;
  std::string method = "kinetic";
  int resweep_period = NondirectionalOptions{}.resweep_period;
};

// A progress bar on a terminal, nothing otherwise.
class ProgressBar {
 public:
  explicit ProgressBar(std::string label) : label_(std::move(label)), tty_(isatty(fileno(stderr)) != 0) {}
  void operator()(double fraction) {
    if (!tty_) return;
    const int width = 40, filled = static_cast<int>(std::clamp(fraction, 0.0, 1.0) * width);
    if (filled == last_) return;
    last_ = filled;
    std::fprintf(stderr, "\r%s [%s%s] %3d%%", label_.c_str(), std::string(filled, '#').c_str(),
                 std::string(width - filled, ' ').c_str(), static_cast<int>(fraction * 100));
    std::fflush(stderr);
  }
  ~ProgressBar() {
    if (tty_ && last_ >= 0) std::fprintf(stderr, "\r%*s\r", 60 + static_cast<int>(label_.size()), "");
  }

 private:
  std::string label_;
  bool tty_;
  int last_ = -1;
};

nlohmann::json OrientationsJson(const std::vector<CriticalOrientation>& orientations) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& o : orientations) {
    nlohmann::json j = {{"theta_deg", Deg(o.theta)}, {"kind", CriticalKindName(o.kind)}, {"refs", o.refs}};
    if (o.kind == CriticalKind::kSliding) j["cause"] = SlidingCauseName(o.sliding);
    out.push_back(std::move(j));
  }
  return out;
}

nlohmann::json IntervalsJson(const std::vector<ThetaInterval>& intervals) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& i : intervals) {
    out.push_back(
        {{"lo_deg", Deg(i.lo)}, {"hi_deg", Deg(i.hi)}, {"best_theta_deg", Deg(i.best_theta)}, {"margin", i.margin}});
  }
  return out;
}

void Run(const Args& a) {
  if (a.threads < 1) throw InputError("command line", "--threads", "must be at least 1");
  if (a.samples < 2) throw InputError("command line", "--samples", "must be at least 2");
  if (a.resweep_period < 0) throw InputError("command line", "--resweep-period", "must be 0 or more");
  const Scene scene = LoadScene(a.scene);
  const CSpace cspace(scene);
  const VcRays rays = ComputeVcRays(scene, cspace);
  const BackprojectionProblem pr = ProblemFromScene(scene, cspace, &rays, 0.0, a.kernel);
  if (pr.goal.empty()) {
    throw JobFailed(a.scene +
                    ": goal: the goal kernel is empty (the goal is narrower than twice the position uncertainty)");
  }
  NamedPolygon start;
  if (scene.start) start.vertices = scene.start->polygon.vertices;
  NondirectionalOptions options;
  options.threads = a.threads;
  options.method = a.method == "baseline" ? SliceMethod::kBaseline : SliceMethod::kKinetic;
  options.resweep_period = a.resweep_period;
  NondirectionalBackprojection nd;
  {
    ProgressBar bar("critical orientations");
    options.progress = [&bar](double f) { bar(f); };
    nd = ComputeNondirectional(pr, scene.start ? &start : nullptr, options);
  }
  nlohmann::json doc;
  doc["orientations"] = OrientationsJson(nd.orientations);
  const auto& st = nd.stats;
  nlohmann::json by_kind;
  for (int k = 0; k < 7; ++k) by_kind[CriticalKindName(static_cast<CriticalKind>(k))] = st.counts.by_kind[k];
  doc["stats"] = {{"method", a.method},
                  {"candidates", st.candidates},
                  {"candidates_by_kind", by_kind},
                  {"events", st.events},
                  {"checked", st.checked},
                  {"backprojections", st.backprojections},
                  {"changes", st.changes},
                  {"selection", st.selection},
                  {"r_critical", st.r_critical},
                  {"unexplained", st.unexplained},
                  {"found_by_probes", st.found_by_probes},
                  {"rule_missed", st.rule_missed},
                  {"rule_missed_sliding", st.rule_missed_sliding},
                  {"explained", st.explained},
                  {"updated", st.updated},
                  {"walks", st.walks},
                  {"ray_points_listed", st.ray_points_listed},
                  {"reused", st.reused}};
  for (int i = 0; i < kSweepPurposes; ++i) {
    doc["stats"]["sweeps"][SweepPurposeName(static_cast<SweepPurpose>(i))] = st.sweeps[i];
  }
  if (scene.start) {
    doc["start_intervals"] = {{"classic", IntervalsJson(IntervalsContaining(nd, pr, start, false))},
                              {"vc", IntervalsJson(IntervalsContaining(nd, pr, start, true))}};
  }
  if (a.slices) {
    nlohmann::json slices = nlohmann::json::array();
    for (const Slice& s : nd.slices) {
      nlohmann::json classic = nlohmann::json::parse(RegionToJson(s.vc.classic));
      nlohmann::json vc = nlohmann::json::parse(RegionToJson(s.vc.region));
      vc["active_rays"] = s.vc.active_rays;
      slices.push_back({{"theta_deg", Deg(s.theta)},
                        {"critical", s.critical},
                        {"lo_deg", Deg(s.lo)},
                        {"hi_deg", Deg(s.hi)},
                        {"classic", classic},
                        {"vc", vc}});
    }
    doc["slices"] = slices;
  }
  WriteTextOutput(doc.dump(), a.out);
  if (!a.svg.empty()) {
    const auto samples = SampleAreas(nd, a.samples);
    WriteTextOutput(AreaProfileSvg(fmt::format("{}: backprojection area against the commanded direction ({} critical "
                                               "orientations)",
                                               scene.name.empty() ? a.scene : scene.name, nd.orientations.size()),
                                   samples, nd.orientations),
                    a.svg);
  }
}

}  // namespace

void RegisterCriticalCommand(CLI::App& app) {
  auto args = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "critical",
      "Critical orientations of the scene's backprojections over every commanded direction (Donald; Fox & Hutchinson "
      "sections VI-VII): the six kinds vgraph, sliding, vertex, R, free-edge, vc, and selection where the choice of "
      "active rays switches. Between two consecutive orientations the structure of `visco backproject` (the cyclic "
      "(kind, ref) sequence of every ring, classic and vc) does not change. Prints JSON {\"orientations\": "
      "[{\"theta_deg\", \"kind\", \"refs\"}], \"stats\", \"start_intervals\": {\"classic\", \"vc\"} (the "
      "theta-intervals where the start region lies inside the backprojection)}; with --slices also \"slices\" "
      "(the nondirectional backprojection: one per orientation and one per open interval).");
  cmd->add_option("SCENE", args->scene, "scene file (JSON, see docs/formats.md)")->required();
  cmd->add_flag("--kernel", args->kernel, "backproject the goal kernel (the goal eroded by the position uncertainty)");
  cmd->add_flag("--slices", args->slices, "print the slices of the nondirectional backprojection too");
  cmd->add_option(
      "--svg", args->svg,
      "draw the areas of B_theta(G) and B_vctheta(G) against theta with the critical orientations into FILE");
  cmd->add_option("--samples", args->samples, "orientations sampled for the --svg curves")->capture_default_str();
  cmd->add_option("--threads", args->threads,
                  "worker threads for the slices (default: the machine's cores; the result does not depend on it)")
      ->capture_default_str();
  cmd->add_option("--method", args->method,
                  "kinetic (sweep again only at candidates that move the regions' free edges, and at sliding or "
                  "along-a-segment candidates whose edge meets the regions) or baseline (Donald's critical-slice "
                  "method: a sweep at every candidate)")
      ->check(CLI::IsMember({"kinetic", "baseline"}))
      ->capture_default_str();
  cmd->add_option("--resweep-period", args->resweep_period,
                  "kinetic: also sweep every N events where none is relevant (a safety net; 0 = never)")
      ->capture_default_str();
  cmd->add_option("--out", args->out, "write the JSON to FILE instead of stdout");
  cmd->callback([args] { Run(*args); });
}

}  // namespace visco::planning

#include "planning/backproject_command.h"

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
#include "planning/cspace.h"
#include "planning/scene.h"
#include "planning/svg.h"
#include "planning/vc_rays.h"

namespace visco::planning {
namespace {

// A ring of CB with its provenance (CSpace::obstacle_union_sources, cspace.h EdgeSource).
NamedPolygon Named(const Polygon& poly, const RingSources& sources, bool hole) {
  NamedPolygon out;
  out.hole = hole;
  out.vertices = poly.vertices;
  out.vertex_refs = sources.vertex_refs;
  for (const EdgeSource& edge : sources.edges) out.edge_refs.push_back(edge.ref);
  return out;
}

nlohmann::json RingJson(const RegionRing& ring) {
  nlohmann::json v = nlohmann::json::array(), e = nlohmann::json::array();
  for (const auto& p : ring.vertices) v.push_back({p.x(), p.y()});
  for (const auto& edge : ring.edges) {
    nlohmann::json item;
    item["kind"] = EdgeKindName(edge.kind);
    item["ref"] = edge.ref.empty() ? nlohmann::json() : nlohmann::json(edge.ref);
    e.push_back(item);
  }
  return {{"vertices", v}, {"edges", e}};
}

nlohmann::json RegionJson(const Region& region) {
  nlohmann::json regions = nlohmann::json::array();
  for (const auto& poly : region.polygons) {
    nlohmann::json holes = nlohmann::json::array();
    for (const auto& h : poly.holes) holes.push_back(RingJson(h));
    regions.push_back({{"outer", RingJson(poly.outer)}, {"holes", holes}});
  }
  return {{"area", region.area}, {"regions", regions}};
}

PolygonWithHoles ToPolygonWithHoles(const RegionPolygon& poly) {
  PolygonWithHoles out;
  out.outer.vertices = poly.outer.vertices;
  for (const RegionRing& h : poly.holes) out.holes.push_back(Polygon{h.vertices});
  return out;
}

// One panel of the Fig. 13-style picture, drawn in world coordinates (y up) on its own canvas.
void DrawPanel(SvgCanvas& c, const Scene& scene, const CSpace& cspace, const BackprojectionProblem& pr,
               const Region& region, const std::vector<std::string>& active, const std::string& title) {
  const Eigen::Vector2d lo = scene.bounds.min, hi = scene.bounds.max;
  c.Polygon(Polygon{{{lo.x(), lo.y()}, {hi.x(), lo.y()}, {hi.x(), hi.y()}, {lo.x(), hi.y()}}},
            "fill=\"white\" stroke=\"#999\" stroke-width=\"1\"");
  // The region: light fill (holes left out), dashed outline, VC edges bold.
  for (const auto& poly : region.polygons)
    c.PolygonWithHoles(ToPolygonWithHoles(poly), "fill=\"#cfe3ff\" stroke=\"none\"");
  for (const auto& o : scene.obstacles) c.Polygon(o.shape.polygon, "fill=\"#bbb\" stroke=\"#777\" stroke-width=\"1\"");
  for (size_t i = 0; i < cspace.num_c_obstacles(); ++i) {
    for (const auto& pw : cspace.c_obstacle(i)) {
      c.Polygon(pw.outer, "fill=\"none\" stroke=\"#333\" stroke-width=\"1\"");
      for (const auto& h : pw.holes) c.Polygon(h, "fill=\"none\" stroke=\"#333\" stroke-width=\"1\"");
    }
  }
  for (const auto& g : pr.goal) c.Polygon(Polygon{g.vertices}, "fill=\"black\" stroke=\"black\"");
  for (const auto& ray : pr.rays) {
    const bool is_active = std::find(active.begin(), active.end(), ray.id) != active.end();
    for (size_t k = 0; k < ray.segments.size(); ++k) {
      const auto& s = ray.segments[k];
      c.Line(s[0], s[1],
             is_active ? "stroke=\"#c00\" stroke-width=\"1.5\" stroke-dasharray=\"6,3\""
                       : "stroke=\"#e9a\" stroke-width=\"0.7\"");
      // An open end of an active ray (the bounds or the camera: complying to it fails) as a hollow circle.
      for (int e = 0; e < 2 && is_active && k < ray.open_ends.size(); ++e) {
        if (ray.open_ends[k][e])
          c.Circle(s[e], 5, "class=\"open-end\" fill=\"white\" stroke=\"#c00\" stroke-width=\"2\"");
      }
    }
  }
  auto ring_edges = [&](const RegionRing& r) {
    for (size_t i = 0; i < r.vertices.size(); ++i) {
      c.Line(r.vertices[i], r.vertices[(i + 1) % r.vertices.size()],
             r.edges[i].kind == EdgeKind::kVc ? "stroke=\"#c00\" stroke-width=\"4\""
                                              : "stroke=\"#036\" stroke-width=\"2\" stroke-dasharray=\"8,4\"");
    }
  };
  for (const auto& poly : region.polygons) {
    ring_edges(poly.outer);
    for (const auto& h : poly.holes) ring_edges(h);
  }
  if (scene.camera) {
    const Eigen::Vector2d center = scene.camera->center;
    const double d = 0.02 * (hi - lo).norm();
    c.Cross(center, 2 * d * (c.x(hi) - c.x(lo)) / (hi - lo).x(), "stroke=\"black\" stroke-width=\"2.5\"");
  }
  // Commanded velocity: an arrow in the top-left corner.
  const double len = 0.08 * (hi - lo).norm();
  const Eigen::Vector2d base = Eigen::Vector2d(lo.x(), hi.y()) + Eigen::Vector2d(1.2 * len, -1.2 * len);
  const Eigen::Vector2d v(std::cos(pr.theta), std::sin(pr.theta));
  const Eigen::Vector2d tip = base + len * v;
  const Eigen::Vector2d n(-v.y(), v.x());
  c.Line(base, tip, "stroke=\"#070\" stroke-width=\"3\"");
  c.Line(tip, tip - 0.3 * len * v + 0.15 * len * n, "stroke=\"#070\" stroke-width=\"3\"");
  c.Line(tip, tip - 0.3 * len * v - 0.15 * len * n, "stroke=\"#070\" stroke-width=\"3\"");
  c.TextPx(c.x(lo), 20, title, 14, "fill=\"black\"");
  c.Legend({{{"■", "#cfe3ff", "the backprojection"},
             {"━", "#c00", "its edges on an active ray"},
             {"╍", "#036", "its other edges"}},
            {{"■", "#bbb", "obstacle"},
             {"□", "#333", "C-obstacle"},
             {"■", "black", "goal (with --kernel: its kernel)"},
             {"✕", "black", "camera"},
             {"➜", "#070", "commanded direction θ"}},
            {{"╍", "#c00", "active CVC ray"}, {"━", "#e9a", "other CVC ray"}, {"○", "#c00", "its open end"}}});
}

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

BackprojectionProblem ProblemFromScene(const Scene& scene, const CSpace& cspace, const VcRays* rays, double theta,
                                       bool kernel) {
  BackprojectionProblem pr;
  if (rays) pr.rays = CvcRayInputs(*rays);
  // CB, the union of the C-obstacles, with the refs of the Minkowski features its edges lie on (the same at every θ).
  const auto& pieces = cspace.obstacle_union();
  const auto& sources = cspace.obstacle_union_sources();
  for (size_t p = 0; p < pieces.size(); ++p) {
    pr.obstacles.push_back(Named(pieces[p].outer, sources[p].outer, false));
    for (size_t h = 0; h < pieces[p].holes.size(); ++h) {
      pr.obstacles.push_back(Named(pieces[p].holes[h], sources[p].holes[h], true));
    }
  }
  NamedPolygon goal;
  const auto& g = scene.goal;
  for (size_t k = 0; k < g.polygon.size(); ++k) {
    goal.vertices.push_back(g.polygon[k]);
    goal.vertex_refs.push_back("goal.v[" + std::to_string(g.source_index[k]) + "]");
    goal.edge_refs.push_back("goal.e[" + std::to_string(SourceEdgeIndex(g, k)) + "]");
  }
  pr.goal = {goal};
  if (kernel) pr.goal = GoalKernel(pr.goal, scene.uncertainty.position);
  pr.bounds_min = scene.bounds.min;
  pr.bounds_max = scene.bounds.max;
  pr.theta = theta;
  pr.velocity_cone = scene.uncertainty.velocity_cone_rad;
  pr.friction_cone = scene.friction_cone_rad;
  pr.ray_tracking_error = scene.uncertainty.vc_tracking;
  return pr;
}

std::vector<CvcRayInput> CvcRayInputs(const VcRays& rays) {
  std::vector<CvcRayInput> out;
  for (const auto& r : rays.cvc_rays) {
    CvcRayInput in;
    in.id = r.id;
    in.group = rays.vc_rays[r.vc_ray].id;
    for (const auto& s : r.segments) in.segments.push_back({s.source, s.target});
    in.open_ends = r.open_ends;
    if (!in.segments.empty()) out.push_back(std::move(in));
  }
  return out;
}

std::string RegionToJson(const Region& region, int indent) { return RegionJson(region).dump(indent); }

std::string BackprojectionToJson(double theta_deg, const Region& classic, const VcBackprojection& vc) {
  nlohmann::json doc;
  doc["theta_deg"] = theta_deg;
  doc["classic"] = RegionJson(classic);
  nlohmann::json v = RegionJson(vc.region);
  v["active_rays"] = vc.active_rays;
  // How the active rays were chosen (an addition to docs/formats.md's fields): "exact" (every subset of the reliable
  // candidates swept: an admissible set of largest area), "greedy" (above the exact limit), "none" (no candidate).
  v["ray_selection"] = {
      {"method", RaySelectionName(vc.selection)}, {"candidates", vc.candidates}, {"sweeps", vc.sweeps}};
  doc["vc"] = v;
  return doc.dump();
}

std::string BackprojectionToSvg(const Scene& scene, const CSpace& cspace, const BackprojectionProblem& problem,
                                const Region& classic, const VcBackprojection& vc) {
  const double width = 560;
  SvgCanvas left(scene.bounds.min, scene.bounds.max, width);
  SvgCanvas right(scene.bounds.min, scene.bounds.max, width);
  const double theta_deg = problem.theta * 180.0 / M_PI;
  DrawPanel(left, scene, cspace, problem, classic, {},
            fmt::format("classic B_θ(G), θ = {:.1f}°, area {:.3f}", theta_deg, classic.area));
  DrawPanel(right, scene, cspace, problem, vc.region, vc.active_rays,
            fmt::format("VC-enlarged B_vcθ(G), area {:.3f}, {} active ray(s)", vc.region.area, vc.active_rays.size()));
  return SideBySide({{"classic", &left}, {"vc", &right}}, 20);
}

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

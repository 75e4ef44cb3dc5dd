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

// A minimal SVG panel in world coordinates (y up).
class Panel {
 public:
  Panel(Eigen::Vector2d min, Eigen::Vector2d max, double width, double ox)
      : min_(min), max_(max), scale_(width / (max - min).x()), ox_(ox) {}
  double X(const Eigen::Vector2d& p) const { return ox_ + 20 + (p.x() - min_.x()) * scale_; }
  double Y(const Eigen::Vector2d& p) const { return 40 + (max_.y() - p.y()) * scale_; }
  double height() const { return (max_ - min_).y() * scale_ + 60; }
  void Poly(const std::vector<Eigen::Vector2d>& v, const std::string& style) {
    std::string pts;
    for (const auto& p : v) pts += fmt::format("{:.2f},{:.2f} ", X(p), Y(p));
    body_ += fmt::format("<polygon points=\"{}\" {}/>\n", pts, style);
  }
  void Line(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const std::string& style) {
    body_ += fmt::format("<line x1=\"{:.2f}\" y1=\"{:.2f}\" x2=\"{:.2f}\" y2=\"{:.2f}\" {}/>\n", X(a), Y(a), X(b), Y(b),
                         style);
  }
  void Text(double x, double y, const std::string& t) {
    body_ +=
        fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" font-family=\"sans-serif\" font-size=\"14\">{}</text>\n", x, y, t);
  }
  std::string body_;

 private:
  Eigen::Vector2d min_, max_;
  double scale_, ox_;
};

void DrawPanel(Panel& p, const Scene& scene, const CSpace& cspace, const BackprojectionProblem& pr,
               const Region& region, const std::vector<std::string>& active, const std::string& title) {
  const Eigen::Vector2d lo = scene.bounds.min, hi = scene.bounds.max;
  p.Poly({{lo.x(), lo.y()}, {hi.x(), lo.y()}, {hi.x(), hi.y()}, {lo.x(), hi.y()}},
         "fill=\"white\" stroke=\"#999\" stroke-width=\"1\"");
  // The region: light fill, dashed outline, VC edges bold.
  for (const auto& poly : region.polygons) {
    p.Poly(poly.outer.vertices, "fill=\"#cfe3ff\" stroke=\"none\"");
    for (const auto& h : poly.holes) p.Poly(h.vertices, "fill=\"white\" stroke=\"none\"");
  }
  for (const auto& o : scene.obstacles)
    p.Poly(o.shape.polygon.vertices, "fill=\"#bbb\" stroke=\"#777\" stroke-width=\"1\"");
  for (size_t i = 0; i < cspace.num_c_obstacles(); ++i) {
    for (const auto& pw : cspace.c_obstacle(i)) {
      p.Poly(pw.outer.vertices, "fill=\"none\" stroke=\"#333\" stroke-width=\"1\"");
      for (const auto& h : pw.holes) p.Poly(h.vertices, "fill=\"none\" stroke=\"#333\" stroke-width=\"1\"");
    }
  }
  for (const auto& g : pr.goal) p.Poly(g.vertices, "fill=\"black\" stroke=\"black\"");
  for (const auto& ray : pr.rays) {
    const bool is_active = std::find(active.begin(), active.end(), ray.id) != active.end();
    for (const auto& s : ray.segments) {
      p.Line(s[0], s[1],
             is_active ? "stroke=\"#c00\" stroke-width=\"1.5\" stroke-dasharray=\"6,3\""
                       : "stroke=\"#e9a\" stroke-width=\"0.7\"");
    }
  }
  auto ring_edges = [&](const RegionRing& r) {
    for (size_t i = 0; i < r.vertices.size(); ++i) {
      const auto& a = r.vertices[i];
      const auto& b = r.vertices[(i + 1) % r.vertices.size()];
      p.Line(a, b,
             r.edges[i].kind == EdgeKind::kVc ? "stroke=\"#c00\" stroke-width=\"4\""
                                              : "stroke=\"#036\" stroke-width=\"2\" stroke-dasharray=\"8,4\"");
    }
  };
  for (const auto& poly : region.polygons) {
    ring_edges(poly.outer);
    for (const auto& h : poly.holes) ring_edges(h);
  }
  if (scene.camera) {
    const Eigen::Vector2d c = scene.camera->center;
    const double d = 0.02 * (hi - lo).norm();
    p.Line(c - Eigen::Vector2d(d, d), c + Eigen::Vector2d(d, d), "stroke=\"black\" stroke-width=\"2.5\"");
    p.Line(c - Eigen::Vector2d(d, -d), c + Eigen::Vector2d(d, -d), "stroke=\"black\" stroke-width=\"2.5\"");
  }
  // Commanded velocity: an arrow in the top-left corner.
  const double len = 0.08 * (hi - lo).norm();
  const Eigen::Vector2d base = Eigen::Vector2d(lo.x(), hi.y()) + Eigen::Vector2d(1.2 * len, -1.2 * len);
  const Eigen::Vector2d v(std::cos(pr.theta), std::sin(pr.theta));
  const Eigen::Vector2d tip = base + len * v;
  const Eigen::Vector2d n(-v.y(), v.x());
  p.Line(base, tip, "stroke=\"#070\" stroke-width=\"3\"");
  p.Line(tip, tip - 0.3 * len * v + 0.15 * len * n, "stroke=\"#070\" stroke-width=\"3\"");
  p.Line(tip, tip - 0.3 * len * v - 0.15 * len * n, "stroke=\"#070\" stroke-width=\"3\"");
  p.Text(p.X(lo), 25, title);
}

struct Args {
  std::string scene;
  double theta_deg = 0;
  bool kernel = false;
  int exact_limit = kExactRaySelectionLimit;
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
  const Region classic = ClassicBackprojection(pr);
  VcSelectionOptions options;
  options.exact_limit = a.exact_limit;
  const VcBackprojection vc = VcEnlargedBackprojection(pr, options);
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
  return pr;
}

std::vector<CvcRayInput> CvcRayInputs(const VcRays& rays) {
  std::vector<CvcRayInput> out;
  for (const auto& r : rays.cvc_rays) {
    CvcRayInput in;
    in.id = r.id;
    in.group = rays.vc_rays[r.vc_ray].id;
    for (const auto& s : r.segments) in.segments.push_back({s.source, s.target});
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
  // How the active rays were chosen (an addition to CONTRACT.md's fields): "exact" (every subset of the reliable
  // candidates swept: an admissible set of largest area), "greedy" (above the exact limit), "none" (no candidate).
  v["ray_selection"] = {
      {"method", RaySelectionName(vc.selection)}, {"candidates", vc.candidates}, {"sweeps", vc.sweeps}};
  doc["vc"] = v;
  return doc.dump();
}

std::string BackprojectionToSvg(const Scene& scene, const CSpace& cspace, const BackprojectionProblem& problem,
                                const Region& classic, const VcBackprojection& vc) {
  const double width = 560;
  Panel left(scene.bounds.min, scene.bounds.max, width, 0);
  Panel right(scene.bounds.min, scene.bounds.max, width, width + 40);
  const double theta_deg = problem.theta * 180.0 / M_PI;
  DrawPanel(left, scene, cspace, problem, classic, {},
            fmt::format("classic B_θ(G), θ = {:.1f}°, area {:.3f}", theta_deg, classic.area));
  DrawPanel(right, scene, cspace, problem, vc.region, vc.active_rays,
            fmt::format("VC-enlarged B_vcθ(G), area {:.3f}, {} active ray(s)", vc.region.area, vc.active_rays.size()));
  return fmt::format(
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{:.0f}\" "
      "height=\"{:.0f}\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n{}{}</svg>",
      2 * width + 80, left.height(), left.body_, right.body_);
}

void RegisterBackprojectCommand(CLI::App& app) {
  auto args = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "backproject",
      "Directional backprojections of the scene's goal for commanded direction THETA (Fox & Hutchinson sections IV-V): "
      "the classic B_theta(G) (Donald-Canny plane sweep) and the VC-enlarged B_vctheta(G), with the CVC rays the "
      "robot complies to chosen so that the region stays sound and contains the classic one, with the largest area "
      "over all subsets of the reliable candidate rays (exact search up to " +
          std::to_string(kExactRaySelectionLimit) +
          " candidates, greedy above). Prints JSON "
          "{\"theta_deg\", \"classic\": REGION, \"vc\": REGION + {\"active_rays\", \"ray_selection\": {\"method\", "
          "\"candidates\", \"sweeps\"}}}, REGION = {\"area\", \"regions\": "
          "[{\"outer\": {\"vertices\", \"edges\": [{\"kind\", \"ref\"}]}, \"holes\"}]} (CONTRACT.md).");
  cmd->add_option("SCENE", args->scene, "scene file (JSON, see CONTRACT.md)")->required();
  cmd->add_option("--theta", args->theta_deg, "commanded direction, degrees counter-clockwise from +x")->required();
  cmd->add_flag("--kernel", args->kernel,
                "backproject the goal kernel (the goal eroded by the position uncertainty) instead of the goal");
  cmd->add_option("--exact-limit", args->exact_limit,
                  "search all subsets of the reliable candidate rays when there are at most N of them, else choose "
                  "greedily (negative: always greedy)")
      ->capture_default_str();
  cmd->add_option("--out", args->out, "write the JSON to FILE instead of stdout");
  cmd->add_option("--svg", args->svg, "draw classic and VC-enlarged side by side (Fig. 13 style) into FILE (SVG)");
  cmd->callback([args] { Run(*args); });
}

}  // namespace visco::planning

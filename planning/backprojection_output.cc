#include "planning/backprojection_output.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "planning/cspace.h"
#include "planning/svg.h"

namespace visco::planning {
namespace {

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

}  // namespace

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
}  // namespace visco::planning

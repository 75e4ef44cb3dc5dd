// The strategy's output (strategy.h): the strategy JSON (docs/formats.md) and its picture with its legend.

#include <fmt/format.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "planning/backprojection_output.h"
#include "planning/cspace.h"
#include "planning/strategy.h"
#include "planning/svg.h"
#include "planning/vc_rays.h"

namespace visco::planning {
namespace {

using Eigen::Vector2d;

double Deg(double rad) { return rad * 180.0 / M_PI; }

constexpr const char* kPreimageColours[] = {"#cfe3ff", "#ffe0b3", "#d9f2d0", "#f2d0e9", "#e0e0e0"};
constexpr const char* kRayColour = "#088";  // the rays a step uses (red is a run's trajectory)

}  // namespace

std::string StrategyToJson(const Scene& scene, const Strategy& strategy, double speed) {
  nlohmann::json doc;
  doc["feasible"] = strategy.feasible;
  doc["scene"] = scene.name;
  if (!scene.digest.empty()) doc["scene_digest"] = scene.digest;  // scenes built in code have none
  doc["speed"] = speed;
  const double timeout = StepTimeout(scene, speed);
  nlohmann::json steps = nlohmann::json::array();
  for (const auto& s : strategy.steps) {
    nlohmann::json step;
    step["theta_deg"] = Deg(s.theta);
    step["active_rays"] = s.active_rays;
    step["terminate"] = {{"kind", TerminationName(s.terminate)},
                         {"ref", s.terminate_ref.empty() ? nlohmann::json() : nlohmann::json(s.terminate_ref)}};
    step["preimage"] = nlohmann::json::parse(RegionToJson(s.preimage));
    step["interval_deg"] = {Deg(s.interval_lo), Deg(s.interval_hi)};
    step["margin"] = s.margin;
    step["guarantee"] = s.guarantee;
    step["timeout_s"] = std::round(timeout);
    if (s.terminate != Termination::kGoal) {
      // Where the step can end: within end_radius of the segment between the two ends.
      step["ends"] = {{s.end_a.x(), s.end_a.y()}, {s.end_b.x(), s.end_b.y()}};
      step["end_radius"] = s.end_radius;
    }
    if (s.terminate == Termination::kContact) step["sticks_deg"] = {Deg(s.sticks_lo), Deg(s.sticks_hi)};
    steps.push_back(step);
  }
  doc["steps"] = steps;
  if (!strategy.feasible) {
    doc["reason"] = strategy.reason;
    doc["best_coverage"] = strategy.best_coverage;
    doc["best_theta_deg"] = Deg(strategy.best_theta);
  }
  return doc.dump();
}

void DrawStrategy(SvgCanvas& c, const Scene& scene, const CSpace& cspace, const Strategy& strategy) {
  const Vector2d lo = scene.bounds.min, hi = scene.bounds.max;
  c.Polygon(Polygon{{{lo.x(), lo.y()}, {hi.x(), lo.y()}, {hi.x(), hi.y()}, {lo.x(), hi.y()}}},
            "fill=\"white\" stroke=\"#999\" stroke-width=\"1\"");
  // Preimages from the last step (innermost, around the goal) to the first.
  for (size_t k = strategy.steps.size(); k-- > 0;) {
    const auto& s = strategy.steps[k];
    for (const auto& poly : s.preimage.polygons) {
      PolygonWithHoles pw;
      pw.outer.vertices = poly.outer.vertices;
      for (const auto& h : poly.holes) pw.holes.push_back(Polygon{h.vertices});
      c.PolygonWithHoles(pw, fmt::format("class=\"preimage step{}\" fill=\"{}\" fill-opacity=\"0.8\" stroke=\"#036\" "
                                         "stroke-width=\"1.5\" stroke-dasharray=\"6,3\"",
                                         k, kPreimageColours[k % 5]));
    }
  }
  for (const auto& o : scene.obstacles) c.Polygon(o.shape.polygon, "fill=\"#bbb\" stroke=\"#777\" stroke-width=\"1\"");
  for (size_t i = 0; i < cspace.num_c_obstacles(); ++i) {
    for (const auto& pw : cspace.c_obstacle(i)) c.Polygon(pw.outer, "fill=\"none\" stroke=\"#333\" stroke-width=\"1\"");
  }
  c.Polygon(scene.goal.polygon, "class=\"goal\" fill=\"black\" stroke=\"black\"");
  if (scene.start) c.Polygon(scene.start->polygon, "class=\"start\" fill=\"#7c7\" stroke=\"#060\" stroke-width=\"2\"");
  // The camera: its centre and the edges of its field of view.
  if (scene.camera) {
    const double reach = 0.25 * (hi - lo).norm();
    for (const Vector2d& d : {scene.camera->fov_first, scene.camera->fov_second}) {
      c.Line(scene.camera->center, scene.camera->center + reach * d,
             "class=\"camera-fov\" stroke=\"#555\" stroke-width=\"1\" stroke-dasharray=\"4,4\"");
    }
    c.Cross(scene.camera->center, 12, "class=\"camera\" stroke=\"black\" stroke-width=\"2.5\"");
    c.Text(scene.camera->center, "camera", 12, "fill=\"black\"", -52, -8);
  }
  // The rays each step uses: the CVC rays it complies to (dashed), and for a visual guarded step the ray it watches
  // (thin) with the piece it must end on (solid).
  bool uses_rays = false;
  for (const auto& s : strategy.steps) uses_rays = uses_rays || !s.active_rays.empty() || !s.terminate_ref.empty();
  const VcRays rays = scene.camera && uses_rays ? ComputeVcRays(scene, cspace) : VcRays{};
  auto draw_ray = [&](const std::string& id, const std::string& style, const std::string& label) {
    for (const CvcRay& ray : rays.cvc_rays) {
      if (ray.id != id) continue;
      for (const Segment& seg : ray.segments) c.Line(seg.source, seg.target, style);
      if (!ray.segments.empty()) {
        const Segment& seg = ray.segments.front();
        c.Text(0.5 * (seg.source + seg.target), label, 12, fmt::format("fill=\"{}\"", kRayColour), 6, -6);
      }
    }
  };
  for (size_t k = 0; k < strategy.steps.size(); ++k) {
    const auto& s = strategy.steps[k];
    for (const std::string& id : s.active_rays) {
      draw_ray(id,
               fmt::format("class=\"active-ray step{}\" stroke=\"{}\" stroke-width=\"2.5\" stroke-dasharray=\"9,4\"", k,
                           kRayColour),
               fmt::format("{}: step {} complies to it", id, k));
    }
    if (s.terminate == Termination::kVisualGuarded) {
      draw_ray(s.terminate_ref,
               fmt::format("class=\"watched-ray step{}\" stroke=\"{}\" stroke-width=\"1\"", k, kRayColour),
               fmt::format("{}: step {} ends on it", s.terminate_ref, k));
      for (const auto& t : s.target) {
        c.Polygon(Polygon{t.vertices}, fmt::format("class=\"terminate-ray\" fill=\"{0}\" stroke=\"{0}\" "
                                                   "stroke-width=\"3\"",
                                                   kRayColour));
      }
    } else if (s.terminate == Termination::kContact) {
      // Where the contact step sticks: the face's piece (thick orange) or the corner (an orange disc).
      const std::string style = "class=\"contact-target\" stroke=\"#e60\" stroke-width=\"5\" fill=\"#e60\"";
      if (s.end_a == s.end_b) {
        c.Circle(s.end_a, 7, style);
      } else {
        c.Line(s.end_a, s.end_b, style);
      }
      c.Text(s.end_a, fmt::format("step {} sticks here", k), 12, "fill=\"#e60\"", 8, 16);
    }
  }
  // Commanded directions: an arrow per step from the centroid of its preimage's first polygon.
  const double len = 0.07 * (hi - lo).norm();
  for (size_t k = 0; k < strategy.steps.size(); ++k) {
    const auto& s = strategy.steps[k];
    if (s.preimage.polygons.empty()) continue;
    Vector2d centroid = Vector2d::Zero();
    const auto& vs = s.preimage.polygons[0].outer.vertices;
    for (const auto& v : vs) centroid += v;
    centroid /= static_cast<double>(vs.size());
    const Vector2d v(std::cos(s.theta), std::sin(s.theta)), n(-v.y(), v.x());
    const Vector2d tip = centroid + len * v;
    const std::string style = "class=\"direction\" stroke=\"#070\" stroke-width=\"3\"";
    c.Line(centroid, tip, style);
    c.Line(tip, tip - 0.3 * len * v + 0.15 * len * n, style);
    c.Line(tip, tip - 0.3 * len * v - 0.15 * len * n, style);
    c.Text(centroid, fmt::format("step {}: θ = {:.1f}°", k, Deg(s.theta)), 13, "fill=\"#070\"", 6, 14);
  }
}

std::vector<std::vector<SvgCanvas::LegendItem>> StrategyLegend(const Strategy& strategy) {
  std::vector<SvgCanvas::LegendItem> preimages;
  for (size_t k = 0; k < strategy.steps.size() && k < 5; ++k) {
    preimages.push_back({"■", kPreimageColours[k], fmt::format("preimage of step {}", k)});
  }
  preimages.push_back({"➜", "#070", "commanded direction θ"});
  return {{{"■", "#7c7", "start region"},
           {"■", "black",
            "goal: where the robot's reference point (its polygon's origin) must end; it may lie on an "
            "obstacle"}},
          preimages,
          {{"■", "#bbb", "obstacle"},
           {"□", "#333", "C-obstacle: where the reference point cannot go"},
           {"✕", "black", "camera and its field of view"}},
          {{"╍", kRayColour, "CVC ray a step complies to"},
           {"━", kRayColour, "CVC ray piece a step ends on"},
           {"●", "#e60", "where a contact step sticks"}}};
}

std::string StrategyToSvg(const Scene& scene, const CSpace& cspace, const Strategy& strategy) {
  SvgCanvas c(scene.bounds.min, scene.bounds.max, 700);
  DrawStrategy(c, scene, cspace, strategy);
  c.TextPx(10, 18,
           strategy.feasible
               ? fmt::format("{}: {} step(s), numbered from 0 as in the JSON", scene.name, strategy.steps.size())
               : fmt::format("{}: no strategy", scene.name),
           14, "fill=\"black\"");
  c.Legend(StrategyLegend(strategy));
  return c.Finish();
}

}  // namespace visco::planning

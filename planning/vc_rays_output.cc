// JSON and SVG output of the visual constraints (`visco vcrays`).

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "planning/json_lines.h"
#include "planning/svg.h"
#include "planning/vc_rays.h"

namespace visco::planning {
namespace {

nlohmann::json PointJson(const Point& p) { return nlohmann::json::array({p.x(), p.y()}); }

constexpr double kPi = 3.14159265358979323846;

}  // namespace

std::string VcRaysToJson(const Scene& scene, const VcRays& rays) {
  nlohmann::ordered_json j;
  j["scene"] = scene.name;
  if (!scene.digest.empty()) j["scene_digest"] = scene.digest;  // scenes built in code have none
  if (scene.camera) {
    j["camera"] = {{"center", PointJson(scene.camera->center)},
                   {"fov_deg", {scene.camera->fov_first_rad * 180 / kPi, scene.camera->fov_second_rad * 180 / kPi}}};
    if (scene.camera->height) j["camera"]["height"] = *scene.camera->height;
  }
  j["vc_rays"] = nlohmann::json::array();
  for (const VcRay& r : rays.vc_rays) {
    j["vc_rays"].push_back({{"id", r.id},
                            {"obstacle", scene.obstacles[r.obstacle].id},
                            {"vertex", r.vertex},
                            {"from", PointJson(r.from)},
                            {"to", PointJson(r.to)},
                            {"cm_vertices", r.cm_vertices}});
  }
  j["cvc_rays"] = nlohmann::json::array();
  for (const CvcRay& c : rays.cvc_rays) {
    nlohmann::json segments = nlohmann::json::array();
    for (const Segment& s : c.segments) segments.push_back({PointJson(s.source), PointJson(s.target)});
    j["cvc_rays"].push_back({{"id", c.id},
                             {"vc_ray", rays.vc_rays[c.vc_ray].id},
                             {"cm_vertex", c.cm_vertex},
                             {"offset", PointJson(c.offset)},
                             {"segments", segments},
                             // Per segment, its two ends: true where the end is open (the bounds or the camera, not
                             // a C-obstacle): complying to it fails.
                             {"open_ends", c.open_ends}});
  }
  j["cvc_crossings"] = nlohmann::json::array();
  for (const CvcCrossing& x : rays.crossings) {
    j["cvc_crossings"].push_back({{"rays", {rays.cvc_rays[x.first].id, rays.cvc_rays[x.second].id}},
                                  {"point", PointJson(x.point)},
                                  {"overlap", x.overlap}});
  }
  // One line per ray or crossing: readable and diff-friendly.
  return JsonLines(j, 1, 2, false);
}

std::string VcRaysToSvg(const Scene& scene, const CSpace& cspace, const VcRays& rays) {
  // The view: the bounds, the obstacles and the camera.
  Point lo = scene.bounds.min, hi = scene.bounds.max;
  const auto extend = [&](const Point& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  };
  for (const Obstacle& o : scene.obstacles) {
    for (const Point& p : o.shape.polygon.vertices) extend(p);
  }
  if (scene.camera) extend(scene.camera->center);
  for (const PolygonWithHoles& cb : cspace.obstacle_union()) {
    for (const Point& p : cb.outer.vertices) extend(p);
  }
  const Point pad = 0.03 * (hi - lo);
  lo -= pad;
  hi += pad;
  SvgCanvas svg(lo, hi, 1000);
  const double diag = (hi - lo).norm();

  // Bounds, free space edge, C-obstacles, obstacles, goal, start.
  svg.Polygon(Polygon{{scene.bounds.min,
                       {scene.bounds.max.x(), scene.bounds.min.y()},
                       scene.bounds.max,
                       {scene.bounds.min.x(), scene.bounds.max.y()}}},
              "fill=\"none\" stroke=\"#888\" stroke-width=\"1\" stroke-dasharray=\"6,4\"");
  for (const PolygonWithHoles& cb : cspace.obstacle_union()) {
    svg.PolygonWithHoles(cb, "fill=\"#dde6f5\" fill-opacity=\"0.6\" stroke=\"#2b4f9e\" stroke-width=\"1.5\"");
  }
  for (const Obstacle& o : scene.obstacles) {
    svg.Polygon(o.shape.polygon, "fill=\"#9a9a9a\" stroke=\"#333\" stroke-width=\"1\"");
  }
  svg.Polygon(scene.goal.polygon, "fill=\"#111\" stroke=\"none\"");
  if (scene.start) {
    svg.Polygon(scene.start->polygon, "fill=\"#6c6\" fill-opacity=\"0.35\" stroke=\"#393\" stroke-width=\"1\"");
    Point c = Point::Zero();
    for (const Point& p : scene.start->polygon.vertices) c += p;
    c /= static_cast<double>(scene.start->polygon.size());
    svg.Text(c, "start", 12, "fill=\"#393\" text-anchor=\"middle\"");
  }

  // Camera and field of view.
  if (scene.camera) {
    const Camera& cam = *scene.camera;
    for (const Vector& d : {cam.fov_first, cam.fov_second}) {
      svg.Line(cam.center, cam.center + 2 * diag * d, "stroke=\"#c90\" stroke-width=\"1\" stroke-dasharray=\"2,3\"");
    }
    svg.Cross(cam.center, 14, "stroke=\"#000\" stroke-width=\"2.5\"");
    svg.Text(cam.center, "P", 14, "font-weight=\"bold\"", 9, -8);
  }

  // VC rays (workspace) thin orange; CVC rays: the uncut line dotted, free parts solid, one colour per CM vertex.
  for (const VcRay& r : rays.vc_rays) {
    svg.Line(r.from, r.to, "stroke=\"#e08a00\" stroke-width=\"1\" stroke-opacity=\"0.8\"");
    svg.Circle(r.from, 2.5, "fill=\"#e08a00\"");
  }
  const char* colours[] = {"#c0392b", "#1f77b4", "#8e44ad", "#16a085", "#d35400", "#2c3e50"};
  for (const CvcRay& c : rays.cvc_rays) {
    const std::string colour = colours[c.cm_vertex % 6];
    svg.Line(
        c.full.source, c.full.target,
        fmt::format("stroke=\"{}\" stroke-width=\"0.8\" stroke-opacity=\"0.35\" stroke-dasharray=\"1,3\"", colour));
    for (const Segment& s : c.segments) {
      svg.Line(s.source, s.target, fmt::format("stroke=\"{}\" stroke-width=\"1.8\"", colour));
    }
    if (!c.segments.empty()) {
      // Label at the obstacle end of the first free part, nudged off the line.
      const Segment& s = c.segments.front();
      const Point at = s.source + 0.04 * (s.target - s.source);
      svg.Text(at, c.id, 9.5, fmt::format("fill=\"{}\"", colour), 4, -3);
    }
  }
  for (const CvcCrossing& x : rays.crossings) svg.Circle(x.point, 2.2, "fill=\"#000\"");

  // The robot at its start (or at the top-left of the bounds), with its vertex numbers (file order).
  Point q = scene.bounds.min + Point(0.05, 0.9).cwiseProduct(scene.bounds.max - scene.bounds.min);
  if (scene.start) {
    q = Point::Zero();
    for (const Point& p : scene.start->polygon.vertices) q += p;
    q /= static_cast<double>(scene.start->polygon.size());
  }
  Polygon robot = scene.robot.polygon;
  for (Point& p : robot.vertices) p += q;
  svg.Polygon(robot, "fill=\"#f4d03f\" fill-opacity=\"0.8\" stroke=\"#7d6608\" stroke-width=\"1.2\"");
  for (std::size_t i = 0; i < robot.size(); ++i) {
    svg.Text(robot[i], fmt::format("a{}", scene.robot.source_index[i]), 10, "fill=\"#7d6608\"", 3, -3);
  }
  svg.Circle(q, 2.5, "fill=\"#000\"");

  const double y0 = svg.height_px() - 40;
  svg.TextPx(30, y0,
             fmt::format("{}: {} VC rays (orange), {} CVC rays (colour = CM vertex aj; solid = free part, dotted = cut "
                         "inside CB), {} crossings (dots)",
                         scene.name, rays.vc_rays.size(), rays.cvc_rays.size(), rays.crossings.size()),
             12, "fill=\"#222\"");
  svg.TextPx(30, y0 + 18,
             "grey: obstacles; blue outline: C-obstacles (CB); black: goal; green: start; yellow: robot at start; "
             "cross: camera P, dotted: field of view",
             12, "fill=\"#222\"");
  return svg.Finish();
}

}  // namespace visco::planning

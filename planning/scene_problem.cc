#include "planning/scene_problem.h"

#include <string>
#include <utility>

#include "planning/cspace.h"
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
}  // namespace visco::planning

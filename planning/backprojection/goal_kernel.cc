// The goal kernel: the goal eroded by the position uncertainty, from inside (backprojection.h, GoalKernel).

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Polygon_set_2.h>
#include <CGAL/Polygon_with_holes_2.h>
#include <CGAL/convex_hull_2.h>

#include <cmath>
#include <iterator>
#include <string>
#include <vector>

#include "planning/backprojection.h"

namespace visco::planning {
namespace {

using K = CGAL::Exact_predicates_exact_constructions_kernel;
using P2 = K::Point_2;
using ExactPolygon = CGAL::Polygon_2<K>;
using ExactPolygonWithHoles = CGAL::Polygon_with_holes_2<K>;
using PolygonSet = CGAL::Polygon_set_2<K>;
using Eigen::Vector2d;

}  // namespace

std::vector<NamedPolygon> GoalKernel(const std::vector<NamedPolygon>& goal, double position_uncertainty, int sides) {
  std::vector<NamedPolygon> out;
  if (position_uncertainty <= 0.0) return goal;
  const double r = position_uncertainty / std::cos(M_PI / sides);  // circumscribes the disc
  for (size_t gi = 0; gi < goal.size(); ++gi) {
    const auto& g = goal[gi];
    ExactPolygon poly;
    for (const auto& v : g.vertices) poly.push_back(P2(v.x(), v.y()));
    if (poly.is_clockwise_oriented()) poly.reverse_orientation();
    PolygonSet kernel(poly);
    for (size_t i = 0; i < g.vertices.size(); ++i) {
      const Vector2d& a = g.vertices[i];
      const Vector2d& b = g.vertices[(i + 1) % g.vertices.size()];
      std::vector<P2> pts;
      for (int k = 0; k < sides; ++k) {
        const double ang = 2 * M_PI * k / sides;
        const Vector2d d(r * std::cos(ang), r * std::sin(ang));
        pts.emplace_back(a.x() + d.x(), a.y() + d.y());
        pts.emplace_back(b.x() + d.x(), b.y() + d.y());
      }
      std::vector<P2> hull;
      CGAL::convex_hull_2(pts.begin(), pts.end(), std::back_inserter(hull));
      kernel.difference(ExactPolygon(hull.begin(), hull.end()));
    }
    std::vector<ExactPolygonWithHoles> parts;
    kernel.polygons_with_holes(std::back_inserter(parts));
    for (size_t pi = 0; pi < parts.size(); ++pi) {
      NamedPolygon np;
      const ExactPolygon& ob = parts[pi].outer_boundary();
      size_t k = 0;
      for (auto v = ob.vertices_begin(); v != ob.vertices_end(); ++v, ++k) {
        np.vertices.emplace_back(CGAL::to_double(v->x()), CGAL::to_double(v->y()));
        const std::string base = "kernel(goal[" + std::to_string(gi) + "])[" + std::to_string(pi) + "]";
        np.vertex_refs.push_back(base + ".v[" + std::to_string(k) + "]");
        np.edge_refs.push_back(base + ".e[" + std::to_string(k) + "]");
      }
      out.push_back(std::move(np));
    }
  }
  return out;
}

}  // namespace visco::planning

#pragma once
// Seeded random scenes for the planning property tests and benchmarks: convex C-obstacles scattered in a 10 x 10
// box, a goal in the lower half (sometimes resting on a floor), a commanded direction roughly downwards, random
// uncertainty and friction, and (optionally) random candidate CVC rays.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "common/motion_model.h"
#include "planning/backprojection.h"
#include "planning/cspace.h"
#include "tests/planning/seed_offset.h"

namespace visco::planning {

class SceneRng {
 public:
  explicit SceneRng(std::uint64_t seed) : rng_(seed) {}
  double Uniform(double lo, double hi) {
    return lo + (hi - lo) * static_cast<double>(rng_() >> 11) * (1.0 / 9007199254740992.0);
  }
  int Int(int lo, int hi) { return lo + static_cast<int>(rng_() % static_cast<std::uint64_t>(hi - lo + 1)); }

 private:
  std::mt19937_64 rng_;
};

inline NamedPolygon RandomConvex(SceneRng& r, double cx, double cy, double radius) {
  const int n = r.Int(3, 6);
  std::vector<double> angles;
  for (int i = 0; i < n; ++i) angles.push_back(r.Uniform(0, 2 * M_PI));
  std::sort(angles.begin(), angles.end());
  NamedPolygon p;
  for (double a : angles) p.vertices.emplace_back(cx + radius * std::cos(a), cy + radius * std::sin(a));
  return p;
}

inline bool InsideConvexOrAny(const NamedPolygon& poly, const Eigen::Vector2d& p) {
  bool inside = false;
  const auto& v = poly.vertices;
  for (size_t i = 0, j = v.size() - 1; i < v.size(); j = i++) {
    if ((v[i].y() > p.y()) != (v[j].y() > p.y())) {
      const double x = v[i].x() + (p.y() - v[i].y()) * (v[j].x() - v[i].x()) / (v[j].y() - v[i].y());
      if (p.x() < x) inside = !inside;
    }
  }
  return inside;
}

/// The parts of segment [a, b] inside the bounds and outside every obstacle (as CVC rays are, docs/semantics.md), with
/// their open ends: an end is closed only where an obstacle edge cuts the segment (a bounds cut and the segment's own
/// ends in free space are open, like a clipped CVC ray's end and its camera end).
struct FreeParts {
  std::vector<std::array<Eigen::Vector2d, 2>> segments;
  std::vector<std::array<bool, 2>> open_ends;
};

inline FreeParts CutToFreeSpace(const BackprojectionProblem& pr, Eigen::Vector2d a, Eigen::Vector2d b) {
  std::vector<std::pair<double, bool>> ts = {{0.0, true}, {1.0, true}};  // (parameter, open)
  const Eigen::Vector2d d = b - a;
  for (int axis = 0; axis < 2; ++axis) {
    if (d[axis] == 0) continue;
    for (double bound : {pr.bounds_min[axis], pr.bounds_max[axis]}) ts.emplace_back((bound - a[axis]) / d[axis], true);
  }
  for (const auto& o : pr.obstacles) {
    for (size_t i = 0; i < o.vertices.size(); ++i) {
      const Eigen::Vector2d c = o.vertices[i], e = o.vertices[(i + 1) % o.vertices.size()] - c;
      const double den = d.x() * e.y() - d.y() * e.x();
      if (std::abs(den) < 1e-15) continue;
      const Eigen::Vector2d ac = c - a;
      const double t = (ac.x() * e.y() - ac.y() * e.x()) / den;
      const double s = (ac.x() * d.y() - ac.y() * d.x()) / den;
      if (s >= 0 && s <= 1) ts.emplace_back(t, false);
    }
  }
  // At equal parameters an obstacle cut (closed) comes first: a contact there stops the compliance.
  std::sort(ts.begin(), ts.end());
  FreeParts out;
  for (size_t i = 0; i + 1 < ts.size(); ++i) {
    const double t0 = std::max(ts[i].first, 0.0), t1 = std::min(ts[i + 1].first, 1.0);
    if (t1 - t0 < 1e-6) continue;
    const Eigen::Vector2d mid = a + 0.5 * (t0 + t1) * d;
    if (mid.x() < pr.bounds_min.x() || mid.x() > pr.bounds_max.x() || mid.y() < pr.bounds_min.y() ||
        mid.y() > pr.bounds_max.y()) {
      continue;
    }
    bool blocked = false;
    for (const auto& o : pr.obstacles) blocked |= InsideConvexOrAny(o, mid);
    if (blocked) continue;
    const Eigen::Vector2d p0 = a + t0 * d, p1 = a + t1 * d;
    // The open flag of an end: closed if any obstacle edge meets the segment there.
    const auto open_at = [&](double t) {
      for (const auto& [u, open] : ts) {
        if (!open && std::abs(u - t) < 1e-12) return false;
      }
      return true;
    };
    if (!out.segments.empty() && (out.segments.back()[1] - p0).norm() < 1e-12) {
      out.segments.back()[1] = p1;
      out.open_ends.back()[1] = open_at(t1);
    } else {
      out.segments.push_back({p0, p1});
      out.open_ends.push_back({open_at(t0), open_at(t1)});
    }
  }
  return out;
}

// A random straight ray starting above the goal's bottom edge, pointing down at an angle in [min_deg, max_deg] (from
// +x), 2 to max_length long, cut to free space (its segments may be empty).
inline CvcRayInput RandomRay(const BackprojectionProblem& pr, SceneRng& r, std::string id, double min_deg,
                             double max_deg, double max_length) {
  CvcRayInput ray;
  ray.id = std::move(id);
  const double gy = pr.goal[0].vertices[0].y();
  const double ax = r.Uniform(0, 10), ay = r.Uniform(gy, 10);
  const double ang = r.Uniform(min_deg, max_deg) * M_PI / 180, len = r.Uniform(2, max_length);
  FreeParts parts =
      CutToFreeSpace(pr, Eigen::Vector2d(ax, ay), Eigen::Vector2d(ax + len * std::cos(ang), ay + len * std::sin(ang)));
  ray.segments = std::move(parts.segments);
  ray.open_ends = std::move(parts.open_ends);
  return ray;
}

inline BackprojectionProblem RandomScene(std::uint64_t seed, bool with_rays = false) {
  SceneRng r((seed + testing::SeedOffset()) * 0x9E3779B97F4A7C15ULL + 17);
  BackprojectionProblem pr;
  pr.bounds_min = {0, 0};
  pr.bounds_max = {10, 10};
  const bool floor = r.Uniform(0, 1) < 0.5;
  const double gx = r.Uniform(1, 7), gw = r.Uniform(0.5, 2.0);
  const double gy = floor ? 1.0 : r.Uniform(1, 5), gh = r.Uniform(0.3, 1.0);
  if (floor) {
    NamedPolygon f;
    f.vertices = {{-1, -1}, {11, -1}, {11, 1}, {-1, 1}};
    pr.obstacles.push_back(f);
  }
  NamedPolygon goal;
  goal.vertices = {{gx, gy}, {gx + gw, gy}, {gx + gw, gy + gh}, {gx, gy + gh}};
  pr.goal.push_back(goal);
  const int k = r.Int(2, 5);
  for (int i = 0; i < k; ++i) {
    const double cx = r.Uniform(0.5, 9.5), cy = r.Uniform(gy + gh + 0.5, 9.5), rad = r.Uniform(0.3, 1.2);
    pr.obstacles.push_back(RandomConvex(r, cx, cy, rad));
  }
  pr.theta = r.Uniform(-135, -45) * M_PI / 180;
  pr.velocity_cone = r.Uniform(3, 15) * M_PI / 180;
  pr.friction_cone = r.Uniform(5, 40) * M_PI / 180;
  if (with_rays) {
    const int nr = r.Int(2, 6);
    for (int i = 0; i < nr; ++i) {
      CvcRayInput ray = RandomRay(pr, r, "ray" + std::to_string(i), -150, -30, 8);
      ray.group = "vc" + std::to_string(i / 2);
      if (!ray.segments.empty()) pr.rays.push_back(ray);
    }
  }
  return pr;
}

/// The motion model's view of a backprojection problem with the given rays active. The problem's C-obstacles must
/// have no holes (a hole ring would become a solid obstacle): for a scene's problem, whose CB is the union of the
/// C-obstacles with its holes, use the overload with the CSpace.
inline MotionWorld ToMotionWorld(const BackprojectionProblem& pr, const std::vector<std::string>& active) {
  MotionWorld w;
  for (const auto& o : pr.obstacles) w.obstacles.push_back(o.vertices);
  for (const auto& g : pr.goal) w.goal.push_back(g.vertices);
  w.bounds_min = pr.bounds_min;
  w.bounds_max = pr.bounds_max;
  w.friction_cone = pr.friction_cone;
  for (const auto& id : active) {
    for (const auto& ray : pr.rays) {
      if (ray.id != id) continue;
      for (size_t k = 0; k < ray.segments.size(); ++k) {
        w.active_rays.push_back(ray.segments[k]);
        w.active_ray_open_ends.push_back(k < ray.open_ends.size() ? ray.open_ends[k] : std::array<bool, 2>{});
      }
    }
  }
  return w;
}

/// As the product's simulated robot sees a scene (control's MakeMotionWorld): one solid polygon per C-obstacle part
/// (the outer boundary of each CB_i; a pocket between two C-obstacles stays free, a hole of one CB_i is unreachable
/// from outside), with the problem's rays.
inline MotionWorld ToMotionWorld(const CSpace& cspace, const BackprojectionProblem& pr,
                                 const std::vector<std::string>& active) {
  BackprojectionProblem solid = pr;
  solid.obstacles.clear();
  for (std::size_t i = 0; i < cspace.num_c_obstacles(); ++i) {
    for (const PolygonWithHoles& part : cspace.c_obstacle(i)) {
      NamedPolygon np;
      for (const Point& v : part.outer.vertices) np.vertices.push_back(v);
      solid.obstacles.push_back(std::move(np));
    }
  }
  return ToMotionWorld(solid, active);
}

}  // namespace visco::planning

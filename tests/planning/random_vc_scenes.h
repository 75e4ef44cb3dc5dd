#pragma once
// Seeded random scenes for property tests and benchmarks: star-shaped obstacles in grid cells, some touching
// (cell-filling rectangles), overlapping their neighbours on request, coordinates on a coarse lattice so that collinear
// vertices, vertices on each other's projection rays, robot edges parallel to rays and cameras on supporting lines
// happen often.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "planning/cspace.h"
#include "planning/scene.h"
#include "tests/planning/seed_offset.h"

namespace visco::planning::testing {

struct RandomSceneOptions {
  int cells_x = 4;
  int cells_y = 4;
  double cell = 4.0;       // cell size
  double lattice = 0.5;    // coordinates are multiples of this (0: continuous)
  double fill = 0.6;       // probability that a cell holds an obstacle
  double touching = 0.15;  // probability that an obstacle fills its whole cell (touching its neighbours)
  int max_vertices = 7;    // per obstacle
  double overlap = 0.0;    // probability that an obstacle reaches into its neighbours' cells (overlapping them)
};

inline double Snap(double v, double lattice) { return lattice > 0 ? std::round(v / lattice) * lattice : v; }

// A star-shaped simple polygon around c within radius r, counter-clockwise.
inline Polygon StarPolygon(std::mt19937_64& rng, const Point& c, double r, int max_vertices, double lattice) {
  std::uniform_int_distribution<int> count(3, std::max(3, max_vertices));
  std::uniform_real_distribution<double> unit(0, 1);
  for (int attempt = 0; attempt < 100; ++attempt) {
    const int n = count(rng);
    std::vector<double> angles(n);
    for (double& a : angles) a = unit(rng) * 2 * M_PI;
    std::sort(angles.begin(), angles.end());
    Polygon p;
    for (double a : angles) {
      const double radius = r * (0.3 + 0.7 * unit(rng));
      p.vertices.push_back({Snap(c.x() + radius * std::cos(a), lattice), Snap(c.y() + radius * std::sin(a), lattice)});
    }
    if (IsSimple(p) && PolygonOrientation(p) > 0) return p;
  }
  return Polygon{{c + Point(-r / 2, -r / 2), c + Point(r / 2, -r / 2), c + Point(0, r / 2)}};
}

inline Scene RandomScene(std::uint64_t seed, const RandomSceneOptions& o = {}) {
  seed += SeedOffset();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  Scene s;
  s.name = "random" + std::to_string(seed);
  s.source = s.name;
  s.bounds = {{0, 0}, {o.cells_x * o.cell, o.cells_y * o.cell}};
  const auto as_scene_polygon = [](Polygon p) {
    ScenePolygon sp;
    sp.polygon = std::move(p);
    for (std::size_t i = 0; i < sp.polygon.size(); ++i) sp.source_index.push_back(static_cast<int>(i));
    return sp;
  };
  for (int cx = 0; cx < o.cells_x; ++cx) {
    for (int cy = 0; cy < o.cells_y; ++cy) {
      if (unit(rng) > o.fill) continue;
      const Point lo(cx * o.cell, cy * o.cell);
      Polygon p;
      if (o.overlap > 0 && unit(rng) < o.overlap) {  // no draw otherwise: the other tests' scenes stay the same
        // A rectangle or a star that reaches into the neighbouring cells: obstacles overlap (docs/semantics.md allows
        // it).
        const double grow = o.cell * (0.2 + 0.4 * unit(rng));
        if (unit(rng) < 0.5) {
          const Point a(Snap(lo.x() - grow, o.lattice), Snap(lo.y() + 0.3 * o.cell, o.lattice));
          const Point b(Snap(lo.x() + o.cell + grow, o.lattice), Snap(lo.y() + 0.7 * o.cell, o.lattice));
          p.vertices = {a, {b.x(), a.y()}, b, {a.x(), b.y()}};
        } else {
          p = StarPolygon(rng, lo + Point(o.cell / 2, o.cell / 2), o.cell / 2 + grow, o.max_vertices, o.lattice);
        }
      } else if (unit(rng) < o.touching) {
        p.vertices = {lo, lo + Point(o.cell, 0), lo + Point(o.cell, o.cell), lo + Point(0, o.cell)};
      } else {
        // Snapping moves a vertex by at most lattice / 2: it stays in the closed cell (it may touch a neighbour).
        p = StarPolygon(rng, lo + Point(o.cell / 2, o.cell / 2), o.cell / 2 - o.lattice / 2 - 1e-9, o.max_vertices,
                        o.lattice);
      }
      s.obstacles.push_back({"o" + std::to_string(s.obstacles.size()), as_scene_polygon(std::move(p)), std::nullopt});
    }
  }
  s.robot = as_scene_polygon(StarPolygon(rng, {0, 0}, 1.0, 6, o.lattice));
  s.goal = as_scene_polygon(Polygon{{{0, 0}, {1, 0}, {1, 1}, {0, 1}}});
  // Camera: a lattice point not inside any obstacle (often on a boundary or a supporting line).
  Camera cam;
  for (int attempt = 0; attempt < 1000; ++attempt) {
    cam.center = {Snap(unit(rng) * s.bounds.max.x(), o.lattice > 0 ? o.lattice : 0.25),
                  Snap(unit(rng) * s.bounds.max.y(), o.lattice > 0 ? o.lattice : 0.25)};
    bool inside = false;
    for (const Obstacle& ob : s.obstacles) inside = inside || Locate(ob.shape.polygon, cam.center) == Location::kInside;
    if (!inside) break;
  }
  // Field of view: multiples of 15 degrees, 15 to 165 wide.
  const double first = 15.0 * std::uniform_int_distribution<int>(0, 23)(rng);
  const double span = 15.0 * std::uniform_int_distribution<int>(1, 11)(rng);
  const auto dir = [](double deg) {
    const double r = deg * M_PI / 180;
    Vector d(std::cos(r), std::sin(r));
    for (double& c : d) {
      if (std::abs(c) < 1e-15) c = 0;
    }
    return d;
  };
  cam.fov_first_rad = first * M_PI / 180;
  cam.fov_second_rad = (first + span) * M_PI / 180;
  cam.fov_first = dir(first);
  cam.fov_second = dir(first + span);
  s.camera = cam;
  s.uncertainty = {0.1, 0.05};
  s.friction_cone_rad = 0.2;
  return s;
}

// A whole random scene for the VC property tests: cells_x x cells_y cells of 4 m (3 x 3 by default), star-shaped
// (non-convex) obstacles, some overlapping; the camera on the edge of the bounds for two seeds in three, anywhere
// otherwise; a small goal in free space (with `goal_on_cb`, around a point of CB's boundary instead: a goal resting on
// a surface, partly inside CB, where motions slide and rays land into it); θ and ε_v random.
inline bool RandomWholeScene(std::uint64_t seed, Scene& s, double& theta, int cells_x = 3, int cells_y = 3,
                             bool goal_on_cb = false) {
  testing::RandomSceneOptions o;
  o.cells_x = cells_x;
  o.cells_y = cells_y;
  o.fill = 0.45;
  const std::uint64_t raw_seed = seed;
  seed += SeedOffset();  // testing::RandomScene shifts its own
  o.lattice = seed % 3 == 0 ? 0.0 : 0.5;
  o.overlap = seed % 4 == 0 ? 0.4 : 0.0;
  s = testing::RandomScene(raw_seed, o);
  std::mt19937_64 rng(seed * 7919 + 1);
  std::uniform_real_distribution<double> unit(0, 1);
  const CSpace probe(s);
  if (seed % 3 != 0) {
    // On one side of the bounds, facing inwards.
    const int side = static_cast<int>(seed % 4);
    const double t = unit(rng);
    const Eigen::Vector2d lo = s.bounds.min, hi = s.bounds.max;
    const Eigen::Vector2d c = side == 0   ? Eigen::Vector2d(lo.x() + t * (hi.x() - lo.x()), lo.y())
                              : side == 1 ? Eigen::Vector2d(hi.x(), lo.y() + t * (hi.y() - lo.y()))
                              : side == 2 ? Eigen::Vector2d(lo.x() + t * (hi.x() - lo.x()), hi.y())
                                          : Eigen::Vector2d(lo.x(), lo.y() + t * (hi.y() - lo.y()));
    bool inside = false;
    for (const Obstacle& ob : s.obstacles) inside |= Locate(ob.shape.polygon, c) == Location::kInside;
    if (!inside) {
      const double first = 90.0 * side + 5.0;  // a 170° view into the box
      s.camera->center = c;
      s.camera->fov_first_rad = first * M_PI / 180;
      s.camera->fov_second_rad = (first + 170.0) * M_PI / 180;
      s.camera->fov_first = {std::cos(s.camera->fov_first_rad), std::sin(s.camera->fov_first_rad)};
      s.camera->fov_second = {std::cos(s.camera->fov_second_rad), std::sin(s.camera->fov_second_rad)};
    }
  }
  // A goal rectangle whose corners are free (the region may still graze CB; the sweep clips it).
  for (int attempt = 0; attempt < 200; ++attempt) {
    const double w = 0.4 + unit(rng), h = 0.3 + 0.6 * unit(rng);
    double x = s.bounds.min.x() + unit(rng) * (s.bounds.max.x() - s.bounds.min.x() - w);
    double y = s.bounds.min.y() + unit(rng) * (s.bounds.max.y() - s.bounds.min.y() - h);
    if (goal_on_cb && probe.num_c_obstacles() > 0) {
      // Around a random point of a random C-obstacle's outer boundary, anywhere within the rectangle.
      const auto& c_obstacle = probe.c_obstacle(static_cast<std::size_t>(unit(rng) * probe.num_c_obstacles()));
      if (c_obstacle.empty()) continue;
      const auto& ring = c_obstacle[static_cast<std::size_t>(unit(rng) * c_obstacle.size())].outer.vertices;
      const std::size_t k = static_cast<std::size_t>(unit(rng) * ring.size());
      const Point on = ring[k] + unit(rng) * (ring[(k + 1) % ring.size()] - ring[k]);
      x = std::clamp(on.x() - unit(rng) * w, s.bounds.min.x(), s.bounds.max.x() - w);
      y = std::clamp(on.y() - unit(rng) * h, s.bounds.min.y(), s.bounds.max.y() - h);
    }
    Polygon g{{{x, y}, {x + w, y}, {x + w, y + h}, {x, y + h}}};
    int free_points = 0;
    for (const Point& v : g.vertices) free_points += probe.Locate(v) == Location::kOutside;
    free_points += probe.Locate(Point(x + w / 2, y + h / 2)) == Location::kOutside;
    if (goal_on_cb ? free_points == 0 : free_points < 5) continue;
    s.goal.polygon = g;
    s.goal.source_index = {0, 1, 2, 3};
    s.uncertainty.velocity_cone_rad = (2.0 + 18.0 * unit(rng)) * M_PI / 180;
    s.friction_cone_rad = (5.0 + 30.0 * unit(rng)) * M_PI / 180;
    theta = (-180.0 + 360.0 * unit(rng)) * M_PI / 180;
    // The servo's tracking error: none (the papers' exact compliance) for one seed in five, else up to 10 cm.
    s.uncertainty.vc_tracking = seed % 5 == 0 ? 0.0 : 0.1 * unit(rng);
    return true;
  }
  return false;
}

// A start region for a RandomWholeScene: a 0.3 m square `near`-`far` m from the goal's centre (default 1-2.5), kept
// where it is free, and a velocity cone of `cone_lo`-`cone_hi` degrees (default 2-8°, narrower than the scene's, so
// that strategies exist often enough to be worth checking). False if no place was found in 200 tries.
inline bool PlaceStartRegion(std::uint64_t seed, Scene& s, double near = 1.0, double far = 2.5, double cone_lo = 2.0,
                             double cone_hi = 8.0) {
  const CSpace cspace(s);
  std::mt19937_64 rng(seed * 101);
  std::uniform_real_distribution<double> u(0, 1);
  s.uncertainty.velocity_cone_rad = (cone_lo + (cone_hi - cone_lo) * u(rng)) * M_PI / 180;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (const auto& v : s.goal.polygon.vertices) centre += v / 4.0;
  for (int attempt = 0; attempt < 200; ++attempt) {
    const double a = 2 * M_PI * u(rng), d = near + (far - near) * u(rng);
    const Eigen::Vector2d c = centre + d * Eigen::Vector2d(std::cos(a), std::sin(a));
    Polygon r{{c + Eigen::Vector2d(-0.15, -0.15), c + Eigen::Vector2d(0.15, -0.15), c + Eigen::Vector2d(0.15, 0.15),
               c + Eigen::Vector2d(-0.15, 0.15)}};
    bool ok = true;
    for (auto& v : r.vertices) ok = ok && s.bounds.Contains(v) && cspace.Locate(v) == Location::kOutside;
    ok = ok && cspace.Locate(c) == Location::kOutside;
    if (!ok) continue;
    ScenePolygon sp;
    sp.polygon = r;
    sp.source_index = {0, 1, 2, 3};
    s.start = sp;
    return true;
  }
  return false;
}

}  // namespace visco::planning::testing

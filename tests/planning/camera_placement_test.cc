// Camera placement (`visco camera`): the viewing cells against the slow reference visibility on seeded
// random scenes (overlapping, non-convex, lattice-aligned: cameras on supporting lines are common), the candidates'
// evaluation against the planner itself, and the best camera's strategy checked by the adversarial simulator.

#include "planning/camera_placement.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <optional>
#include <random>
#include <string>

#include "common/error.h"
#include "planning/cspace.h"
#include "planning/scene_file.h"
#include "planning/strategy.h"
#include "planning/vc_rays.h"
#include "random_vc_scenes.h"

namespace visco::planning {
namespace {

#if defined(__SANITIZE_ADDRESS__)
constexpr bool kSanitized = true;  // exact arithmetic is tens of times slower: fewer scenes, cells and points
#else
constexpr bool kSanitized = false;
#endif

// What the planner sees from p with a field of view of the whole circle, by the O(n (n + m)) reference.
std::vector<ViewVertex> ReferenceView(const Scene& scene, const Point& p,
                                      std::optional<double> camera_height = std::nullopt) {
  Scene probe = scene;
  std::vector<ViewVertex> view;
  for (double first : {0.0, 120.0, 240.0}) {
    probe.camera = MakePlanarCamera(p, first, 125.0);
    probe.camera->height = camera_height;
    for (const UnoccludedVertex& u : FindUnoccludedVerticesReference(probe)) {
      view.push_back({u.obstacle, u.vertex, u.cm[0], u.cm[1]});
    }
  }
  std::sort(view.begin(), view.end());
  view.erase(std::unique(view.begin(), view.end()), view.end());
  return view;
}

// Up to `count` distinct cell indices, in random order.
std::vector<std::size_t> RandomCells(const ViewingCells& cells, std::size_t count, std::mt19937_64& rng) {
  std::vector<std::size_t> pick(cells.cells.size());
  for (std::size_t i = 0; i < pick.size(); ++i) pick[i] = i;
  std::shuffle(pick.begin(), pick.end(), rng);
  pick.resize(std::min(pick.size(), count));
  return pick;
}

// A random convex combination of a cell's vertices, pulled towards its sample: strictly inside, away from the rounded
// boundary.
Point RandomPointInside(const ViewingCell& cell, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(0, 1);
  Point p(0, 0);
  double total = 0;
  for (const Point& v : cell.polygon.vertices) {
    const double w = unit(rng);
    p += w * v;
    total += w;
  }
  return cell.sample + 0.9 * (p / total - cell.sample);
}

Scene SmallRandomScene(std::uint64_t seed) {
  testing::RandomSceneOptions o;
  o.cells_x = 3;
  o.cells_y = 2;
  o.cell = 3.0;
  o.fill = 0.5;
  o.max_vertices = 5;
  o.lattice = seed % 3 == 0 ? 0.0 : 0.5;
  o.overlap = seed % 4 == 0 ? 0.5 : 0.0;
  return testing::RandomScene(seed, o);
}

// The property that makes one evaluation per cell enough: the view is the same everywhere inside a cell. Checked at
// random points of every cell (convex combinations of its vertices, kept off its boundary), and the cell's sample
// against a point drawn uniformly in the region and located by brute force.
TEST(ViewingCells, TheViewIsTheSameEverywhereInACell) {
  int cells_checked = 0, points_checked = 0, scenes = 0;
  const std::uint64_t last_seed = kSanitized ? 4 : 24;
  for (std::uint64_t seed = 1; seed <= last_seed; ++seed) {
    const Scene scene = SmallRandomScene(seed);
    if (scene.obstacles.empty()) continue;
    ++scenes;
    const ViewingCells cells = ComputeViewingCells(scene, scene.bounds.min, scene.bounds.max);
    ASSERT_FALSE(cells.cells.empty()) << scene.name;
    // At most the faces of L lines in general position plus the rectangle's (a bound a spurious face would break).
    const long long l = cells.event_lines + 4;
    EXPECT_LE(cells.faces, l * (l + 1) / 2 + 1) << scene.name;
    EXPECT_LE(cells.views, static_cast<int>(cells.cells.size())) << scene.name;
    std::mt19937_64 rng(seed);
    for (std::size_t i : RandomCells(cells, kSanitized ? 3 : 12, rng)) {
      const ViewingCell& cell = cells.cells[i];
      if (cell.area < 1e-6) continue;
      const std::vector<ViewVertex> expected = ReferenceView(scene, cell.sample);
      EXPECT_EQ(ViewFrom(scene, cell.sample), expected) << scene.name << " cell " << i;
      ++cells_checked;
      for (int k = 0; k < 3; ++k) {
        const Point p = RandomPointInside(cell, rng);
        EXPECT_EQ(ReferenceView(scene, p), expected)
            << scene.name << ": the view changes inside cell " << i << " at (" << p.x() << ", " << p.y() << ")";
        ++points_checked;
      }
    }
  }
  EXPECT_GE(scenes, kSanitized ? 2 : 15);
  EXPECT_GE(cells_checked, kSanitized ? 6 : 150);
  RecordProperty("cells_checked", cells_checked);
  RecordProperty("points_checked", points_checked);
}

// The same with heights (2.5D): candidates 3 m up, most obstacles prisms 0.5-4 m high (some taller than the
// camera). The homothetic images of the prisms' edges are event lines too; without them the view would change inside
// cells (checked: the heights change the view of some cells, so the property is not met by accident).
TEST(ViewingCells, TheViewIsTheSameEverywhereInACellWithHeights) {
  int cells_checked = 0, scenes = 0, changed_by_heights = 0;
  const double height = 3.0;
  const std::uint64_t last_seed = kSanitized ? 2 : 8;
  for (std::uint64_t seed = 1; seed <= last_seed; ++seed) {
    Scene scene = SmallRandomScene(seed);
    if (scene.obstacles.empty()) continue;
    std::mt19937_64 rng(seed * 31 + 3);
    std::uniform_real_distribution<double> unit(0, 1);
    for (Obstacle& o : scene.obstacles) {
      if (unit(rng) < 0.8) o.height = 0.5 + 3.5 * unit(rng);
    }
    ++scenes;
    const ViewingCells cells = ComputeViewingCells(scene, scene.bounds.min, scene.bounds.max, height);
    const ViewingCells flat = ComputeViewingCells(scene, scene.bounds.min, scene.bounds.max);
    EXPECT_GE(cells.event_lines, flat.event_lines) << scene.name;
    for (std::size_t i : RandomCells(cells, kSanitized ? 3 : 10, rng)) {
      const ViewingCell& cell = cells.cells[i];
      if (cell.area < 1e-6) continue;
      const std::vector<ViewVertex> expected = ReferenceView(scene, cell.sample, height);
      EXPECT_EQ(ViewFrom(scene, cell.sample, height), expected) << scene.name << " cell " << i;
      changed_by_heights += expected != ReferenceView(scene, cell.sample);
      ++cells_checked;
      for (int k = 0; k < 3; ++k) {
        const Point p = RandomPointInside(cell, rng);
        EXPECT_EQ(ReferenceView(scene, p, height), expected)
            << scene.name << ": the view changes inside cell " << i << " at (" << p.x() << ", " << p.y() << ")";
      }
    }
  }
  EXPECT_GE(scenes, kSanitized ? 1 : 5);
  EXPECT_GE(cells_checked, kSanitized ? 3 : 50);
  if (testing::DesignedSeeds()) {  // not vacuous
    EXPECT_GT(changed_by_heights, kSanitized ? 0 : 10);
  }
}

// Across the event lines the view does change (the cells are not merely a fine grid): fig13 and slot have several
// views. corner.json has one: from anywhere in its free quadrant the same two vertices, (10, 0.5) and (0.5, 6), are
// in view (the inner corner is a crossing of the floor's and the wall's edges, no vertex), and the lines where their
// CM vertices change (axis-parallel through them: the robot is a square) are the free region's own boundary.
TEST(ViewingCells, CellsSeparateDifferentViewsOnTheExampleScenes) {
  for (const char* name : {"fig13", "corner", "slot"}) {
    const Scene scene = LoadScene(std::string("data/scenes/") + name + ".json");
    const ViewingCells cells = ComputeViewingCells(scene, scene.bounds.min, scene.bounds.max);
    if (std::string(name) == "corner") {
      EXPECT_EQ(cells.views, 1);
      ASSERT_FALSE(cells.cells.empty());
      EXPECT_EQ(ViewFrom(scene, cells.cells.front().sample).size(), 2u);
    } else {
      EXPECT_GT(cells.views, 1) << name;
    }
    EXPECT_GT(cells.event_lines, 0) << name;
    double area = 0;
    for (const ViewingCell& c : cells.cells) {
      area += c.area;
      EXPECT_GT(c.area, 0) << name;
      EXPECT_EQ(c.polygon.size() >= 3, true) << name;
    }
    // The cells and the obstacles inside the bounds tile the bounds.
    const Vector size = scene.bounds.max - scene.bounds.min;
    EXPECT_LE(area, size.x() * size.y() * (1 + 1e-9)) << name;
    EXPECT_GT(area, 0.3 * size.x() * size.y()) << name;
  }
}

TEST(CameraPlacement, GridCandidatesAreCentredAndOutsideTheObstacles) {
  const Scene scene = LoadScene("data/scenes/fig13.json");
  const std::vector<Point> grid = GridCandidates(scene, scene.bounds.min, scene.bounds.max, 1.0);
  ASSERT_FALSE(grid.empty());
  for (const Point& p : grid) {
    EXPECT_TRUE(scene.bounds.Contains(p));
    for (const Obstacle& o : scene.obstacles) EXPECT_EQ(Locate(o.shape.polygon, p), Location::kOutside);
  }
  // fig13: bounds [0, 10] x [1, 8], spacing 1: x = 0..10 and y = 1..8 (centred), the post [2, 3] x [1, 3] and the
  // floor's top edge y = 1 excluded.
  EXPECT_EQ(grid.front(), Point(0, 2));
  EXPECT_THROW(GridCandidates(scene, scene.bounds.min, scene.bounds.max, 0.0), InputError);
}

TEST(CameraPlacement, RankingIsAStrictWeakOrderThatPrefersFewerSteps) {
  std::mt19937_64 rng(7);
  std::uniform_int_distribution<int> small(0, 2);
  std::vector<CameraEvaluation> e(200);
  for (CameraEvaluation& x : e) {
    x.feasible = small(rng) != 0;
    x.steps = x.feasible ? 1 + small(rng) : 0;
    x.min_interval_deg = small(rng);
    x.preimage_area = small(rng);
    x.coverage = x.feasible ? 1.0 : 0.5 * small(rng);
    x.center = Point(small(rng), small(rng));
  }
  for (const auto& a : e) {
    EXPECT_FALSE(RanksBefore(a, a));
    for (const auto& b : e) {
      if (RanksBefore(a, b)) {
        EXPECT_FALSE(RanksBefore(b, a));
      }
      if (a.feasible && !b.feasible) {
        EXPECT_TRUE(RanksBefore(a, b));
      }
      if (a.feasible && b.feasible && a.steps < b.steps) {
        EXPECT_TRUE(RanksBefore(a, b));
      }
    }
  }
  std::sort(e.begin(), e.end(), RanksBefore);
  EXPECT_TRUE(std::is_sorted(e.begin(), e.end(), RanksBefore));
}

// The evaluation is the planner's own result for that camera, the same whatever the threads, and the best camera's
// strategy is sound: every sampled start reaches the goal in simulation.
TEST(CameraPlacement, EvaluationsAreThePlannersAndTheBestCameraIsChecked) {
  // Under ASan, planning.camera_cli runs the same code through `visco camera`; this one takes many minutes there.
  if (kSanitized) GTEST_SKIP() << "the evaluations are planned and checked in the normal build";
  const Scene scene = LoadScene("data/scenes/fig13.json");
  const ViewingCells cells = ComputeViewingCells(scene, scene.bounds.min, scene.bounds.max);
  const Point aim = DefaultAim(scene);
  std::vector<std::optional<Camera>> cameras = {std::nullopt, scene.camera};
  std::vector<int> seen;
  for (const ViewingCell& c : cells.cells) {
    if (std::find(seen.begin(), seen.end(), c.view) != seen.end()) continue;
    seen.push_back(c.view);
    cameras.push_back(AimedCamera(c.sample, aim, 100.0));
    if (cameras.size() == 5) break;
  }
  CameraSearchOptions options;
  options.max_steps = 2;
  options.threads = 1;
  const std::vector<CameraEvaluation> one = EvaluateCameras(scene, cameras, options);
  options.threads = 2;
  const std::vector<CameraEvaluation> two = EvaluateCameras(scene, cameras, options);
  ASSERT_EQ(one.size(), cameras.size());
  for (std::size_t i = 0; i < one.size(); ++i) {
    EXPECT_EQ(one[i].feasible, two[i].feasible) << i;
    EXPECT_EQ(one[i].steps, two[i].steps) << i;
    EXPECT_EQ(one[i].min_interval_deg, two[i].min_interval_deg) << i;
    EXPECT_EQ(one[i].preimage_area, two[i].preimage_area) << i;
  }
  // The scene's camera as the planner sees it (fig13: one step with visual constraints, none without, §VIII-A).
  PlanOptions plan;
  plan.max_steps = 2;
  plan.max_nondirectional = options.max_backprojections;
  const Strategy with = PlanStrategy(scene, plan);
  EXPECT_EQ(one[1].feasible, with.feasible);
  EXPECT_EQ(one[1].steps, static_cast<int>(with.steps.size()));
  plan.use_camera = false;
  const Strategy without = PlanStrategy(scene, plan);
  EXPECT_EQ(one[0].feasible, without.feasible);
  EXPECT_EQ(one[0].steps, static_cast<int>(without.steps.size()));
  // The best candidate camera, planned again and simulated.
  std::size_t best = 2;
  for (std::size_t i = 3; i < one.size(); ++i) {
    if (RanksBefore(one[i], one[best])) best = i;
  }
  ASSERT_TRUE(one[best].feasible) << "no candidate of fig13's largest views gives a strategy";
  Scene placed = scene;
  placed.camera = cameras[best];
  plan.use_camera = true;
  const Strategy strategy = PlanStrategy(placed, plan);
  ASSERT_TRUE(strategy.feasible);
  const CSpace cspace(placed);
  const VcRays rays = ComputeVcRays(placed, cspace);
  const StrategyCheck check = CheckStrategy(placed, cspace, rays, strategy, 40, 3);
  EXPECT_EQ(check.successes, check.starts) << (check.failures.empty() ? "" : check.failures.front());
}

}  // namespace
}  // namespace visco::planning

#pragma once
// Where to put the camera (Fox & Hutchinson §VIII-B, Conjecture 2; docs/camera_placement.md).
//
// What the planner sees of a camera at P is the set of unoccluded obstacle vertices (each gives a VC ray) and, per
// vertex b, the robot's two CM vertices for the direction P -> b. Both change only where P crosses an event line:
//   * occlusion: the line through a vertex b and a point w of the obstacles' boundary where such a line can graze it
//     (a vertex, or a crossing of two obstacles' edges), w's obstacle locally on one side (this includes the
//     supporting lines of the obstacle edges, across which a vertex's own obstacle starts to hide it);
//   * CM vertices: the line through b parallel to a robot hull edge (the extreme robot vertex left or right of
//     P -> b changes there).
// The faces of the arrangement of these lines inside the candidate region are the viewing cells: inside one, the view
// (ignoring the field of view, which `visco camera` aims per candidate) is the same, so one evaluation per cell
// replaces a dense grid. Faces are convex (the arrangement has only lines and the region's rectangle), and each lies
// inside or outside every obstacle (the obstacle edges lie on event lines).

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "planning/geometry.h"
#include "planning/scene.h"

namespace visco::planning {

/// One face of the event-line arrangement that lies outside the obstacles.
struct ViewingCell {
  Polygon polygon;    ///< convex, counter-clockwise (rounded from exact vertices)
  Point sample;       ///< a point strictly inside (the average of the exact vertices, rounded)
  double area = 0.0;  ///< of the rounded polygon
  int view = 0;       ///< index of its view (cells with the same unoccluded vertices and CM vertices share one)
};

struct ViewingCells {
  int event_lines = 0;             ///< distinct event lines crossing the region
  int faces = 0;                   ///< faces of the arrangement inside the region (inside obstacles too)
  std::vector<ViewingCell> cells;  ///< the faces outside the obstacles, largest first (ties: by sample, x then y)
  int views = 0;                   ///< distinct views among the cells
  int obstacle_vertices = 0;       ///< n
  int robot_vertices = 0;          ///< m (of the robot's convex hull)
};

/// The viewing cells of `scene`'s obstacles and robot inside the rectangle [min, max]. Exact (CGAL's Arrangement_2
/// on exact constructions); O(L^2) faces for L event lines. Not real-time safe. The scene's camera is ignored.
/// With `camera_height` (2.5D: cameras that high above the plane, obstacles with heights), a prism of height h < H
/// starts or stops hiding a vertex b where the line of sight from b first meets its footprint at h / H of the way:
/// P on the image of the prism's boundary under the homothety about b of ratio H / h. The lines of those images'
/// edges are events too (whole lines, so that the faces stay convex).
ViewingCells ComputeViewingCells(const Scene& scene, const Point& min, const Point& max,
                                 std::optional<double> camera_height = std::nullopt);

/// What the planner sees from P when the field of view is the whole circle: per unoccluded obstacle vertex (its
/// obstacle, its normalised index) the two CM vertices, sorted. Two points in one viewing cell have the same view.
struct ViewVertex {
  int obstacle = 0;
  int vertex = 0;
  int cm_left = 0;
  int cm_right = 0;
  friend bool operator==(const ViewVertex&, const ViewVertex&) = default;
  friend auto operator<=>(const ViewVertex&, const ViewVertex&) = default;
};
std::vector<ViewVertex> ViewFrom(const Scene& scene, const Point& p,
                                 std::optional<double> camera_height = std::nullopt);

/// How a candidate camera does: the strategy the planner finds with it.
struct CameraEvaluation {
  Point center{0, 0};
  double fov_first_deg = 0.0, fov_span_deg = 0.0;
  int cell = -1;  ///< index into ViewingCells::cells, -1 for a grid point, a given candidate or the scene's camera
  bool feasible = false;
  int steps = 0;                ///< of the strategy (0 when infeasible)
  double min_interval_deg = 0;  ///< the narrowest θ-interval among its steps: how far the direction may err
  double preimage_area = 0;     ///< of the first step's preimage (where the strategy may start from)
  double coverage = 0;          ///< share of the start region one step covers (1 when feasible)
  double seconds = 0;           ///< planning time
  std::string reason;           ///< when infeasible
};

/// The ranking: feasible first, then fewest steps, the widest narrowest interval, the largest first preimage, the
/// largest coverage, then by centre (x, then y). A strict weak order; the same candidates always rank the same.
bool RanksBefore(const CameraEvaluation& a, const CameraEvaluation& b);

struct CameraSearchOptions {
  int max_steps = 2;
  int max_backprojections = 12;  ///< per candidate (PlanOptions::max_nondirectional)
  int threads = 1;               ///< candidates planned side by side
  std::function<void(int done, int total)> progress;
};

/// The candidate camera at `center` looking at `aim`: the direction from the centre to the aim point (+x when they
/// coincide) is the middle of a field of view `fov_deg` wide, `height` above the plane if given (2.5D visibility).
Camera AimedCamera(const Point& center, const Point& aim, double fov_deg, std::optional<double> height = std::nullopt);

/// Where candidates look by default: midway between the start region's and the goal's vertex averages. @throws
/// InputError if the scene has no start region.
Point DefaultAim(const Scene& scene);

/// Plans with each camera as the scene's camera (std::nullopt: without a camera, the baseline) and returns the
/// evaluations in the order given. A camera whose centre lies inside an obstacle is infeasible with that reason.
/// Deterministic whatever `threads`. @throws what PlanStrategy throws for the scene itself (an empty goal kernel).
std::vector<CameraEvaluation> EvaluateCameras(const Scene& scene, const std::vector<std::optional<Camera>>& cameras,
                                              const CameraSearchOptions& options);

/// Points of the grid of spacing h over [min, max] (centred in it) that lie outside the obstacles.
std::vector<Point> GridCandidates(const Scene& scene, const Point& min, const Point& max, double h);

}  // namespace visco::planning

#pragma once
// The planner's immutable scene model (docs/formats.md "Scene file", docs/semantics.md "Frames and units"); scene
// files are read by planning/scene_file.h.
//
// A Scene is plain data, built and validated once by LoadScene / ParseScene (scene_file.h) and then only read (pass it
// as `const Scene&`). Polygons are normalised: counter-clockwise, repeated consecutive vertices dropped; the
// `source_index` of each polygon maps a normalised vertex back to its 0-based position in the file, which is what
// outputs report (docs/formats.md "Indices in outputs"). Angles are radians, lengths metres.

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "planning/geometry.h"

namespace visco::planning {

/// A polygon as read from a scene file, normalised to counter-clockwise order.
struct ScenePolygon {
  /// Simple, counter-clockwise, no repeated consecutive vertices.
  Polygon polygon;
  /// source_index[i] is the 0-based position in the file of polygon.vertices[i].
  std::vector<int> source_index;
  /// source_edge[i] is the 0-based position in the file of the edge from polygon.vertices[i] to vertices[i + 1]
  /// (file edge k runs from file vertex k to k + 1, wrapping; repeated vertices make degenerate file edges, which
  /// are never named). Filled by the loader; may be empty in hand-built polygons (see SourceEdgeIndex).
  std::vector<int> source_edge = {};
};

/// The file position of the edge from vertices[i] to vertices[i + 1]: source_edge[i] when filled, else derived from
/// source_index for a polygon without repeated vertices (file edge source_index[i] if the file runs
/// counter-clockwise, source_index[i + 1] if it was reversed).
int SourceEdgeIndex(const ScenePolygon& polygon, std::size_t i);

/// A workspace obstacle.
struct Obstacle {
  /// Unique, non-empty id from the file (used in ray ids and edge refs).
  std::string id;
  ScenePolygon shape;
  /// Height of the vertical prism over the polygon (metres, > 0), for 2.5D visibility from a camera with a height
  /// (docs/planning_cspace.md "Heights"). Absent: unbounded (the planar model: the obstacle hides everything behind
  /// it).
  std::optional<double> height = std::nullopt;
};

/// The rectangle of allowed configurations (reference-point positions); min < max componentwise.
struct Bounds {
  Point min;
  Point max;
  /// Whether q lies in the closed rectangle.
  bool Contains(const Point& q) const {
    return q.x() >= min.x() && q.x() <= max.x() && q.y() >= min.y() && q.y() <= max.y();
  }
};

/// A calibrated pinhole camera in 3D (ViSP conventions): pixel (u, v) sees the ray x = (u - u0) / px,
/// y = (v - v0) / py, z = 1 in the camera frame (x right, y down, z forward); wMc takes camera coordinates to world
/// coordinates (world z up, motion plane z = 0).
struct PinholeCamera {
  double px = 0;
  double py = 0;
  double u0 = 0;
  double v0 = 0;
  int width = 0;   // pixels
  int height = 0;  // pixels
  Eigen::Matrix4d wMc = Eigen::Matrix4d::Identity();
};

/// The planner's camera (Fox & Hutchinson §III-A): a projection centre in the plane and a field of view of two
/// extreme directions; the field of view is the closed sector swept counter-clockwise from `fov_first` to
/// `fov_second`, strictly between 0 and 180 degrees wide.
struct Camera {
  Point center;
  /// Extreme viewing directions (unit vectors, as doubles; predicates treat them as exact).
  Vector fov_first;
  Vector fov_second;
  /// The same directions as angles (radians, counter-clockwise from +x); fov_second - fov_first in (0, pi).
  double fov_first_rad = 0;
  double fov_second_rad = 0;
  /// Set when the scene gave a 3D pinhole camera; center and the field of view are then derived from it
  /// (DerivePlanarCamera).
  std::optional<PinholeCamera> pinhole;
  /// Height of the camera centre above the motion plane (metres, > 0): from the pinhole's pose, or `height` of a
  /// planar camera. With it, obstacles with a height hide only what their prism hides (2.5D visibility).
  std::optional<double> height = std::nullopt;
  /// Whether the direction from the centre to p lies in the closed field of view (false for p == center). Exact.
  bool Sees(const Point& p) const;
  /// Sees(p) and, for a pinhole camera, the point p of the motion plane projects in front of the camera at least
  /// kImageMargin pixels inside the image's border (in doubles; the margin absorbs their rounding).
  bool InView(const Point& p) const;
  /// The parameters s in [0, 1] for which from + s (to - from) is in view as InView says (for a planar camera the
  /// sector test is left to the caller: [0, 1]); an empty optional when none is. The image's border cuts a segment
  /// of the plane once at most per side, so the set is one interval.
  std::optional<std::pair<double, double>> ViewInterval(const Point& from, const Point& to) const;
  /// How far inside the image's border (pixels) a point must project to count as seen by a pinhole camera.
  static constexpr double kImageMargin = 1.0;
};

/// The planar camera at `center` whose field of view sweeps `span_deg` counter-clockwise from the direction
/// `first_deg` (degrees from +x; directions at multiples of 90 degrees are exact). No checks: the scene loader checks
/// what it reads, `visco camera` builds its candidates with this.
Camera MakePlanarCamera(const Point& center, double first_deg, double span_deg);

/// Control and sensing uncertainty.
struct Uncertainty {
  /// Half-angle of the control uncertainty cone, radians, in [0, pi/2).
  double velocity_cone_rad = 0;
  /// Radius of the position-sensing disc, metres, >= 0.
  double position = 0;
  /// How far (metres, >= 0) the robot may run beside an active ray's line while it complies to it (the visual
  /// servo's tracking error): where the ray ends on a C-obstacle, the motion may meet CB anywhere this close to the
  /// line, not only at the ray's end (docs/semantics.md "Compliance ends"). Optional in the file.
  double vc_tracking = kDefaultVcTracking;
  /// The default: the demo's servo runs up to 14 mm beside the line at 7 m from the camera (docs/demo.md).
  static constexpr double kDefaultVcTracking = 0.02;
};

/// A planning scene (docs/formats.md). Treat as immutable after loading.
struct Scene {
  std::string name;
  /// Where it came from (file path, or a label such as "<embedded slot.json>"), for messages.
  std::string source;
  /// The digest of the scene's JSON (common/scene_digest.h): plans and rays record it, `visco run` compares it.
  std::string digest;
  Bounds bounds;
  /// The robot in its own frame; the reference point is the origin.
  ScenePolygon robot;
  std::vector<Obstacle> obstacles;
  /// Goal region in C (reference-point positions).
  ScenePolygon goal;
  std::optional<ScenePolygon> start;
  std::optional<Camera> camera;
  Uncertainty uncertainty;
  /// Half-angle of the friction cone, radians, in [0, pi/2).
  double friction_cone_rad = 0;
};

/// Derives the planar camera model from a pinhole camera (docs/semantics.md "Real cameras", docs/planning_cspace.md):
/// the projection centre is the camera centre's foot point on the motion plane z = 0, the field of view is the
/// angular extent, seen from that foot point, of the image's footprint on the motion plane.
/// @throws visco::InputError(source, object, ...) if the camera centre is not above the plane, the image sees no
///   part of the plane, or the footprint's angular extent is not strictly between 0 and 180 degrees (e.g. a camera
///   looking straight down sees its own foot point).
Camera DerivePlanarCamera(const PinholeCamera& pinhole, const std::string& source, const std::string& object);

}  // namespace visco::planning

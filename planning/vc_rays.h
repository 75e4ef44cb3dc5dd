#pragma once
// Visual constraint rays (Fox & Hutchinson §III, docs/semantics.md "Visual constraints"): the workspace VC rays from
// unoccluded obstacle vertices to the camera's projection centre, the CM vertices of the robot for each ray
// direction, and the C-space VC (CVC) rays, cut where they enter the interior of CB and clipped to the bounds, with
// their pairwise crossings.
//
// Ids are deterministic functions of the scene alone: the VC ray of an obstacle vertex is "vc<k>", where k is the
// vertex's position in the file counting the obstacles' vertices in file order (obstacle 0's vertices first); its
// CVC ray for robot vertex j (0-based, as in the file) is "vc<k>.cm<j>". The same vertex keeps the same id whatever
// the camera sees.

#include <array>
#include <string>
#include <vector>

#include "planning/cspace.h"
#include "planning/geometry.h"
#include "planning/scene.h"

namespace visco::planning {

/// An unoccluded obstacle vertex inside the field of view and the robot's two CM vertices for its ray direction.
struct UnoccludedVertex {
  int obstacle = 0;  ///< index into Scene::obstacles
  int vertex = 0;    ///< index into that obstacle's normalised polygon (shape.polygon)
  /// The two CM vertices, as indices into the robot's normalised polygon: cm[0] is extreme to the left of the
  /// direction camera -> vertex, cm[1] to the right. Ties (a hull edge parallel to the ray) go to the lower file
  /// index.
  std::array<int, 2> cm = {0, 0};

  friend bool operator==(const UnoccludedVertex&, const UnoccludedVertex&) = default;
};

/// The unoccluded vertices inside the field of view, by a rotational sweep about the projection centre with the
/// robot's hull-edge directions interleaved (rotating calipers). O((n + m) log n) for n obstacle vertices and m robot
/// vertices; scenes whose obstacles overlap use the O(n (n + m)) reference instead (the sweep needs edges that do not
/// cross). Sorted by (obstacle, vertex). Empty without a camera. Exact. Not real-time safe.
///
/// A vertex b is unoccluded iff b != P, b is in view (Camera::InView: in the closed field of view and, for a pinhole
/// camera, inside its image), and no obstacle hides it: an obstacle hides b if the open segment (P, b) meets its
/// interior (its own included; touching or running along boundaries does not occlude) and, with heights
/// (UsesHeights), the line of sight from b to the camera centre passes below the top of its prism there. A
/// vertex inside another obstacle is occluded (its segment to P starts in that interior).
std::vector<UnoccludedVertex> FindUnoccludedVertices(const Scene& scene);

/// Whether visibility is 2.5D: the camera has a height (a pinhole camera, or a planar one with `height`) and some
/// obstacle has a height. Then an obstacle with a height hides a point of the plane only where its prism rises above
/// the line of sight from that point to the camera centre (docs/planning_cspace.md "Heights"); obstacles without one
/// hide everything behind them, as in the planar model.
bool UsesHeights(const Scene& scene);

/// Along the workspace VC ray from obstacle vertex b (s = 0) to the projection centre (s = 1): the closed intervals
/// of s at which a robot vertex standing on the plane there is seen, sorted and disjoint. A point is seen when it is
/// in view (Camera::InView: the pinhole image's border cuts the ray) and no prism that the line of sight from b passes
/// over hides it (the robot stands lower than b's line of sight behind such a prism). [[0, 1]] for a planar camera
/// without heights. Decided in doubles, conservatively (points within 1e-9 of the ray's length of a limit count as
/// hidden); which obstacles the ray passes is decided exactly. Assumes b is unoccluded.
std::vector<std::pair<double, double>> VisibleRayParameters(const Scene& scene, const Point& b);

/// The same set by the slow obvious method (every vertex against every edge and vertex; CM vertices by scanning the
/// hull): O(n (n + m)). For tests and benchmarks.
std::vector<UnoccludedVertex> FindUnoccludedVerticesReference(const Scene& scene);

/// A workspace VC ray: the segment from an unoccluded obstacle vertex to the projection centre.
struct VcRay {
  std::string id;                           ///< "vc<k>"
  int obstacle = 0;                         ///< index into Scene::obstacles
  int vertex = 0;                           ///< 0-based position of the vertex in the obstacle's polygon in the file
  int vertex_normalised = 0;                ///< index into the obstacle's normalised polygon
  Point from;                               ///< the obstacle vertex b
  Point to;                                 ///< the projection centre P
  std::array<int, 2> cm_vertices = {0, 0};  ///< robot file indices of the CM vertices (ascending)
};

/// A C-space VC ray: the VC ray displaced by a0(0) - aj(0) = -aj for CM vertex aj, cut to its free parts.
struct CvcRay {
  std::string id;     ///< "vc<k>.cm<j>"
  int vc_ray = 0;     ///< index into VcRays::vc_rays
  int cm_vertex = 0;  ///< robot vertex j (0-based position in the file)
  Vector offset;      ///< -aj (exactly representable)
  /// The uncut ray [from - aj, to - aj] (rounded).
  Segment full;
  /// Its maximal parts of positive length outside the interior of CB and inside the bounds, from the obstacle end
  /// towards the camera end (rounded to doubles from exact values).
  std::vector<Segment> segments;
  /// open_ends[k]: per end of segments[k] (source, target), true where it is not on CB's boundary: the bounds clip
  /// the ray there, the camera stops seeing the CM vertex there (a pinhole image's border or a prism in the way:
  /// VisibleRayParameters), or it is the camera end. Complying along the ray to an open end fails (docs/semantics.md:
  /// nothing physical stops the servo there).
  std::vector<std::array<bool, 2>> open_ends;
};

/// Where the free parts of two CVC rays meet (an event for the backprojection, Fox & Hutchinson §III-C-2, §V-A).
struct CvcCrossing {
  int first = 0;   ///< index into VcRays::cvc_rays, first < second
  int second = 0;  ///< index into VcRays::cvc_rays
  Point point;
  bool overlap = false;  ///< the rays are collinear and overlap; point is an end of the shared piece
};

/// All visual constraints of a scene.
struct VcRays {
  std::vector<VcRay> vc_rays;    ///< sorted by k (file order)
  std::vector<CvcRay> cvc_rays;  ///< two per VC ray (ascending robot vertex), in VC ray order
  std::vector<CvcCrossing> crossings;
};

/// Computes the VC rays, CVC rays and their crossings. Exact, O((n + m) log n + (n + c) log n) with c the number of
/// meetings of CVC rays with CB edges and with each other. Not real-time safe.
VcRays ComputeVcRays(const Scene& scene, const CSpace& cspace);

/// The `visco vcrays` JSON (docs/formats.md): {"vc_rays": [{"id", "obstacle", "vertex", "from", "to"}], "cvc_rays":
/// [{"id", "vc_ray", "cm_vertex", "segments"}]}, plus "cvc_crossings": [{"rays": [id, id], "point", "overlap"}] and
/// "camera": {"center", "fov_deg"}. "obstacle" is the obstacle's id, "vertex" and "cm_vertex" file positions.
std::string VcRaysToJson(const Scene& scene, const VcRays& rays);

/// A picture in the style of Fox & Hutchinson Fig. 5-7: obstacles shaded, C-obstacles outlined, the camera as a
/// cross with its field of view, VC rays, labelled CVC rays (free parts solid, cut parts dotted), crossings, goal,
/// start, and the robot with its vertex numbers.
std::string VcRaysToSvg(const Scene& scene, const CSpace& cspace, const VcRays& rays);

/// The ids as functions of the scene: "vc<k>" for obstacle `obstacle`'s file vertex `file_vertex`, and the CVC id.
std::string VcRayId(const Scene& scene, int obstacle, int file_vertex);
std::string CvcRayId(const std::string& vc_ray_id, int robot_file_vertex);

}  // namespace visco::planning

#pragma once
// Computed updates (docs/planning_nondirectional.md, "Computing the slice after a change"): the slice after an event
// computed from the one before it, without a sweep, where the event's local edit brings no new chain (internal to the
// nondirectional backprojection; in a header so that it can be unit tested).

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "planning/backprojection.h"
#include "planning/critical.h"

namespace visco::planning::internal {

using Eigen::Vector2d;

// Updating a slice across an event without a sweep (docs/planning_nondirectional.md, "Computing the slice after a
// change"): the local edits whose new edges follow from the event and the static arrangement alone.
enum class Update : std::uint8_t { kUnchanged, kEdited, kUnknown };

class RegionUpdater {
 public:
  // `crossed`: the static edges another one meets away from their shared ends (overlapping obstacles, a goal on
  // CB): the region's boundary there is not the polygon's, and no shape below is taken along them.
  RegionUpdater(const std::vector<RegionEdge>& statics, const std::set<std::string>& crossed, double tolerance,
                double eps)
      : statics_(statics), crossed_(crossed), tol_(tolerance), eps_(eps) {}

  // The static edges another static edge meets away from their shared ends (within `tolerance`).
  static std::set<std::string> Crossed(const std::vector<RegionEdge>& e, double tolerance);

  // The edit that candidate c (a free vertex crossing a static edge, or a free edge passing a C-obstacle vertex)
  // makes to `region` (a slice's, at its own θ; `at_event` is it carried to the event), applied and carried to
  // `theta_after` in `out`; kUnchanged where the event's point is off the region's boundary; kUnknown where the
  // region near the event is not one of the shapes below, or the shapes that pass their checks disagree, or none
  // does (the walk then sweeps). `rays`: every candidate ray's segments for the VC region (none for the
  // classic one): an event at a ray, or an edit that reaches one, can change the rays chosen, which no shape covers.
  Update Apply(const CriticalOrientation& c, const Region& region, const Region& at_event, double theta_after,
               const std::vector<std::array<Vector2d, 2>>& rays, Region& out) const;

 private:
  enum class Shape : std::uint8_t {
    kFreeVertexCut,    // [a/+, b/-] -> [a/+, e, b/-]: the corner at the free vertex cut off by e
    kFreeVertexFreed,  // [a/+, e, b/-] -> [a/+, b/-]
    kHitPassesOn,      // [x, a/s] -> [x, y, a/s] (or mirrored): the free edge's end passes b from x onto y
    kHitPassesBack,    // [a/s, x, y] -> [a/s, y] (or mirrored): from x back onto y, x's part gone
    kUnblocked,        // [x, b'/s, chain, y, a/s] -> [x, a/s] (or mirrored): the free edge no longer ends on b's
                       // obstacle, and the obstacle's chain and the free edge b'/s beside it go
    kCutOff,           // [a/s, run, z] -> [a/s, z] (or mirrored): any run of edges with b at one of its vertices,
                       // all of it now beyond a's free edge (the two shapes above are the commonest such runs)
  };
  // An edit of a ring, at its edge `index` (the anchor, which stays): the `remove` edges after it replaced by
  // `insert`. `forward`: the shape as written above (else mirrored: the ring runs the other way round the site).
  struct Site {
    Shape shape = Shape::kFreeVertexCut;
    size_t polygon = 0, index = 0;
    int hole = -1;  // -1: the outer ring
    size_t remove = 0;
    std::vector<RegionEdge> insert;
    bool forward = true;
    Vector2d b{0, 0};    // the point of the event (b, or the free vertex f)
    RegionEdge free, x;  // vgraph: the free edge, and the edge it ends on before the event
    RegionEdge y;        // the edge it ends on after (kHitPassesOn/Back) or before (kUnblocked), or the crossed edge
  };

  static const RegionRing& RingOf(const Region& r, size_t p, int h);
  static RegionRing& RingOf(Region& r, size_t p, int h);
  bool NearRay(const Vector2d& p, const std::vector<std::array<Vector2d, 2>>& rays) const;
  bool FreeOf(const RegionEdge& e, const Vector2d& p, int sign) const;
  bool IsObstacle(const RegionEdge& e) const;
  static bool IsStatic(const RegionEdge& e);
  static bool Same(const RegionEdge& u, const RegionEdge& w) { return u.kind == w.kind && u.ref == w.ref; }
  double ToSegment(const Vector2d& p, const RegionEdge& e) const;
  bool EndsAt(const RegionEdge& e, const Vector2d& p) const;
  // The direction of a's free edge of sign s at θ (upstream: θ + π ± ε_v).
  Vector2d FreeDirection(int sign, double theta) const;
  // Whether another ring of the region touches ring (p, h): motions can pass from one part of the region to another
  // where they touch, so an edit of one can change the other (VISCO_SEED_OFFSET=1000003, seed 63: a second part
  // touching the first where a run was cut off went with it).
  bool TouchesOtherRings(const Region& region, size_t p, int h) const;

  // Whether the segment pq crosses a static edge or a ray in its interior (away from its ends).
  bool Crosses(const Vector2d& p, const Vector2d& q, const std::vector<std::array<Vector2d, 2>>& rays) const;

  // The two C-obstacle edges that end at b, when b is a vertex of exactly those and no other static edge passes it.
  std::optional<std::array<const RegionEdge*, 2>> EdgesAt(const Vector2d& b) const;
  // The other C-obstacle edge at b (b a vertex of exactly two, x one of them).
  const RegionEdge* OtherEdgeAt(const Vector2d& b, const RegionEdge& x) const;

  // A free vertex f of a's +ε_v and b's −ε_v free edges crossing a static edge e: with the region inside the corner
  // at f (the corner is cut off by e), or e between them (e goes, the corner comes back).
  void VertexSites(const CriticalOrientation& c, const RegionRing& ring, const RegionRing& at_event, size_t i,
                   std::vector<Site>& out) const;

  // a's free edge (sign s) passing b, a vertex of CB where two C-obstacle edges meet (docs: the shapes above).
  void VgraphSites(const CriticalOrientation& c, const RegionRing& ring, const RegionRing& at_event, size_t i,
                   std::vector<Site>& out) const;

  // Applies site s to `region` and carries it to θ; whether the result is clearly what the shape says (by more than
  // the tolerance): the new vertices on their segments, the free edges going upstream from their sources, the
  // corner cut off or free again, the free edge's end past b.
  bool Edit(const Site& s, const Region& region, double theta, const std::vector<std::array<Vector2d, 2>>& rays,
            Region& out) const;

  static std::string Key(const RegionEdge& e) { return std::string(EdgeKindName(e.kind)) + ":" + e.ref; }
  bool Clean(const RegionEdge& e) const { return crossed_.count(Key(e)) == 0; }

  const std::vector<RegionEdge>& statics_;
  const std::set<std::string>& crossed_;
  double tol_, eps_;
};

}  // namespace visco::planning::internal

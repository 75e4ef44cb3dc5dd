// The local edit of a critical orientation (local_edit.h).

#include "planning/nondirectional/local_edit.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "planning/geometry.h"

namespace visco::planning::internal {

using Eigen::Vector2d;

bool MakesEdit(const CriticalOrientation& c, const RingEdit& e, double tol) {
  const RegionRing &b = *e.before, &a = *e.after;
  const size_t nb = b.edges.size();
  const RegionEdge& prev = b.edges[(e.b_begin + nb - 1) % nb];
  const RegionEdge& next = b.edges[(e.b_begin + e.b_count) % nb];
  // The side that has the extra edges, and where they are in its ring.
  const bool inserted = e.b_count == 0;
  const RegionRing& ring = inserted ? a : b;
  const size_t begin = inserted ? e.a_begin : e.b_begin, count = inserted ? e.a_count : e.b_count;
  const size_t n = ring.edges.size();
  auto edge = [&](size_t k) -> const RegionEdge& { return ring.edges[(begin + k) % n]; };
  auto free_of = [&](const RegionEdge& x, const Vector2d& p, int sign) {
    return x.kind == EdgeKind::kFree && x.sign == sign && (x.source - p).norm() <= tol;
  };
  auto on_segment = [&](const Vector2d& x, const Vector2d& p, const Vector2d& q) {
    return PointSegmentDistance(x, p, q) <= tol;
  };
  switch (c.kind) {
    case CriticalKind::kVertex:
    case CriticalKind::kFreeEdge: {
      // One static edge, on whose segment the free vertex is, between the two free edges.
      if ((e.b_count != 0 && e.a_count != 0) || count != 1 || c.sources.size() != 2 || c.point.empty()) return false;
      const RegionEdge& x = edge(0);
      if (x.kind == EdgeKind::kFree || !on_segment(c.point[0], x.line[0], x.line[1])) return false;
      const bool ab = free_of(prev, c.sources[0], 1) && free_of(next, c.sources[1], -1);
      const bool ba = free_of(prev, c.sources[1], -1) && free_of(next, c.sources[0], 1);
      return ab || ba;
    }
    case CriticalKind::kVgraph: {
      if (c.sources.size() != 1 || c.source_signs.size() != 1) return false;
      const Vector2d& src = c.sources[0];
      const int sign = c.source_signs[0];
      if (!c.point.empty() && (e.b_count == 0 || e.a_count == 0)) {
        const Vector2d& pb = c.point[0];
        // The free edge itself, next to the free edge erected at b.
        if (count == 1 && free_of(edge(0), src, sign)) {
          return (prev.kind == EdgeKind::kFree && (prev.source - pb).norm() <= tol) ||
                 (next.kind == EdgeKind::kFree && (next.source - pb).norm() <= tol);
        }
        // A chain next to the free edge that hangs on b: b is one of its vertices (the free edge now ends on the
        // chain beyond b, or no longer does).
        if (!free_of(prev, src, sign) && !free_of(next, src, sign)) return false;
        for (size_t k = 0; k <= count; ++k) {
          if ((ring.vertices[(begin + k) % n] - pb).norm() <= tol) return true;
        }
        return false;
      }
      if (c.feature.size() == 2 && e.b_count + e.a_count == 3 && std::min(e.b_count, e.a_count) == 1) {
        // Along the segment pq: [p's free edge] <-> [the segment, q's free edge] (either order, either way round).
        const Vector2d &p = c.feature[0], &q = c.feature[1];
        const RegionRing& one = e.b_count == 1 ? b : a;
        const RegionRing& two = e.b_count == 1 ? a : b;
        const RegionEdge& single = one.edges[e.b_count == 1 ? e.b_begin : e.a_begin];
        const size_t t0 = e.b_count == 1 ? e.a_begin : e.b_begin, nt = two.edges.size();
        const RegionEdge &u = two.edges[t0], &w = two.edges[(t0 + 1) % nt];
        const RegionEdge& seg = u.kind == EdgeKind::kFree ? w : u;
        const RegionEdge& other = u.kind == EdgeKind::kFree ? u : w;
        if (seg.kind == EdgeKind::kFree || other.kind != EdgeKind::kFree) return false;
        const size_t si = &seg == &u ? t0 : (t0 + 1) % nt;
        if (!on_segment(two.vertices[si], p, q) || !on_segment(two.vertices[(si + 1) % nt], p, q)) return false;
        const bool pq = free_of(single, p, sign) && free_of(other, q, sign);
        const bool qp = free_of(single, q, sign) && free_of(other, p, sign);
        return (pq || qp) && (free_of(single, src, sign) || free_of(other, src, sign));
      }
      return false;
    }
    default:
      return false;
  }
}

}  // namespace visco::planning::internal

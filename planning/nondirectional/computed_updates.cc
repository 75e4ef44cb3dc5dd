// Computed updates (computed_updates.h).

#include "planning/nondirectional/computed_updates.h"

#include <Eigen/Geometry>
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
#include "planning/nondirectional.h"
#include "planning/nondirectional/carry.h"
#include "planning/nondirectional/ring_geometry.h"

namespace visco::planning::internal {

std::set<std::string> RegionUpdater::Crossed(const std::vector<RegionEdge>& e, double tolerance) {
  std::set<std::string> out;
  for (size_t i = 0; i < e.size(); ++i) {
    for (size_t j = i + 1; j < e.size(); ++j) {
      const auto &p = e[i].line, &q = e[j].line;
      if (SegmentsDistance(p[0], p[1], q[0], q[1]) > tolerance) continue;
      // Sharing an end only (two edges of one polygon) is not crossing; anything more is.
      bool only_an_end = false;
      for (int a = 0; a < 2 && !only_an_end; ++a) {
        for (int b = 0; b < 2 && !only_an_end; ++b) {
          if ((p[a] - q[b]).norm() > tolerance) continue;
          only_an_end = PointSegmentDistance(p[1 - a], q[0], q[1]) > tolerance &&
                        PointSegmentDistance(q[1 - b], p[0], p[1]) > tolerance;
        }
      }
      if (only_an_end) continue;
      out.insert(Key(e[i]));
      out.insert(Key(e[j]));
    }
  }
  return out;
}

Update RegionUpdater::Apply(const CriticalOrientation& c, const Region& region, const Region& at_event,
                            double theta_after, const std::vector<std::array<Vector2d, 2>>& rays, Region& out) const {
  if (c.point.empty() || c.sources.empty()) return Update::kUnknown;
  // At a ray's point, or with a source at a ray's end or cut point (whose free edges are the VC region's).
  if (NearRay(c.point[0], rays)) return Update::kUnknown;
  for (const auto& source : c.sources) {
    if (NearRay(source, rays)) return Update::kUnknown;
  }
  std::vector<Site> sites;
  for (size_t p = 0; p < region.polygons.size(); ++p) {
    for (int h = -1; h < static_cast<int>(region.polygons[p].holes.size()); ++h) {
      const RegionRing& ring = RingOf(region, p, h);
      const RegionRing& event_ring = RingOf(at_event, p, h);
      if (event_ring.edges.size() != ring.edges.size()) return Update::kUnknown;
      for (size_t i = 0; i < ring.edges.size(); ++i) {
        const size_t before = sites.size();
        if (c.kind == CriticalKind::kVertex) {
          VertexSites(c, ring, event_ring, i, sites);
        } else if (c.kind == CriticalKind::kVgraph && c.feature.empty()) {
          VgraphSites(c, ring, event_ring, i, sites);
        }
        for (size_t k = before; k < sites.size(); ++k) {
          sites[k].polygon = p;
          sites[k].hole = h;
          sites[k].index = i;
        }
      }
    }
  }
  if (sites.empty()) return PointNearBoundary(c.point[0], at_event, tol_) ? Update::kUnknown : Update::kUnchanged;
  // Shapes that pass their checks must agree (a run cut off can also be one of the named shapes; one shape at two
  // places would be two events).
  std::optional<std::vector<std::string>> confirmed;
  std::set<std::pair<size_t, int>> apart;  // rings found to touch no other
  for (const auto& s : sites) {
    Region edited;
    if (!apart.count({s.polygon, s.hole})) {
      if (TouchesOtherRings(region, s.polygon, s.hole)) return Update::kUnknown;
      apart.insert({s.polygon, s.hole});
    }
    if (!Edit(s, region, theta_after, rays, edited)) continue;
    const auto structure = RegionStructure(edited);
    if (confirmed && *confirmed != structure) return Update::kUnknown;
    confirmed = structure;
    out = std::move(edited);
  }
  return confirmed ? Update::kEdited : Update::kUnknown;
}

const RegionRing& RegionUpdater::RingOf(const Region& r, size_t p, int h) {
  return h < 0 ? r.polygons[p].outer : r.polygons[p].holes[static_cast<size_t>(h)];
}

RegionRing& RegionUpdater::RingOf(Region& r, size_t p, int h) {
  return h < 0 ? r.polygons[p].outer : r.polygons[p].holes[static_cast<size_t>(h)];
}

bool RegionUpdater::NearRay(const Vector2d& p, const std::vector<std::array<Vector2d, 2>>& rays) const {
  return std::any_of(rays.begin(), rays.end(),
                     [&](const auto& r) { return PointSegmentDistance(p, r[0], r[1]) <= tol_; });
}

bool RegionUpdater::FreeOf(const RegionEdge& e, const Vector2d& p, int sign) const {
  return e.kind == EdgeKind::kFree && e.sign == sign && (e.source - p).norm() <= tol_;
}

bool RegionUpdater::IsObstacle(const RegionEdge& e) const {
  return e.kind == EdgeKind::kObstacle && e.line[0] != e.line[1] && Clean(e);
}

bool RegionUpdater::IsStatic(const RegionEdge& e) {
  return e.kind != EdgeKind::kFree && e.kind != EdgeKind::kVc && e.line[0] != e.line[1];
}

double RegionUpdater::ToSegment(const Vector2d& p, const RegionEdge& e) const {
  return PointSegmentDistance(p, e.line[0], e.line[1]);
}

bool RegionUpdater::EndsAt(const RegionEdge& e, const Vector2d& p) const {
  return (e.line[0] - p).norm() <= tol_ || (e.line[1] - p).norm() <= tol_;
}

Vector2d RegionUpdater::FreeDirection(int sign, double theta) const {
  const double angle = theta + M_PI + (sign > 0 ? eps_ : -eps_);
  return {std::cos(angle), std::sin(angle)};
}

bool RegionUpdater::TouchesOtherRings(const Region& region, size_t p, int h) const {
  const RegionRing& ring = RingOf(region, p, h);
  auto box = [&](const RegionRing& r) {
    Eigen::AlignedBox2d b;
    for (const auto& v : r.vertices) b.extend(v);
    return b;
  };
  Eigen::AlignedBox2d near = box(ring);  // grown by the tolerance
  near.min().array() -= tol_;
  near.max().array() += tol_;
  Region one;
  one.polygons.push_back({ring, {}});
  for (size_t q = 0; q < region.polygons.size(); ++q) {
    for (int g = -1; g < static_cast<int>(region.polygons[q].holes.size()); ++g) {
      if (q == p && g == h) continue;
      const RegionRing& other = RingOf(region, q, g);
      if (!near.intersects(box(other))) continue;  // apart: cannot touch
      Region that;
      that.polygons.push_back({other, {}});
      for (const auto& v : other.vertices) {
        if (PointNearBoundary(v, one, tol_)) return true;
      }
      for (const auto& v : ring.vertices) {
        if (PointNearBoundary(v, that, tol_)) return true;
      }
    }
  }
  return false;
}

bool RegionUpdater::Crosses(const Vector2d& p, const Vector2d& q,
                            const std::vector<std::array<Vector2d, 2>>& rays) const {
  const Vector2d d = q - p;
  auto crosses = [&](const Vector2d& a, const Vector2d& b) {
    const Vector2d e = b - a;
    const double den = Cross(d, e);
    if (std::abs(den) <= 1e-12 * d.norm() * e.norm()) return false;  // parallel: touching at most
    const double t = Cross(a - p, e) / den, u = Cross(a - p, d) / den;
    const double margin = tol_ / std::max(d.norm(), tol_);
    return t > margin && t < 1 - margin && u >= 0 && u <= 1;
  };
  for (const auto& g : statics_) {
    if (crosses(g.line[0], g.line[1])) return true;
  }
  return std::any_of(rays.begin(), rays.end(), [&](const auto& r) { return crosses(r[0], r[1]); });
}

std::optional<std::array<const RegionEdge*, 2>> RegionUpdater::EdgesAt(const Vector2d& b) const {
  std::array<const RegionEdge*, 2> at{nullptr, nullptr};
  int found = 0;
  for (const auto& e : statics_) {
    if (ToSegment(b, e) > tol_) continue;
    if (found == 2 || !IsObstacle(e) || !EndsAt(e, b)) return std::nullopt;
    at[static_cast<size_t>(found++)] = &e;
  }
  if (found != 2) return std::nullopt;
  return at;
}

const RegionEdge* RegionUpdater::OtherEdgeAt(const Vector2d& b, const RegionEdge& x) const {
  const auto at = EdgesAt(b);
  if (!at) return nullptr;
  if (Same(*(*at)[0], x)) return (*at)[1];
  if (Same(*(*at)[1], x)) return (*at)[0];
  return nullptr;
}

void RegionUpdater::VertexSites(const CriticalOrientation& c, const RegionRing& ring, const RegionRing& at_event,
                                size_t i, std::vector<Site>& out) const {
  if (c.sources.size() != 2) return;
  const size_t n = ring.edges.size();
  const Vector2d& f = c.point[0];
  auto pair = [&](const RegionEdge& u, const RegionEdge& w) {
    return (FreeOf(u, c.sources[0], 1) && FreeOf(w, c.sources[1], -1)) ||
           (FreeOf(u, c.sources[1], -1) && FreeOf(w, c.sources[0], 1));
  };
  const RegionEdge &e0 = ring.edges[i], &e1 = ring.edges[(i + 1) % n], &e2 = ring.edges[(i + 2) % n];
  Site s;
  s.b = f;
  if (pair(e0, e1) && (at_event.vertices[(i + 1) % n] - f).norm() <= tol_) {
    // The region inside the corner (rings keep the region on their left: a left turn).
    const Vector2d &p = ring.vertices[i], &q = ring.vertices[(i + 1) % n], &r = ring.vertices[(i + 2) % n];
    if (!(Cross(q - p, r - q) > 0)) return;
    const RegionEdge* crossed = nullptr;
    for (const auto& e : statics_) {
      if (ToSegment(f, e) > tol_) continue;
      if (crossed != nullptr) return;  // at a vertex of the arrangement, or on two edges
      crossed = &e;
    }
    if (crossed == nullptr || EndsAt(*crossed, f) || !Clean(*crossed)) return;
    s.shape = Shape::kFreeVertexCut;
    s.y = *crossed;
    s.insert = {*crossed};
    s.free = e0;
    s.x = e1;
    out.push_back(s);
    return;
  }
  if (n >= 4 && pair(e0, e2) && IsStatic(e1) && Clean(e1) && ToSegment(f, e1) <= tol_ &&
      (at_event.vertices[(i + 1) % n] - f).norm() <= tol_ && (at_event.vertices[(i + 2) % n] - f).norm() <= tol_) {
    s.shape = Shape::kFreeVertexFreed;
    s.remove = 1;
    s.y = e1;
    s.free = e0;
    s.x = e2;
    out.push_back(s);
  }
}

void RegionUpdater::VgraphSites(const CriticalOrientation& c, const RegionRing& ring, const RegionRing& at_event,
                                size_t i, std::vector<Site>& out) const {
  if (c.sources.size() != 1 || c.source_signs.size() != 1) return;
  const size_t n = ring.edges.size();
  const Vector2d& a = c.sources[0];
  const int sign = c.source_signs[0];
  const Vector2d& b = c.point[0];
  auto edge = [&](size_t k) -> const RegionEdge& { return ring.edges[(i + k) % n]; };
  auto vertex = [&](size_t k) -> const Vector2d& { return ring.vertices[(i + k) % n]; };
  auto event_vertex = [&](size_t k) -> const Vector2d& { return at_event.vertices[(i + k) % n]; };
  const bool free0 = FreeOf(edge(0), a, sign), free1 = FreeOf(edge(1), a, sign);
  Site s;
  s.b = b;
  // [x, a/s] / [a/s, x], the free edge ending on x at b at the event: it passes on to y, the hit moving towards b
  // from the side away from x's part of the ring (where b is that part's other end, x shrinks instead: below).
  if ((free0 != free1) && (event_vertex(1) - b).norm() <= tol_) {
    const bool forward = free1;
    const RegionEdge& x = forward ? edge(0) : edge(1);
    const Vector2d& other_end = forward ? vertex(0) : vertex(2);
    if (IsObstacle(x) && EndsAt(x, b) && (other_end - b).norm() > tol_ &&
        (b - vertex(1)).dot(other_end - vertex(1)) < 0) {
      if (const RegionEdge* y = OtherEdgeAt(b, x)) {
        s.shape = Shape::kHitPassesOn;
        s.forward = forward;
        s.x = x;
        s.free = forward ? edge(1) : edge(0);
        s.y = *y;
        s.insert = {*y};
        out.push_back(s);
      }
    }
  }
  // [a/s, x, y] / [y, x, a/s], x and y meeting at b, the hit on x at b at the event: x goes.
  for (const bool forward : {true, false}) {
    if (n < 4) break;
    const size_t f = forward ? 0 : 2, y = forward ? 2 : 0;
    const Vector2d& at_b = forward ? vertex(2) : vertex(1);  // where x meets y
    const Vector2d& hit = forward ? event_vertex(1) : event_vertex(2);
    if (!FreeOf(edge(f), a, sign) || !IsObstacle(edge(1)) || !IsObstacle(edge(y)) || (at_b - b).norm() > tol_ ||
        (hit - b).norm() > tol_) {
      continue;
    }
    s.shape = Shape::kHitPassesBack;
    s.forward = forward;
    s.free = edge(f);
    s.x = edge(1);
    s.y = edge(y);
    s.remove = 1;
    s.insert.clear();
    out.push_back(s);
  }
  // Any run with b at one of its vertices (or the source of one of its free edges): [a/s, run, z] / [z, run, a/s].
  for (const bool forward : {true, false}) {
    for (size_t len = 1; len + 3 <= n && len <= 8; ++len) {
      const RegionEdge& f = forward ? edge(0) : edge(len + 1);
      const RegionEdge& z = forward ? edge(len + 1) : edge(0);
      if (!FreeOf(f, a, sign) || z.kind == EdgeKind::kVc || (z.kind != EdgeKind::kFree && !Clean(z))) continue;
      bool ok = true, has_b = false;
      for (size_t k = 1; k <= len && ok; ++k) {
        const RegionEdge& r = edge(k);
        ok = r.kind == EdgeKind::kFree || (IsStatic(r) && Clean(r));
        has_b = has_b || (r.kind == EdgeKind::kFree && (r.source - b).norm() <= tol_);
      }
      for (size_t k = 1; k <= len + 1 && ok && !has_b; ++k) has_b = (vertex(k) - b).norm() <= tol_;
      if (!ok || !has_b) continue;
      s.shape = Shape::kCutOff;
      s.forward = forward;
      s.free = f;
      s.y = z;
      s.remove = len;
      s.insert.clear();
      out.push_back(s);
    }
  }
  // The reverse: [x, b'/s, chain, y, a/s] / mirrored, the chain's last vertex before y at b and the hit on y at b at
  // the event: everything between x and a/s goes.
  for (const bool forward : {true, false}) {
    for (size_t m = 0; m + 4 <= n && m <= 4; ++m) {
      // Forward: edge(0) = x, edge(1) = b'/s, edge(2 .. m+1) = chain, edge(m+2) = y, edge(m+3) = a/s.
      const RegionEdge& f = forward ? edge(m + 3) : edge(0);
      const RegionEdge& bf = forward ? edge(1) : edge(m + 2);
      const RegionEdge& y = forward ? edge(m + 2) : edge(1);
      if (!FreeOf(f, a, sign) || bf.kind != EdgeKind::kFree || bf.sign != sign || !IsObstacle(y)) continue;
      bool chain_ok = true;  // edges 2 .. m + 1 either way round
      for (size_t k = 0; k < m; ++k) chain_ok = chain_ok && IsObstacle(edge(2 + k));
      if (!chain_ok) continue;
      const Vector2d& at_b = forward ? vertex(m + 2) : vertex(2);  // where y meets the chain (or b'/s)
      const Vector2d& hit = forward ? event_vertex(m + 3) : event_vertex(1);
      if ((at_b - b).norm() > tol_ || (hit - b).norm() > tol_) continue;
      s.shape = Shape::kUnblocked;
      s.forward = forward;
      s.free = f;
      s.y = y;
      s.x = forward ? edge(0) : edge(m + 3);
      s.remove = m + 2;
      s.insert.clear();
      out.push_back(s);
    }
  }
}

bool RegionUpdater::Edit(const Site& s, const Region& region, double theta,
                         const std::vector<std::array<Vector2d, 2>>& rays, Region& out) const {
  Region edited = region;
  RegionRing& ring = RingOf(edited, s.polygon, s.hole);
  const size_t n = ring.edges.size();
  if (s.remove + 3 > n + s.insert.size()) return false;
  // The site at the ring's start: edge 0 is the anchor, edges 1 .. remove go, `insert` comes after edge 0.
  std::rotate(ring.edges.begin(), ring.edges.begin() + static_cast<std::ptrdiff_t>(s.index), ring.edges.end());
  std::rotate(ring.vertices.begin(), ring.vertices.begin() + static_cast<std::ptrdiff_t>(s.index), ring.vertices.end());
  const RegionRing before = ring;
  ring.edges.erase(ring.edges.begin() + 1, ring.edges.begin() + 1 + static_cast<std::ptrdiff_t>(s.remove));
  ring.vertices.erase(ring.vertices.begin() + 2, ring.vertices.begin() + 2 + static_cast<std::ptrdiff_t>(s.remove));
  ring.edges.insert(ring.edges.begin() + 1, s.insert.begin(), s.insert.end());
  ring.vertices.insert(ring.vertices.begin() + 2, s.insert.size(), Vector2d::Zero());
  // Vertices 1 .. insert.size() + 1 are new: between two static edges, the point both end at (carrying keeps it);
  // the others are where the lines meet (carrying computes them).
  const size_t m = ring.edges.size();
  for (size_t k = 1; k <= s.insert.size() + 1 && k < m; ++k) {
    const RegionEdge &u = ring.edges[k - 1], &w = ring.edges[k];
    if (u.kind == EdgeKind::kFree || w.kind == EdgeKind::kFree) continue;
    const Vector2d* shared = EndsAt(w, u.line[0]) ? &u.line[0] : EndsAt(w, u.line[1]) ? &u.line[1] : nullptr;
    if (shared == nullptr) return false;
    ring.vertices[k] = *shared;
  }
  out = CarryRegion(edited, theta, eps_);
  const RegionRing& v = RingOf(out, s.polygon, s.hole);
  for (const auto& p : v.vertices) {
    if (!p.allFinite()) return false;
  }
  for (size_t k = 1; k <= s.insert.size() + 1 && k < m; ++k) {
    if (NearRay(v.vertices[k], rays)) return false;
  }
  // The anchor and the edge after the edit keep their direction (else the edit reaches further than the shape).
  const size_t after_edit = s.insert.size() + 1;
  auto kept = [&](const Vector2d& p0, const Vector2d& p1, const Vector2d& q0, const Vector2d& q1) {
    return (q1 - q0).norm() > tol_ && (q1 - q0).dot(p1 - p0) > 0;
  };
  if (!kept(before.vertices[0], before.vertices[1], v.vertices[0], v.vertices[1]) ||
      !kept(before.vertices[1 + s.remove], before.vertices[(2 + s.remove) % n], v.vertices[after_edit],
            v.vertices[(after_edit + 1) % m])) {
    return false;
  }
  // The free edges the edit lengthens or moves (the anchor, the edge after the edit, and what it inserts) run
  // through free space: they cross no static edge or ray (a free edge that now reaches past an obstacle ends on it,
  // which is another shape).
  for (size_t k = 0; k <= after_edit && k < m; ++k) {
    if (v.edges[k].kind != EdgeKind::kFree) continue;
    if (Crosses(v.vertices[k], v.vertices[(k + 1) % m], rays)) return false;
  }
  auto upstream = [&](const RegionEdge& f, const Vector2d& p) {  // p lies on f's free edge, past its source
    return (p - f.source).dot(FreeDirection(f.sign, theta)) > tol_;
  };
  const auto& w = v.vertices;
  switch (s.shape) {
    case Shape::kFreeVertexCut: {
      const auto tip = MeetAt(s.free, s.x, theta, eps_);
      if (!tip || ToSegment(w[1], s.y) > tol_ || ToSegment(w[2], s.y) > tol_ || (w[2] - w[1]).norm() <= tol_) {
        return false;
      }
      return Cross((w[2] - w[1]).normalized(), *tip - w[1]) < -tol_;  // the old corner beyond the edge
    }
    case Shape::kFreeVertexFreed: {
      const Vector2d d = (before.vertices[2] - before.vertices[1]).normalized();  // the edge, region on its left
      return d.allFinite() && Cross(d, w[1] - before.vertices[1]) > tol_;
    }
    case Shape::kHitPassesOn: {
      const Vector2d& hit = s.forward ? w[2] : w[1];
      const auto old_hit = MeetAt(s.free, s.x, theta, eps_);
      return ToSegment(hit, s.y) <= tol_ && (hit - s.b).norm() > tol_ && upstream(s.free, hit) && old_hit &&
             ToSegment(*old_hit, s.x) > tol_;
    }
    case Shape::kHitPassesBack: {
      const Vector2d& hit = w[1];
      const Vector2d& next = s.forward ? w[2 % m] : w[0];  // y's other end in the ring
      const auto old_hit = MeetAt(s.free, s.x, theta, eps_);
      return ToSegment(hit, s.y) <= tol_ && (hit - s.b).norm() > tol_ && (next - hit).norm() > tol_ &&
             (next - s.b).norm() > (next - hit).norm() && upstream(s.free, hit) && old_hit &&
             ToSegment(*old_hit, s.x) > tol_;
    }
    case Shape::kCutOff: {
      // The new corner where a/s meets z: on z (a static z's segment, or upstream on a free z), and everything the
      // run had that is not on a/s's line clearly beyond it (right of a/s as the ring runs: outside).
      const Vector2d& corner = w[1];
      if (!upstream(s.free, corner)) return false;
      if (s.y.kind == EdgeKind::kFree ? !upstream(s.y, corner) : ToSegment(corner, s.y) > tol_) return false;
      const Vector2d dir = s.forward ? (corner - w[0]).normalized() : (w[2 % m] - corner).normalized();
      const RegionRing old_ring = CarryRing(before, theta, eps_);
      for (size_t k = s.forward ? 2 : 1; k <= (s.forward ? s.remove + 1 : s.remove); ++k) {
        if (!(Cross(dir, old_ring.vertices[k] - corner) < -tol_)) return false;
      }
      return true;
    }
    case Shape::kUnblocked: {
      const Vector2d& hit = w[1];
      const auto old_hit = MeetAt(s.free, s.y, theta, eps_);
      return ToSegment(hit, s.x) <= tol_ && upstream(s.free, hit) && old_hit && ToSegment(*old_hit, s.y) > tol_;
    }
  }
  return false;
}

}  // namespace visco::planning::internal

#include "planning/nondirectional.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <iterator>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <thread>

#include "planning/geometry.h"

namespace visco::planning {

int MachineThreads() { return static_cast<int>(std::max(1u, std::thread::hardware_concurrency())); }
namespace {

using Eigen::Vector2d;

constexpr double kSameTheta = 1e-10;  // candidates closer than this are one event

std::vector<std::string> RingSequence(const RegionRing& ring, const char* tag) {
  const size_t n = ring.edges.size();
  std::vector<std::string> items;
  items.reserve(n);
  for (const auto& e : ring.edges) items.push_back(std::string(EdgeKindName(e.kind)) + ":" + e.ref);
  // The lexicographically least rotation names the cyclic sequence. Rotations are compared in place on the items'
  // ranks (the same order as the strings), without building them: a ring of a thousand edges costs about n
  // comparisons instead of n² string copies.
  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return items[a] < items[b]; });
  std::vector<size_t> rank(n);
  for (size_t i = 0, r = 0; i < n; ++i) {
    if (i > 0 && items[order[i]] != items[order[i - 1]]) ++r;
    rank[order[i]] = r;
  }
  size_t best = 0;
  for (size_t r = 1; r < n; ++r) {
    for (size_t i = 0; i < n; ++i) {
      const size_t x = rank[(r + i) % n], y = rank[(best + i) % n];
      if (x != y) {
        if (x < y) best = r;
        break;
      }
    }
  }
  std::vector<std::string> out = {tag};
  out.reserve(n + 1);
  for (size_t i = 0; i < n; ++i) out.push_back(std::move(items[(best + i) % n]));
  return out;
}

std::string Join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) {
    if (!s.empty()) s += ' ';
    s += x;
  }
  return s;
}

double Cross(const Vector2d& u, const Vector2d& v) { return u.x() * v.y() - u.y() * v.x(); }

double SegmentsDistance(const Vector2d& a, const Vector2d& b, const Vector2d& c, const Vector2d& d) {
  const double den = Cross(b - a, d - c);
  if (std::abs(den) > 0) {
    const double t = Cross(c - a, d - c) / den, u = Cross(c - a, b - a) / den;
    if (t >= 0 && t <= 1 && u >= 0 && u <= 1) return 0.0;
  }
  return std::min({PointSegmentDistance(a, c, d), PointSegmentDistance(b, c, d), PointSegmentDistance(c, a, b),
                   PointSegmentDistance(d, a, b)});
}

template <typename F>
void ForEachRing(const Region& region, F&& f) {
  for (const auto& poly : region.polygons) {
    f(poly.outer);
    for (const auto& h : poly.holes) f(h);
  }
}

// How near (relative to the scene's size) an event's point must be to a carried region's boundary to count as on
// it: the carrying's error is about 1e-12 (NondirectionalProperty), and candidates up to 1e-10 rad apart are one
// event.
constexpr double kOnBoundary = 1e-7;

// Whether p lies within `tolerance` of a ring of `region`.
bool PointNearBoundary(const Vector2d& p, const Region& region, double tolerance) {
  bool near = false;
  ForEachRing(region, [&](const RegionRing& r) {
    const size_t n = r.vertices.size();
    for (size_t i = 0; i < n && !near; ++i)
      near = PointSegmentDistance(p, r.vertices[i], r.vertices[(i + 1) % n]) <= tolerance;
  });
  return near;
}

// One ring's change across an event: the edges of `before` from b_begin (b_count of them, wrapping) replaced by those
// of `after` from a_begin (a_count), the rest of the two rings equal.
struct RingEdit {
  const RegionRing* before = nullptr;
  const RegionRing* after = nullptr;
  size_t b_begin = 0, b_count = 0, a_begin = 0, a_count = 0;
};

bool SameEdge(const RegionEdge& x, const RegionEdge& y) { return x.kind == y.kind && x.ref == y.ref; }

// The smallest contiguous edit turning ring `b` into ring `a` (both cyclic), found from three anchors (edges both
// share: an anchor outside the edit gives it).
std::optional<RingEdit> SmallestEdit(const RegionRing& b, const RegionRing& a) {
  const size_t nb = b.edges.size(), na = a.edges.size();
  if (nb == 0 || na == 0) return std::nullopt;
  std::optional<RingEdit> best;
  for (const size_t i : {size_t{0}, nb / 3, 2 * nb / 3}) {
    for (size_t j = 0; j < na; ++j) {
      if (!SameEdge(b.edges[i], a.edges[j])) continue;
      const size_t most = std::min(nb, na);
      size_t p = 0, q = 0;
      while (p < most && SameEdge(b.edges[(i + p) % nb], a.edges[(j + p) % na])) ++p;
      while (q + p < most && SameEdge(b.edges[(i + nb - 1 - q) % nb], a.edges[(j + na - 1 - q) % na])) ++q;
      RingEdit e{&b, &a, (i + p) % nb, nb - p - q, (j + p) % na, na - p - q};
      if (!best || e.b_count + e.a_count < best->b_count + best->a_count) best = e;
    }
  }
  return best;
}

// The one ring of `before` and the one of `after` that differ (as cyclic sequences), when exactly one does on each
// side and the polygons they belong to are the only ones that differ.
std::optional<RingEdit> OneRingChanged(const Region& before, const Region& after,
                                       const std::vector<std::string>& s_before,
                                       const std::vector<std::string>& s_after) {
  std::vector<std::string> only_b, only_a;
  std::set_difference(s_before.begin(), s_before.end(), s_after.begin(), s_after.end(), std::back_inserter(only_b));
  std::set_difference(s_after.begin(), s_after.end(), s_before.begin(), s_before.end(), std::back_inserter(only_a));
  if (only_b.size() != 1 || only_a.size() != 1) return std::nullopt;
  std::vector<std::pair<std::string, const RegionRing*>> rb, ra;
  auto rings = [](const Region& r, std::vector<std::pair<std::string, const RegionRing*>>& out) {
    ForEachRing(r, [&](const RegionRing& ring) { out.push_back({Join(RingSequence(ring, "ring")), &ring}); });
    std::sort(out.begin(), out.end());
  };
  rings(before, rb);
  rings(after, ra);
  std::vector<const RegionRing*> changed_b, changed_a;
  auto differ = [](const auto& x, const auto& y, std::vector<const RegionRing*>& out) {
    size_t j = 0;
    for (const auto& [key, ring] : x) {
      while (j < y.size() && y[j].first < key) ++j;
      if (j < y.size() && y[j].first == key) {
        ++j;
      } else {
        out.push_back(ring);
      }
    }
  };
  differ(rb, ra, changed_b);
  differ(ra, rb, changed_a);
  if (changed_b.size() != 1 || changed_a.size() != 1) return std::nullopt;
  return SmallestEdit(*changed_b[0], *changed_a[0]);
}

// Whether `edit` is the local change candidate c makes at its orientation (docs/planning_nondirectional.md, "How much
// changes at a critical orientation"): a free vertex crossing a static edge inserts or removes that edge between its
// two free edges; a free edge passing a point b inserts or removes a chain next to it that has b for a vertex, or the
// free edge itself next to the free edge erected at b; a free edge running along a static segment hands over from
// one end's free edge to the other's and the segment between them. Refs and points both have to agree.
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

// A point where an event can change a region, and which of the point's two free edges it must involve (+1:
// direction θ + π + ε_v, −1: θ + π − ε_v, 0: either).
struct EventPoint {
  Vector2d p;
  int sign = 0;
};

// Where events can change `region`, broadly (the R-critical cuts, the reported candidate, the walk's broad rule): at
// the static point a free edge of it is erected at (its source), involving that free edge, and at every vertex,
// involving either free edge there. A free edge usually starts at its source, but not
// always: where the part next to the source lies outside the region (in a forbidden region beside a goal strip, or
// beyond the bounds), the region's edge starts where the line leaves it, and events at the source move that edge all
// the same (VISCO_SEED_OFFSET=19507001, strategy seed 11: the free vertex of a goal strip's two free edges crossed
// the bounds unseen, and a slice spanning 133° was carried to a region of area 15 where the sweep gives 0.03). And a
// vertex where a free edge does not start yet is where a part of the region can appear, attached (and go again
// before the next sweep: the strip property).
void AddEventPoints(const Region& region, std::vector<EventPoint>& out) {
  ForEachRing(region, [&](const RegionRing& ring) {
    for (size_t i = 0; i < ring.vertices.size(); ++i) {
      out.push_back({ring.vertices[i], 0});
      if (ring.edges[i].kind == EdgeKind::kFree) out.push_back({ring.edges[i].source, ring.edges[i].sign});
    }
  });
}

// The kinetic walk's narrower rule: only the free edges of `region` (their sources, and their two ends, each with
// its sign). A part of the region that appears attached at a vertex where no free edge starts does so where a free
// edge turns across a static segment's line at that vertex (the segment's `along` vgraph events, decided by whether
// the segment meets the region: CanChange) or where an edge starts or stops sticking (sliding events).
void AddFreeEdgePoints(const Region& region, std::vector<EventPoint>& out) {
  ForEachRing(region, [&](const RegionRing& ring) {
    const size_t n = ring.vertices.size();
    for (size_t i = 0; i < n; ++i) {
      if (ring.edges[i].kind != EdgeKind::kFree) continue;
      const int sign = ring.edges[i].sign;
      out.push_back({ring.edges[i].source, sign});
      out.push_back({ring.vertices[i], sign});
      out.push_back({ring.vertices[(i + 1) % n], sign});
    }
  });
}

// Whether `p` is one of `points`, for the free edge of sign `want` (0: either).
bool IsEventPoint(const std::vector<EventPoint>& points, const Vector2d& p, int want, double tolerance) {
  return std::any_of(points.begin(), points.end(), [&](const EventPoint& e) {
    return (e.p - p).norm() <= tolerance && (e.sign == 0 || want == 0 || e.sign == want);
  });
}

// Runs task(i) for i in [0, n) on `threads` threads; the calling thread reports progress.
template <typename Task>
void ParallelFor(size_t n, int threads, const std::function<void(double)>& progress, double base, double span,
                 Task&& task) {
  std::atomic<size_t> next{0}, done{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto worker = [&] {
    for (;;) {
      const size_t i = next.fetch_add(1);
      if (i >= n) return;
      try {
        task(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        next = n;
      }
      done.fetch_add(1);
    }
  };
  // With more than one thread the calling thread only reports progress.
  const int extra = threads > 1 ? std::min<int>(threads, static_cast<int>(n)) : 0;
  std::vector<std::thread> pool;
  for (int t = 0; t < extra; ++t) pool.emplace_back(worker);
  if (extra == 0) {
    for (;;) {
      const size_t i = next.fetch_add(1);
      if (i >= n) break;
      task(i);
      done.fetch_add(1);
      if (progress && (i % 8 == 0)) progress(base + span * static_cast<double>(i + 1) / static_cast<double>(n));
    }
  } else {
    while (done.load() < n && !error) {
      if (progress) progress(base + span * static_cast<double>(done.load()) / static_cast<double>(n));
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      if (next.load() >= n) break;
    }
    for (auto& t : pool) t.join();
  }
  if (error) std::rethrow_exception(error);
  if (progress) progress(base + span);
}

// The line an edge of a ring lies on at θ: a free edge's through its source, direction θ + π ± ε_v by its ref's
// suffix; any other edge's is the line of the static segment it lies on (it does not move).
struct EdgeLine {
  Vector2d point, dir;
  bool free = false;
};

EdgeLine LineOf(const RegionRing& ring, size_t i, double theta, double eps) {
  const RegionEdge& e = ring.edges[i];
  if (e.kind == EdgeKind::kFree) {
    const double angle = theta + M_PI + (e.sign > 0 ? eps : -eps);
    return {e.source, Vector2d(std::cos(angle), std::sin(angle)), true};
  }
  // The static segment it lies on as the sweep recorded it (exact up to one rounding), else its own two ends (less
  // precise when the edge is short).
  if (e.line[0] != e.line[1]) return {e.line[0], e.line[1] - e.line[0], false};
  const Vector2d& a = ring.vertices[i];
  const Vector2d& b = ring.vertices[(i + 1) % ring.vertices.size()];
  return {a, b - a, false};
}

double RingArea2(const std::vector<Vector2d>& v) {
  double a = 0;
  for (size_t i = 0; i < v.size(); ++i) a += Cross(v[i], v[(i + 1) % v.size()]);
  return a;
}

RegionRing CarryRing(const RegionRing& ring, double theta, double eps) {
  RegionRing out = ring;
  const size_t n = ring.vertices.size();
  if (n == 0 || ring.edges.size() != n) return out;
  std::vector<EdgeLine> lines(n);
  for (size_t i = 0; i < n; ++i) lines[i] = LineOf(ring, i, theta, eps);
  for (size_t i = 0; i < n; ++i) {
    const EdgeLine& u = lines[(i + n - 1) % n];  // the edge into vertex i
    const EdgeLine& w = lines[i];                // the edge out of it
    if (!u.free && !w.free) continue;            // two edges that do not move meet where they did
    const double den = Cross(u.dir, w.dir);
    // Parallel lines meet nowhere: only at a critical orientation (a vgraph or vc event), where nothing is carried.
    if (std::abs(den) <= 1e-15 * u.dir.norm() * w.dir.norm()) continue;
    out.vertices[i] = u.point + (Cross(w.point - u.point, w.dir) / den) * u.dir;
  }
  return out;
}

// Updating a slice across an event without a sweep (docs/planning_nondirectional.md, "Computing the slice after a
// change"): the local edits whose new edges follow from the event and the static arrangement alone.
enum class Update : std::uint8_t { kUnchanged, kEdited, kUnknown };

// Where the lines of two edges meet at θ, unless they are (nearly) parallel.
std::optional<Vector2d> MeetAt(const RegionEdge& u, const RegionEdge& w, double theta, double eps) {
  const RegionRing pair{{Vector2d::Zero(), Vector2d::Zero()}, {u, w}};
  const EdgeLine a = LineOf(pair, 0, theta, eps), b = LineOf(pair, 1, theta, eps);
  const double den = Cross(a.dir, b.dir);
  if (!(std::abs(den) > 1e-12 * a.dir.norm() * b.dir.norm())) return std::nullopt;
  return a.point + (Cross(b.point - a.point, b.dir) / den) * a.dir;
}

class RegionUpdater {
 public:
  // `crossed`: the static edges another one meets away from their shared ends (overlapping obstacles, a goal on
  // CB): the region's boundary there is not the polygon's, and no shape below is taken along them.
  RegionUpdater(const std::vector<RegionEdge>& statics, const std::set<std::string>& crossed, double tolerance,
                double eps)
      : statics_(statics), crossed_(crossed), tol_(tolerance), eps_(eps) {}

  // The static edges another static edge meets away from their shared ends (within `tolerance`).
  static std::set<std::string> Crossed(const std::vector<RegionEdge>& e, double tolerance) {
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

  // The edit that candidate c (a free vertex crossing a static edge, or a free edge passing a C-obstacle vertex)
  // makes to `region` (a slice's, at its own θ; `at_event` is it carried to the event), applied and carried to
  // `theta_after` in `out`; kUnchanged where the event's point is off the region's boundary; kUnknown where the
  // region near the event is not one of the shapes below, or the shapes that pass their checks disagree, or none
  // does (the walk then sweeps). `rays`: every candidate ray's segments for the VC region (none for the
  // classic one): an event at a ray, or an edit that reaches one, can change the rays chosen, which no shape covers.
  Update Apply(const CriticalOrientation& c, const Region& region, const Region& at_event, double theta_after,
               const std::vector<std::array<Vector2d, 2>>& rays, Region& out) const {
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

  static const RegionRing& RingOf(const Region& r, size_t p, int h) {
    return h < 0 ? r.polygons[p].outer : r.polygons[p].holes[static_cast<size_t>(h)];
  }
  static RegionRing& RingOf(Region& r, size_t p, int h) {
    return h < 0 ? r.polygons[p].outer : r.polygons[p].holes[static_cast<size_t>(h)];
  }
  bool NearRay(const Vector2d& p, const std::vector<std::array<Vector2d, 2>>& rays) const {
    return std::any_of(rays.begin(), rays.end(),
                       [&](const auto& r) { return PointSegmentDistance(p, r[0], r[1]) <= tol_; });
  }
  bool FreeOf(const RegionEdge& e, const Vector2d& p, int sign) const {
    return e.kind == EdgeKind::kFree && e.sign == sign && (e.source - p).norm() <= tol_;
  }
  bool IsObstacle(const RegionEdge& e) const {
    return e.kind == EdgeKind::kObstacle && e.line[0] != e.line[1] && Clean(e);
  }
  static bool IsStatic(const RegionEdge& e) {
    return e.kind != EdgeKind::kFree && e.kind != EdgeKind::kVc && e.line[0] != e.line[1];
  }
  static bool Same(const RegionEdge& u, const RegionEdge& w) { return u.kind == w.kind && u.ref == w.ref; }
  double ToSegment(const Vector2d& p, const RegionEdge& e) const {
    return PointSegmentDistance(p, e.line[0], e.line[1]);
  }
  bool EndsAt(const RegionEdge& e, const Vector2d& p) const {
    return (e.line[0] - p).norm() <= tol_ || (e.line[1] - p).norm() <= tol_;
  }
  // The direction of a's free edge of sign s at θ (upstream: θ + π ± ε_v).
  Vector2d FreeDirection(int sign, double theta) const {
    const double angle = theta + M_PI + (sign > 0 ? eps_ : -eps_);
    return {std::cos(angle), std::sin(angle)};
  }
  // Whether another ring of the region touches ring (p, h): motions can pass from one part of the region to another
  // where they touch, so an edit of one can change the other (VISCO_SEED_OFFSET=1000003, seed 63: a second part
  // touching the first where a run was cut off went with it).
  bool TouchesOtherRings(const Region& region, size_t p, int h) const {
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

  // Whether the segment pq crosses a static edge or a ray in its interior (away from its ends).
  bool Crosses(const Vector2d& p, const Vector2d& q, const std::vector<std::array<Vector2d, 2>>& rays) const {
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

  // The two C-obstacle edges that end at b, when b is a vertex of exactly those and no other static edge passes it.
  std::optional<std::array<const RegionEdge*, 2>> EdgesAt(const Vector2d& b) const {
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
  // The other C-obstacle edge at b (b a vertex of exactly two, x one of them).
  const RegionEdge* OtherEdgeAt(const Vector2d& b, const RegionEdge& x) const {
    const auto at = EdgesAt(b);
    if (!at) return nullptr;
    if (Same(*(*at)[0], x)) return (*at)[1];
    if (Same(*(*at)[1], x)) return (*at)[0];
    return nullptr;
  }

  // A free vertex f of a's +ε_v and b's −ε_v free edges crossing a static edge e: with the region inside the corner
  // at f (the corner is cut off by e), or e between them (e goes, the corner comes back).
  void VertexSites(const CriticalOrientation& c, const RegionRing& ring, const RegionRing& at_event, size_t i,
                   std::vector<Site>& out) const {
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

  // a's free edge (sign s) passing b, a vertex of CB where two C-obstacle edges meet (docs: the shapes above).
  void VgraphSites(const CriticalOrientation& c, const RegionRing& ring, const RegionRing& at_event, size_t i,
                   std::vector<Site>& out) const {
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

  // Applies site s to `region` and carries it to θ; whether the result is clearly what the shape says (by more than
  // the tolerance): the new vertices on their segments, the free edges going upstream from their sources, the
  // corner cut off or free again, the free edge's end past b.
  bool Edit(const Site& s, const Region& region, double theta, const std::vector<std::array<Vector2d, 2>>& rays,
            Region& out) const {
    Region edited = region;
    RegionRing& ring = RingOf(edited, s.polygon, s.hole);
    const size_t n = ring.edges.size();
    if (s.remove + 3 > n + s.insert.size()) return false;
    // The site at the ring's start: edge 0 is the anchor, edges 1 .. remove go, `insert` comes after edge 0.
    std::rotate(ring.edges.begin(), ring.edges.begin() + static_cast<std::ptrdiff_t>(s.index), ring.edges.end());
    std::rotate(ring.vertices.begin(), ring.vertices.begin() + static_cast<std::ptrdiff_t>(s.index),
                ring.vertices.end());
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

  static std::string Key(const RegionEdge& e) { return std::string(EdgeKindName(e.kind)) + ":" + e.ref; }
  bool Clean(const RegionEdge& e) const { return crossed_.count(Key(e)) == 0; }

  const std::vector<RegionEdge>& statics_;
  const std::set<std::string>& crossed_;
  double tol_, eps_;
};

class Builder {
 public:
  Builder(const BackprojectionProblem& problem, const NamedPolygon* start, const NondirectionalOptions& options)
      : pr_(problem), start_(start), options_(options) {
    size_ = (problem.bounds_max - problem.bounds_min).norm();
  }

  NondirectionalBackprojection Run() {
    NondirectionalBackprojection nd;
    nd.velocity_cone = pr_.velocity_cone;
    if (options_.method == SliceMethod::kKinetic && options_.computed_updates) {
      statics_ = StaticRegionEdges(pr_);
      crossed_ = RegionUpdater::Crossed(statics_, kOnBoundary * size_);
      // Every candidate ray, active or not: an event at a ray's end can also change which rays are chosen.
      for (const auto& ray : pr_.rays)
        ray_segments_.insert(ray_segments_.end(), ray.segments.begin(), ray.segments.end());
    }
    auto candidates = CriticalCandidates(pr_, start_, &nd.stats.counts);
    nd.stats.candidates = static_cast<std::int64_t>(candidates.size());
    std::vector<CriticalOrientation> r_candidates;
    for (auto& c : candidates) {
      if (c.kind == CriticalKind::kR) {
        r_candidates.push_back(std::move(c));
      } else {
        structural_.push_back(std::move(c));
      }
    }
    // Events: groups of structural candidates at (nearly) one θ.
    for (size_t i = 0; i < structural_.size();) {
      size_t j = i + 1;
      while (j < structural_.size() && structural_[j].theta - structural_[j - 1].theta <= kSameTheta) ++j;
      events_.push_back({i, j});
      i = j;
    }
    // Interval k's structure is that of intervals[source[k]] (the last swept interval up to k).
    std::vector<size_t> source;
    std::vector<Slice> intervals = IntervalSlices(source);
    // Orientations where the interval structure changes.
    std::vector<double> changes;
    std::vector<int> change_candidate;
    const size_t m = events_.size();
    for (size_t k = 0; k < m && m > 1; ++k) {
      const size_t b = source[(k + m - 1) % m], a = source[k];
      if (a == b) continue;  // no sweep in between: the same structure
      const Slice& before = intervals[b];
      const Slice& after = intervals[a];
      if (before.structure == after.structure) continue;
      if (const auto rays = RaySwitchInGap(k, before, after)) {
        AddSelection(*rays, changes, change_candidate);
        continue;
      }
      changes.push_back(EventTheta(k));
      change_candidate.push_back(PickCandidate(k, before, after));
      // The rule judged against the true structure before the event: a change it would skip was found only by the
      // walk's later sweeps (docs/planning_nondirectional.md argues there is none with the same chosen rays; a switch
      // of the rays can follow from an event in a ray's trial region, outside the regions the rule looks at).
      if (options_.method == SliceMethod::kKinetic && before.structure.active_rays == after.structure.active_rays &&
          !EventRelevant(k, WalkPointsOf(before), before)) {
        ++rule_missed_;
        bool sliding = false;
        for (size_t i = events_[k].begin; i < events_[k].end; ++i) {
          sliding = sliding || structural_[i].kind == CriticalKind::kSliding;
        }
        if (sliding) ++rule_missed_sliding_;
      }
    }
    Verify(changes, change_candidate, intervals, source);
    // Final slices.
    std::vector<std::pair<double, int>> order;
    for (size_t i = 0; i < changes.size(); ++i) order.push_back({changes[i], change_candidate[i]});
    std::sort(order.begin(), order.end());
    order.erase(std::unique(order.begin(), order.end(),
                            [](const auto& x, const auto& y) { return y.first - x.first <= kSameTheta; }),
                order.end());
    const size_t n = order.size();
    nd.slices.resize(n == 0 ? 1 : 2 * n);
    ParallelFor(nd.slices.size(), options_.threads, options_.progress, 0.85, 0.15, [&](size_t s) {
      if (n == 0) {
        nd.slices[0] = Evaluate(0.0, kSweepSlices);
        nd.slices[0].lo = -M_PI;
        nd.slices[0].hi = M_PI;
        return;
      }
      const size_t k = s / 2;
      const double lo = order[k].first;
      const double hi = k + 1 < n ? order[k + 1].first : order[0].first + 2 * M_PI;
      if (s % 2 == 0) {
        nd.slices[s] = Evaluate(lo, kSweepSlices);
        nd.slices[s].lo = nd.slices[s].hi = lo;
        nd.slices[s].critical = true;
      } else {
        // The interval checks swept its midpoint already when it was last probed.
        const auto cached = midpoints_.find({lo, hi});
        nd.slices[s] = cached != midpoints_.end() ? std::move(cached->second)
                                                  : Evaluate(WrapAngle(lo + 0.5 * (hi - lo)), kSweepSlices);
        nd.slices[s].lo = lo;
        nd.slices[s].hi = hi;
      }
    });
    for (const auto& [theta, c] : order) {
      CriticalOrientation o;
      o.theta = theta;
      if (c >= 0) {
        o.kind = structural_[c].kind;
        o.refs = structural_[c].refs;
        o.sliding = structural_[c].sliding;
      } else {
        o.kind = CriticalKind::kSelection;
        o.refs = selection_refs_[theta];
      }
      nd.orientations.push_back(o);
      ++nd.stats.changes;
      if (c < 0) ++nd.stats.selection;
    }
    // R-critical orientations of the start region where their sources are vertices of the regions there.
    for (int i = 0; i < kSweepPurposes; ++i) {
      nd.stats.sweeps[i] = sweeps_[i].load();
      nd.stats.sweep_seconds[i] = 1e-9 * static_cast<double>(sweep_ns_[i].load());
      nd.stats.backprojections += nd.stats.sweeps[i];
    }
    nd.stats.checked = checked_;
    nd.stats.events = static_cast<std::int64_t>(events_.size());
    nd.stats.unexplained = unexplained_;
    nd.stats.found_by_probes = found_by_probes_;
    nd.stats.rule_missed = rule_missed_;
    nd.stats.explained = explained_;
    nd.stats.updated = updated_.load();
    nd.stats.update_mismatches = update_mismatches_.load();
    nd.stats.rule_missed_sliding = rule_missed_sliding_;
    nd.stats.unexplained_at = unexplained_at_;
    for (auto& c : r_candidates) {
      const Slice& s = SliceAt(nd, c.theta);
      if (!Relevant(c, EventPointsOf(s))) continue;
      c.sources.clear();
      nd.orientations.push_back(std::move(c));
      ++nd.stats.r_critical;
    }
    std::stable_sort(nd.orientations.begin(), nd.orientations.end(),
                     [](const CriticalOrientation& x, const CriticalOrientation& y) { return x.theta < y.theta; });
    for (auto& o : nd.orientations) o.sources.clear();
    return nd;
  }

 private:
  struct Event {
    size_t begin, end;  // candidates [begin, end)
  };

  double EventTheta(size_t k) const { return structural_[events_[k].begin].theta; }

  Slice Evaluate(double theta, SweepPurpose purpose) {
    const auto t0 = std::chrono::steady_clock::now();
    BackprojectionProblem p = pr_;
    p.theta = theta;
    Slice s;
    s.theta = theta;
    s.lo = s.hi = theta;
    s.vc = VcEnlargedBackprojection(p, options_.selection);
    s.structure.classic = RegionStructure(s.vc.classic);
    s.structure.vc = RegionStructure(s.vc.region);
    s.structure.active_rays = s.vc.active_rays;
    ++sweeps_[purpose];
    sweep_ns_[purpose] +=
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count();
    return s;
  }

  // Where events can change the slice's regions (both of them).
  std::vector<EventPoint> EventPointsOf(const Slice& s) const {
    std::vector<EventPoint> v;
    AddEventPoints(s.vc.classic, v);
    AddEventPoints(s.vc.region, v);
    return v;
  }

  // The points the kinetic walk's rule looks at (every vertex of the regions with the broad rule).
  std::vector<EventPoint> WalkPointsOf(const Slice& s) const {
    if (options_.vertex_events) return EventPointsOf(s);
    std::vector<EventPoint> v;
    AddFreeEdgePoints(s.vc.classic, v);
    AddFreeEdgePoints(s.vc.region, v);
    return v;
  }

  // An event matters only where every free edge it involves can be one of the regions' (a free vertex needs both):
  // each source is a vertex of the regions, or the source of one of their free edges with the same sign.
  bool Relevant(const CriticalOrientation& c, const std::vector<EventPoint>& ends) const {
    for (size_t k = 0; k < c.sources.size(); ++k) {
      const int want = k < c.source_signs.size() ? c.source_signs[k] : 0;
      if (!IsEventPoint(ends, c.sources[k], want, 1e-9 * size_)) return false;
    }
    return true;
  }

  // A slice's regions carried to an event's orientation, computed when first asked for (most events are decided by
  // their sources alone).
  class CarriedAt {
   public:
    CarriedAt(const Slice& s, double theta, double eps) : s_(s), theta_(theta), eps_(eps) {}
    const std::array<Region, 2>& Get() {
      if (!regions_) {
        regions_ = {CarryRegion(s_.vc.classic, theta_, eps_), CarryRegion(s_.vc.region, theta_, eps_)};
      }
      return *regions_;
    }

   private:
    const Slice& s_;
    double theta_, eps_;
    std::optional<std::array<Region, 2>> regions_;
  };

  // Whether candidate c can change the structure of slice s (whose event points are `ends`; `carried` is s carried to
  // the event): a sliding event only where its edge or vertex meets the closure of a region, the others where their
  // sources are event points and, with `boundary_events`, their point lies on the boundary of a carried region.
  bool CanChange(const CriticalOrientation& c, const std::vector<EventPoint>& ends, const Slice& s,
                 CarriedAt& carried) const {
    const auto feature_meets_regions = [&] {
      const double tol = 1e-9 * size_;
      return FeatureMeetsRegion(c.feature, s.vc.classic, tol) || FeatureMeetsRegion(c.feature, s.vc.region, tol);
    };
    if (c.kind == CriticalKind::kSliding && options_.local_sliding && !c.feature.empty()) {
      // The cone pointing away from the obstacle, θ itself along the edge, the vertex rule's bisector pointing out
      // of CB, the edge sticking on both sides: no velocity's contact changes.
      if (SlidingCauseChangesNothing(c.sliding)) return false;
      return feature_meets_regions();
    }
    if (Relevant(c, ends)) {
      if (!options_.boundary_events || options_.vertex_events || c.point.empty()) return true;
      const double tol = kOnBoundary * size_;
      const auto& regions = carried.Get();
      return PointNearBoundary(c.point.front(), regions[0], tol) || PointNearBoundary(c.point.front(), regions[1], tol);
    }
    // A free edge turning across the line of a static segment: a part of the region can appear along the segment.
    return !options_.vertex_events && c.kind == CriticalKind::kVgraph && !c.feature.empty() && feature_meets_regions();
  }

  // Whether event k can change the structure of `current` (the last swept slice, whose event points are `ends`).
  bool EventRelevant(size_t k, const std::vector<EventPoint>& ends, const Slice& current) const {
    CarriedAt carried(current, EventTheta(k), pr_.velocity_cone);
    for (size_t i = events_[k].begin; i < events_[k].end; ++i) {
      if (CanChange(structural_[i], ends, current, carried)) return true;
    }
    return false;
  }

  // The slice after event k computed from `last` (the last slice before it, swept or computed) without a sweep, where
  // the event is one candidate whose local edit the updater knows and that edit is confirmed; nullopt otherwise.
  // `ends`: last's walk points (the walk has them already).
  std::optional<Slice> Updated(size_t k, const Slice& last, const std::vector<EventPoint>& ends) const {
    CarriedAt carried(last, EventTheta(k), pr_.velocity_cone);
    const CriticalOrientation* only = nullptr;
    for (size_t i = events_[k].begin; i < events_[k].end; ++i) {
      if (!CanChange(structural_[i], ends, last, carried)) continue;
      if (only != nullptr) return std::nullopt;  // several events at once
      only = &structural_[i];
    }
    if (only == nullptr || (only->kind != CriticalKind::kVertex && only->kind != CriticalKind::kVgraph)) {
      return std::nullopt;
    }
    const double theta = IntervalTheta(k);
    const RegionUpdater updater(statics_, crossed_, kOnBoundary * size_, pr_.velocity_cone);
    Slice s;
    s.theta = s.lo = s.hi = theta;
    s.vc.active_rays = last.vc.active_rays;
    s.vc.rejected_rays = last.vc.rejected_rays;
    s.vc.unreliable_rays = last.vc.unreliable_rays;
    s.vc.selection = last.vc.selection;
    s.vc.candidates = last.vc.candidates;
    bool edited = false;
    for (int r = 0; r < 2; ++r) {
      const Region& region = r == 0 ? last.vc.classic : last.vc.region;
      Region& out = r == 0 ? s.vc.classic : s.vc.region;
      switch (updater.Apply(*only, region, carried.Get()[static_cast<size_t>(r)], theta,
                            r == 0 ? std::vector<std::array<Vector2d, 2>>{} : ray_segments_, out)) {
        case Update::kUnknown:
          return std::nullopt;
        case Update::kUnchanged:
          out = CarryRegion(region, theta, pr_.velocity_cone);
          break;
        case Update::kEdited:
          edited = true;
          break;
      }
    }
    if (!edited) return std::nullopt;
    s.structure.classic = RegionStructure(s.vc.classic);
    s.structure.vc = RegionStructure(s.vc.region);
    s.structure.active_rays = s.vc.active_rays;
    return s;
  }

  // Whether the change between `before` and `after` (swept with no event but k between them that the rule takes) is
  // a local edit event k makes (MakesEdit), in each region that changes, with the same active rays: then it happened
  // at k, and no sweep just before k needs to say so. A change at a skipped event would add an edit of its own.
  bool ExplainedAt(size_t k, const Slice& before, const Slice& after) const {
    if (before.structure.active_rays != after.structure.active_rays) return false;
    const double tol = 1e-9 * size_;
    for (const bool vc : {false, true}) {
      const auto& sb = vc ? before.structure.vc : before.structure.classic;
      const auto& sa = vc ? after.structure.vc : after.structure.classic;
      if (sb == sa) continue;
      const auto edit =
          OneRingChanged(vc ? before.vc.region : before.vc.classic, vc ? after.vc.region : after.vc.classic, sb, sa);
      if (!edit) return false;
      bool made = false;
      for (size_t i = events_[k].begin; i < events_[k].end && !made; ++i) made = MakesEdit(structural_[i], *edit, tol);
      if (!made) return false;
    }
    return true;
  }

  // The interval after event k: from its θ to event k + 1's (the last one wraps to the first, a turn on).
  std::pair<double, double> EventInterval(size_t k) const {
    return {EventTheta(k), k + 1 < events_.size() ? EventTheta(k + 1) : EventTheta(0) + 2 * M_PI};
  }

  // The representative θ of the interval after event k.
  double IntervalTheta(size_t k) const {
    const auto [lo, hi] = EventInterval(k);
    return WrapAngle(0.5 * (lo + hi));
  }

  // One slice per interval between consecutive events: every one swept (baseline) or only after relevant events
  // (kinetic; the others inherit the previous interval's slice).
  std::vector<Slice> IntervalSlices(std::vector<size_t>& source) {
    const size_t m = events_.size();
    source.resize(m);
    for (size_t k = 0; k < m; ++k) source[k] = k;
    if (m <= 1) return m == 0 ? std::vector<Slice>{} : std::vector<Slice>{Evaluate(IntervalTheta(0), kSweepWalk)};
    std::vector<Slice> out(m);
    if (options_.method == SliceMethod::kBaseline) {
      checked_ = static_cast<std::int64_t>(m);
      ParallelFor(m, options_.threads, options_.progress, 0.0, 0.7,
                  [&](size_t k) { out[k] = Evaluate(IntervalTheta(k), kSweepWalk); });
      return out;
    }
    // Chunks of events walked independently (one per thread), each starting from a swept interval. An event is
    // swept again when it is relevant, and every `resweep_period` events anyway; when the structure differs from the
    // last swept interval's, the skipped events in between are bisected for where it changed (an event whose free
    // edges are the region's only after it is found that way).
    const size_t period = options_.resweep_period > 0 ? static_cast<size_t>(options_.resweep_period) : m;
    const size_t chunks = std::clamp<size_t>(static_cast<size_t>(std::max(1, options_.threads)), 1, m);
    std::vector<std::int64_t> checked(chunks, 0), explained(chunks, 0);
    std::vector<char> swept(m, 0);
    ParallelFor(chunks, options_.threads, options_.progress, 0.0, 0.7, [&](size_t c) {
      const size_t begin = m * c / chunks, end = m * (c + 1) / chunks;
      auto sweep = [&](size_t k, SweepPurpose purpose) {
        out[k] = Evaluate(IntervalTheta(k), purpose);
        swept[k] = 1;
        ++checked[c];
      };
      // The slice after relevant event k, from the last one: computed where the update knows the event's edit, else
      // swept. With check_updates it is swept as well, and the walk goes on with the sweep.
      auto advance = [&](size_t k, size_t last, const std::vector<EventPoint>& ends) {
        if (options_.computed_updates && !statics_.empty()) {
          if (auto updated = Updated(k, out[last], ends)) {
            ++updated_;
            if (!options_.check_updates) {
              out[k] = std::move(*updated);
              swept[k] = 1;
              return;
            }
            sweep(k, kSweepWalk);
            const double tol = 1e-9 * size_ * size_;
            if (!(updated->structure == out[k].structure) ||
                std::abs(updated->vc.classic.area - out[k].vc.classic.area) > tol ||
                std::abs(updated->vc.region.area - out[k].vc.region.area) > tol) {
              ++update_mismatches_;
            }
            return;
          }
        }
        sweep(k, kSweepWalk);
      };
      // Finds every change between swept intervals lo < hi whose structures differ.
      std::function<void(size_t, size_t)> bisect = [&](size_t lo, size_t hi) {
        if (hi - lo <= 1) return;
        const size_t mid = lo + (hi - lo) / 2;
        sweep(mid, kSweepLocate);
        if (!(out[mid].structure == out[lo].structure)) bisect(lo, mid);
        if (!(out[mid].structure == out[hi].structure)) bisect(mid, hi);
      };
      // Most changes are at the event just swept (it was swept because it is relevant): the interval before it
      // tells at once, instead of a bisection of the whole gap.
      auto locate = [&](size_t lo, size_t hi) {
        if (hi - lo >= 2 && options_.local_edits && ExplainedAt(hi, out[lo], out[hi])) {
          ++explained[c];
          return;  // the change is event hi's own local edit
        }
        if (hi - lo <= 2) return bisect(lo, hi);
        sweep(hi - 1, kSweepLocate);
        if (out[hi - 1].structure == out[lo].structure) return;  // the change is at event hi alone
        bisect(lo, hi - 1);
      };
      // Where the structure differs between swept intervals lo < hi: the changes located, then every stretch between
      // two swept intervals walked again with the free edges of the slice that begins it. The events there were
      // skipped for the free edges of the slice at lo; a change found in between can give the region free edges
      // (and so relevant events) it did not have at lo, and a bisection alone misses a structure that comes and
      // goes again between two equal ends (VISCO_SEED_OFFSET=19507001, strategy seed 11: free edges appeared at
      // 54.2°, their free vertex crossed the bounds at 78.3° and back at 152.2°, and the walk, which had skipped
      // those events before the free edges were found, never swept between them).
      std::function<void(size_t, size_t)> walk;
      auto resolve = [&](size_t lo, size_t hi) {
        locate(lo, hi);
        size_t p = lo;
        for (size_t q = lo + 1; q <= hi; ++q) {
          if (!swept[q]) continue;
          if (q - p > 1) walk(p, q);
          p = q;
        }
      };
      // The events strictly between swept intervals lo < hi, under the free edges of each last swept slice.
      walk = [&](size_t lo, size_t hi) {
        size_t last = lo;
        std::vector<EventPoint> ends = WalkPointsOf(out[lo]);
        for (size_t k = lo + 1; k < hi; ++k) {
          if (swept[k] || !EventRelevant(k, ends, out[last])) continue;
          advance(k, last, ends);
          if (!(out[k].structure == out[last].structure)) resolve(last, k);
          last = k;
          ends = WalkPointsOf(out[k]);
        }
        if (last != lo && !(out[hi].structure == out[last].structure)) resolve(last, hi);
      };
      sweep(begin, kSweepWalk);
      std::vector<EventPoint> ends = WalkPointsOf(out[begin]);
      size_t last = begin;
      for (size_t k = begin + 1; k < end; ++k) {
        if (!EventRelevant(k, ends, out[last]) && k - last < period && k + 1 < end) continue;
        advance(k, last, ends);
        if (!(out[k].structure == out[last].structure)) resolve(last, k);
        last = k;
        ends = WalkPointsOf(out[k]);
      }
      // Intervals not swept have the structure of the last swept one before them (not copied: at thousands of
      // events the copies of large structures cost more memory and time than the sweeps).
      size_t from = begin;
      for (size_t k = begin + 1; k < end; ++k) {
        if (swept[k]) from = k;
        source[k] = from;
      }
    });
    for (auto c : checked) checked_ += c;
    for (auto c : explained) explained_ += c;
    return out;
  }

  // The candidate of event k to report: the first whose sources are vertices on either side.
  int PickCandidate(size_t k, const Slice& before, const Slice& after) const {
    auto vb = EventPointsOf(before), va = EventPointsOf(after);
    CarriedAt cb(before, EventTheta(k), pr_.velocity_cone), ca(after, EventTheta(k), pr_.velocity_cone);
    // Prefer the specific kinds (a free edge parallel to a ray is also parallel to the segment of its two ends).
    static const CriticalKind priority[] = {CriticalKind::kVc, CriticalKind::kFreeEdge, CriticalKind::kVertex,
                                            CriticalKind::kSliding, CriticalKind::kVgraph};
    for (CriticalKind kind : priority) {
      for (size_t i = events_[k].begin; i < events_[k].end; ++i) {
        const auto& c = structural_[i];
        if (c.kind == kind && (CanChange(c, vb, before, cb) || CanChange(c, va, after, ca))) return static_cast<int>(i);
      }
    }
    // No candidate the rules take (a change they missed): the first that can change anything at all.
    for (size_t i = events_[k].begin; i < events_[k].end; ++i) {
      if (!SlidingCauseChangesNothing(structural_[i].sliding)) return static_cast<int>(i);
    }
    return static_cast<int>(events_[k].begin);
  }

  // θ (radians) moved by whole turns to the first value not below `from`.
  static double Unwrap(double theta, double from) {
    while (theta < from) theta += 2 * M_PI;
    while (theta - 2 * M_PI >= from) theta -= 2 * M_PI;
    return theta;
  }

  // A change located between two sweeps: where (θ, wrapped) and the structures on its two sides.
  struct Switch {
    double theta = 0.0;
    SliceStructure before, after;
  };

  // Bisects x < y (radians, unwrapped; the structure is `sx` at x and differs at y) to 1e-12 rad for where it changes.
  Switch Bisect(double x, double y, const SliceStructure& sx) {
    for (int it = 0; it < 60 && y - x > 1e-12; ++it) {
      const double mid = 0.5 * (x + y);
      if (Evaluate(WrapAngle(mid), kSweepBisect).structure == sx) {
        x = mid;
      } else {
        y = mid;
      }
    }
    return {WrapAngle(0.5 * (x + y)), sx, Evaluate(WrapAngle(y), kSweepBisect).structure};
  }

  // The chosen rays can switch between two events (the choice compares areas; no event bounds it): the walk's slices
  // on the two sides of event k then differ although nothing happens at k. Where the rays differ and nothing changes
  // just beside k, the gap is bisected for the switch (after k, towards the gap's midpoint where `after` was swept, or
  // before it); a change there that is not the rays' stays with event k.
  std::optional<Switch> RaySwitchInGap(size_t k, const Slice& before, const Slice& after) {
    if (before.structure.active_rays == after.structure.active_rays) return std::nullopt;
    const size_t m = events_.size();
    const double at = EventTheta(k);
    const double gap = std::min(at - EventTheta((k + m - 1) % m) + (k == 0 ? 2 * M_PI : 0.0),
                                EventTheta((k + 1) % m) - at + (k + 1 == m ? 2 * M_PI : 0.0));
    const double dt = std::min(1e-9, 0.25 * gap);
    if (!(dt > 0)) return std::nullopt;
    const SliceStructure right = Evaluate(WrapAngle(at + dt), kSweepBisect).structure;
    if (!(Evaluate(WrapAngle(at - dt), kSweepBisect).structure == right)) return std::nullopt;
    const Switch s = right == after.structure ? Bisect(Unwrap(before.theta, at - 2 * M_PI), at - dt, before.structure)
                                              : Bisect(at + dt, Unwrap(after.theta, at), right);
    if (s.before.active_rays == s.after.active_rays) return std::nullopt;
    return s;
  }

  // Reports a switch of the chosen rays as a `selection` orientation, naming the rays that come or go.
  void AddSelection(const Switch& s, std::vector<double>& changes, std::vector<int>& change_candidate) {
    changes.push_back(s.theta);
    change_candidate.push_back(-1);
    std::vector<std::string> refs;
    std::set_symmetric_difference(s.before.active_rays.begin(), s.before.active_rays.end(), s.after.active_rays.begin(),
                                  s.after.active_rays.end(), std::back_inserter(refs));
    selection_refs_[s.theta] = refs;
  }

  // The candidate within `tolerance` of θ, or −1.
  int NearestCandidate(double theta, double tolerance) const {
    int best = -1;
    double best_d = tolerance;
    for (size_t i = 0; i < structural_.size(); ++i) {
      const double d = std::abs(WrapAngle(structural_[i].theta - theta));
      if (d <= best_d) {
        best_d = d;
        best = static_cast<int>(i);
      }
    }
    return best;
  }

  // The event interval containing θ (radians, any turn): k such that θ lies between events k and k + 1 (wrapping).
  size_t EventIntervalAt(double theta) const {
    theta = WrapAngle(theta);
    const auto first_not_before = std::partition_point(
        events_.begin(), events_.end(), [&](const Event& e) { return structural_[e.begin].theta < theta; });
    // Before the first event: the wrapping interval after the last.
    const size_t after = static_cast<size_t>(first_not_before - events_.begin());
    return (after == 0 ? events_.size() : after) - 1;
  }

  // Records the change located between two sweeps (a switch of the chosen rays, or a change at the nearest
  // candidate, which the walk had skipped, or at none).
  void AddFound(const Switch& s, std::vector<double>& changes, std::vector<int>& change_candidate) {
    const int c = NearestCandidate(s.theta, 1e-7);
    if (s.before.active_rays != s.after.active_rays) {
      AddSelection(s, changes, change_candidate);
      return;
    }
    changes.push_back(c >= 0 ? structural_[c].theta : s.theta);
    change_candidate.push_back(c >= 0 ? c : (structural_.empty() ? -1 : 0));
    if (c >= 0) ++found_by_probes_;
    if (c < 0) {
      ++unexplained_;
      unexplained_at_.push_back(s.theta);
    }
  }

  // Checks every interval between consecutive changes at three orientations and locates any change found there.
  void Verify(std::vector<double>& changes, std::vector<int>& change_candidate, const std::vector<Slice>& intervals,
              const std::vector<size_t>& source) {
    for (int round = 0; round < 4; ++round) {
      std::vector<std::pair<double, int>> order;
      for (size_t i = 0; i < changes.size(); ++i) order.push_back({changes[i], change_candidate[i]});
      std::sort(order.begin(), order.end());
      const size_t n = std::max<size_t>(order.size(), 1);
      struct Probe {
        double lo, hi;
        Slice s[3];
        bool disagreed = false;
      };
      std::vector<Probe> probes(n);
      const double fractions[3] = {0.3, 0.5, 0.7};
      ParallelFor(3 * n, options_.threads, options_.progress, 0.7 + 0.04 * round, 0.04, [&](size_t t) {
        const size_t k = t / 3;
        const double lo = order.empty() ? -M_PI : order[k].first;
        const double hi =
            order.empty() ? M_PI : (k + 1 < order.size() ? order[k + 1].first : order[0].first + 2 * M_PI);
        probes[k].lo = lo;
        probes[k].hi = hi;
        probes[k].s[t % 3] = Evaluate(WrapAngle(lo + fractions[t % 3] * (hi - lo)), kSweepChecks);
      });
      bool found = false;
      for (auto& p : probes) {
        // First round: each probe against the structure the walk gave its event interval (the walk swept there or
        // at an earlier event of the same stretch). A difference is a change the walk missed between that sweep and
        // the probe.
        for (int a = 0; a < 3 && round == 0 && !p.disagreed && events_.size() > 1; ++a) {
          const double theta = p.lo + fractions[a] * (p.hi - p.lo);
          const size_t k = EventIntervalAt(theta);
          // A switch of the chosen rays found inside this event interval: the walk's one structure for it holds
          // on one side of the switch only.
          const auto [event_lo, event_hi] = EventInterval(k);
          const double from = Unwrap(event_lo, theta - 2 * M_PI), to = from + (event_hi - event_lo);
          if (Unwrap(p.lo, from) < to || Unwrap(p.hi, from) < to) continue;
          const Slice& walk = intervals[source[k]];
          if (walk.structure == p.s[a].structure) continue;
          const double swept = Unwrap(walk.theta, p.lo);
          AddFound(swept < theta ? Bisect(swept, theta, walk.structure) : Bisect(theta, swept, p.s[a].structure),
                   changes, change_candidate);
          p.disagreed = true;
          found = true;
        }
        if (p.disagreed) continue;
        for (int a = 0; a < 2; ++a) {
          if (p.s[a].structure == p.s[a + 1].structure) continue;
          // Bisect between the two probes for where the structure changes.
          AddFound(
              Bisect(p.lo + fractions[a] * (p.hi - p.lo), p.lo + fractions[a + 1] * (p.hi - p.lo), p.s[a].structure),
              changes, change_candidate);
          found = true;
          break;  // the rest of this interval is probed again next round
        }
      }
      // The midpoints, for the final open slices of the intervals that do not change any more.
      midpoints_.clear();
      for (auto& p : probes) midpoints_.emplace(std::make_pair(p.lo, p.hi), std::move(p.s[1]));
      if (!found) return;
    }
  }

  const BackprojectionProblem& pr_;
  const NamedPolygon* start_;
  NondirectionalOptions options_;
  double size_ = 1.0;
  std::vector<CriticalOrientation> structural_;
  std::vector<Event> events_;
  std::array<std::atomic<std::int64_t>, kSweepPurposes> sweeps_{};
  std::array<std::atomic<std::int64_t>, kSweepPurposes> sweep_ns_{};
  std::int64_t checked_ = 0;
  std::int64_t unexplained_ = 0;
  std::int64_t found_by_probes_ = 0;
  std::int64_t rule_missed_ = 0;
  std::int64_t explained_ = 0;
  std::int64_t rule_missed_sliding_ = 0;
  std::vector<double> unexplained_at_;
  std::map<double, std::vector<std::string>> selection_refs_;
  std::map<std::pair<double, double>, Slice> midpoints_;  // the last interval checks' midpoint slices, by (lo, hi)
  std::vector<RegionEdge> statics_;                       // the static edges events can bring (computed_updates)
  std::set<std::string> crossed_;                         // of those, the ones another meets (RegionUpdater::Crossed)
  std::vector<std::array<Vector2d, 2>> ray_segments_;     // every candidate ray's segments (computed_updates)
  std::atomic<std::int64_t> updated_{0}, update_mismatches_{0};
};

}  // namespace

std::vector<std::string> RegionStructure(const Region& region) {
  std::vector<std::string> polys;
  for (const auto& poly : region.polygons) {
    std::string s = Join(RingSequence(poly.outer, "outer"));
    std::vector<std::string> holes;
    for (const auto& h : poly.holes) holes.push_back(Join(RingSequence(h, "hole")));
    std::sort(holes.begin(), holes.end());
    for (const auto& h : holes) s += " | " + h;
    polys.push_back(std::move(s));
  }
  std::sort(polys.begin(), polys.end());
  return polys;
}

const char* SweepPurposeName(SweepPurpose purpose) {
  static const char* const kNames[kSweepPurposes] = {"walk", "locate", "checks", "bisect", "slices"};
  return purpose < kSweepPurposes ? kNames[purpose] : "?";
}

NondirectionalBackprojection ComputeNondirectional(const BackprojectionProblem& problem, const NamedPolygon* start,
                                                   const NondirectionalOptions& options) {
  return Builder(problem, start, options).Run();
}

const Slice& SliceAt(const NondirectionalBackprojection& nd, double theta) {
  if (nd.slices.size() == 1) return nd.slices[0];
  theta = WrapAngle(theta);
  for (size_t s = 0; s < nd.slices.size(); s += 2) {
    if (std::abs(WrapAngle(theta - nd.slices[s].theta)) <= 1e-12) return nd.slices[s];
  }
  for (size_t s = 1; s < nd.slices.size(); s += 2) {
    const Slice& sl = nd.slices[s];
    for (double t : {theta, theta + 2 * M_PI}) {
      if (t > sl.lo && t < sl.hi) return sl;
    }
  }
  return nd.slices.back();
}

Region CarryRegion(const Region& region, double theta, double velocity_cone) {
  // θ₀ is not needed: the free edges' lines depend on θ only, and the other edges and the sources do not move.
  const double eps = std::max(velocity_cone, 1e-9);  // as the sweep plans a cone of zero width
  Region out;
  double area2 = 0;
  for (const auto& poly : region.polygons) {
    RegionPolygon q{CarryRing(poly.outer, theta, eps), {}};
    area2 += RingArea2(q.outer.vertices);
    for (const auto& h : poly.holes) {
      q.holes.push_back(CarryRing(h, theta, eps));
      area2 += RingArea2(q.holes.back().vertices);
    }
    out.polygons.push_back(std::move(q));
  }
  out.area = 0.5 * area2;
  return out;
}

Region RegionAt(const NondirectionalBackprojection& nd, double theta, bool vc) {
  const Slice& s = SliceAt(nd, theta);
  const Region& r = vc ? s.vc.region : s.vc.classic;
  if (s.critical) return r;
  return CarryRegion(r, theta, nd.velocity_cone);
}

bool FeatureMeetsRegion(const std::vector<Vector2d>& feature, const Region& region, double tolerance) {
  if (feature.empty() || region.polygons.empty()) return false;
  for (const auto& p : feature) {
    if (region.Contains(p)) return true;
  }
  // Otherwise the feature meets the closure only by touching or crossing a ring (a point as a segment of length 0).
  const Vector2d &a = feature.front(), &b = feature.back();
  bool meets = false;
  ForEachRing(region, [&](const RegionRing& r) {
    const size_t n = r.vertices.size();
    for (size_t i = 0; i < n && !meets; ++i) {
      meets = SegmentsDistance(a, b, r.vertices[i], r.vertices[(i + 1) % n]) <= tolerance;
    }
  });
  return meets;
}

bool RegionContainsPolygon(const Region& region, const std::vector<Vector2d>& polygon, double tolerance,
                           double* clearance) {
  std::vector<std::array<Vector2d, 2>> edges;
  std::vector<bool> obstacle;  // C-obstacle edges: walls, not a risk to be near (they do not count in the clearance)
  ForEachRing(region, [&](const RegionRing& r) {
    for (size_t i = 0; i < r.vertices.size(); ++i) {
      edges.push_back({r.vertices[i], r.vertices[(i + 1) % r.vertices.size()]});
      obstacle.push_back(i < r.edges.size() && r.edges[i].kind == EdgeKind::kObstacle);
    }
  });
  auto inside = [&](const Vector2d& p) { return region.Contains(p) || region.BoundaryDistance(p) <= tolerance; };
  const size_t n = polygon.size();
  double clear = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < n; ++i) {
    const Vector2d a = polygon[i], b = polygon[(i + 1) % n];
    if (!inside(a)) return false;
    // Split the edge where it meets the region's boundary; every piece must be inside.
    std::vector<double> cuts = {0.0, 1.0};
    const Vector2d d = b - a;
    for (size_t k = 0; k < edges.size(); ++k) {
      const auto& e = edges[k];
      const Vector2d f = e[1] - e[0];
      const double den = Cross(d, f);
      if (!obstacle[k]) clear = std::min(clear, SegmentsDistance(a, b, e[0], e[1]));
      if (std::abs(den) < 1e-300) continue;
      const double t = Cross(e[0] - a, f) / den, u = Cross(e[0] - a, d) / den;
      if (t > 0 && t < 1 && u >= 0 && u <= 1) cuts.push_back(t);
    }
    std::sort(cuts.begin(), cuts.end());
    for (size_t k = 0; k + 1 < cuts.size(); ++k) {
      if (!inside(a + 0.5 * (cuts[k] + cuts[k + 1]) * d)) return false;
    }
  }
  if (clearance) *clearance = clear;
  return true;
}

namespace {

// How far (relative to the scene's size) R must be from a carried region's moving edges for the carried region to
// decide containment: the carrying's error is about 1e-12 on the test scenes (NondirectionalProperty).
constexpr double kCarryMargin = 1e-6;

// Whether a point of the polygon's boundary (a vertex, or one of 16 points along each edge) lies outside the region
// farther than `margin` from its boundary.
bool ClearlyOutside(const Region& region, const std::vector<Vector2d>& polygon, double margin) {
  const size_t n = polygon.size();
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 16; ++k) {
      const Vector2d p = polygon[i] + (k / 16.0) * (polygon[(i + 1) % n] - polygon[i]);
      if (!region.Contains(p) && region.BoundaryDistance(p) > margin) return true;
    }
  }
  return false;
}

}  // namespace

std::vector<ThetaInterval> IntervalsContaining(const NondirectionalBackprojection& nd,
                                               const BackprojectionProblem& problem, const NamedPolygon& region,
                                               bool vc, IntervalQueryStats* stats) {
  const double size = (problem.bounds_max - problem.bounds_min).norm();
  // Breakpoints: the slices' orientations and R's own R-critical orientations where their sources are vertices of
  // the region there.
  std::vector<double> cuts;
  for (size_t s = 0; s < nd.slices.size(); s += 2) {
    if (nd.slices[s].critical) cuts.push_back(nd.slices[s].theta);
  }
  for (const auto& c : RCriticalCandidates(problem, region)) {
    const Slice& s = SliceAt(nd, c.theta);
    bool relevant = c.sources.empty();
    std::vector<EventPoint> points;
    AddEventPoints(vc ? s.vc.region : s.vc.classic, points);
    for (const auto& src : c.sources) relevant = relevant || IsEventPoint(points, src, 0, 1e-9 * size);
    if (relevant) cuts.push_back(c.theta);
  }
  std::sort(cuts.begin(), cuts.end());
  cuts.erase(std::unique(cuts.begin(), cuts.end(), [](double x, double y) { return y - x <= kSameTheta; }), cuts.end());
  if (cuts.empty()) cuts.push_back(-M_PI);
  std::vector<ThetaInterval> out;
  const size_t n = cuts.size();
  std::vector<bool> in(n, false);
  std::vector<double> margin(n, 0.0), mids(n, 0.0);
  int carried_decisions = 0;
  for (size_t k = 0; k < n; ++k) {
    const double lo = cuts[k], hi = k + 1 < n ? cuts[k + 1] : cuts[0] + 2 * M_PI;
    const double mid = WrapAngle(0.5 * (lo + hi));
    mids[k] = mid;
    // The slice's region carried to the midpoint decides without a sweep where R is clearly in (its clearance from
    // every edge that moves exceeds the carrying's error many times) or clearly out (a point of R's boundary that
    // far outside); a sweep decides the rest.
    double clear = 0;
    const Region carried = RegionAt(nd, mid, vc);
    const bool carried_in = RegionContainsPolygon(carried, region.vertices, 1e-9 * size, &clear);
    if (carried_in ? clear > kCarryMargin * size : ClearlyOutside(carried, region.vertices, kCarryMargin * size)) {
      in[k] = carried_in;
      margin[k] = carried_in ? clear : 0.0;
      ++carried_decisions;
      continue;
    }
    BackprojectionProblem p = problem;
    p.theta = mid;
    const Slice& s = SliceAt(nd, mid);
    const Region reg = vc ? BackprojectionWithActiveRays(p, s.vc.active_rays) : ClassicBackprojection(p);
    clear = 0;
    in[k] = RegionContainsPolygon(reg, region.vertices, 1e-9 * size, &clear);
    margin[k] = clear;
  }
  if (stats) *stats = {static_cast<int>(n), carried_decisions};
  // Merge runs of containing intervals (wrapping).
  size_t first = 0;
  while (first < n && in[first]) ++first;
  if (first == n) {
    ThetaInterval all{-M_PI, M_PI, 0.0, 0.0};
    for (size_t k = 0; k < n; ++k) {
      if (margin[k] > all.margin) all.margin = margin[k], all.best_theta = mids[k];
    }
    return {all};
  }
  bool open = false;
  for (size_t step = 1; step <= n; ++step) {
    const size_t k = (first + step) % n;
    if (!in[k]) {
      open = false;
      continue;
    }
    if (!open) out.push_back({cuts[k], cuts[k], -1.0, mids[k]});
    open = true;
    ThetaInterval& cur = out.back();
    double hi = k + 1 < n ? cuts[k + 1] : cuts[0] + 2 * M_PI;
    while (hi < cur.lo) hi += 2 * M_PI;
    cur.hi = hi;
    if (margin[k] > cur.margin) cur.margin = margin[k], cur.best_theta = mids[k];
  }
  return out;
}

}  // namespace visco::planning

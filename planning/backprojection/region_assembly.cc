// Region assembly: the sweep's good pieces chained into rings (exact decisions at every vertex), holes placed in
// their outer rings, and the rings rotated back to the world frame with their edges' provenance.

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "planning/backprojection/plane_sweep.h"

namespace visco::planning::internal {

namespace {

// Where p lies relative to a counter-clockwise ring, exactly, by its winding number. The sweep's rings may touch
// themselves at a vertex (weakly simple, where CGAL's Polygon_2::bounded_side requires a simple polygon).
CGAL::Bounded_side RingSide(const std::vector<P2>& ring, const P2& p) {
  int winding = 0;
  for (size_t i = 0; i < ring.size(); ++i) {
    const P2& a = ring[i];
    const P2& b = ring[(i + 1) % ring.size()];
    const CGAL::Orientation o = CGAL::orientation(a, b, p);
    if (o == CGAL::COLLINEAR && CGAL::collinear_are_ordered_along_line(a, p, b)) return CGAL::ON_BOUNDARY;
    const bool a_below = CGAL::compare_y(a, p) != CGAL::LARGER;
    const bool b_below = CGAL::compare_y(b, p) != CGAL::LARGER;
    if (a_below && !b_below && o == CGAL::LEFT_TURN) ++winding;   // upward, p on its left
    if (!a_below && b_below && o == CGAL::RIGHT_TURN) --winding;  // downward, p on its right
  }
  return winding != 0 ? CGAL::ON_BOUNDED_SIDE : CGAL::ON_UNBOUNDED_SIDE;
}
}  // namespace

std::vector<ExactRing> Sweep::Assemble() const {
  // Pieces are directed with the region on their left. At a vertex, a ring leaves by the first piece clockwise from
  // the reverse of the arriving one (the sharpest left turn), so rings that touch at a vertex stay separate. All
  // decisions are exact; a chain that does not close is an inconsistency of the sweep, never a smaller region.
  std::map<P2, std::vector<int>, LessYX> starts;
  for (size_t i = 0; i < pieces_.size(); ++i) starts[pieces_[i].a].push_back(static_cast<int>(i));
  std::vector<char> used(pieces_.size(), 0);
  std::vector<ExactRing> rings;
  auto fail = [&](const char* what, const P2& at) {
    const Vector2d w = rot_.InvertExact(at);
    throw std::logic_error(std::string("backprojection: ") + what + " at (" + std::to_string(w.x()) + ", " +
                           std::to_string(w.y()) + ") (a bug: please report the scene and θ)");
  };
  for (size_t i0 = 0; i0 < pieces_.size(); ++i0) {
    if (used[i0]) continue;
    std::vector<int> ring;
    int cur = static_cast<int>(i0);
    while (true) {
      used[cur] = 1;
      ring.push_back(cur);
      const Piece& pc = pieces_[cur];
      auto it = starts.find(pc.b);
      if (it == starts.end()) fail("open boundary chain", pc.b);
      const V2 back = pc.a - pc.b;
      int next = -1;
      // The pairing of arriving and leaving pieces is decided among all pieces at the vertex (in and out alternate
      // around it when the labels are consistent), so it is a bijection; meeting a used piece is an inconsistency.
      for (int cand : it->second) {
        const V2 d = pieces_[cand].b - pieces_[cand].a;
        if (next < 0 || ClockwiseBefore(back, d, pieces_[next].b - pieces_[next].a)) next = cand;
      }
      if (next == static_cast<int>(i0)) break;
      if (used[next]) fail("boundary chains meet inconsistently", pc.b);
      cur = next;
    }
    // Merge collinear consecutive pieces with the same provenance.
    ExactRing r;
    for (int idx : ring) {
      const Piece& pc = pieces_[idx];
      if (!r.vertices.empty() && r.edges.back() == std::make_pair(pc.kind, pc.name) &&
          CGAL::orientation(r.vertices.back(), pc.a, pc.b) == CGAL::COLLINEAR) {
        continue;  // extends the previous edge: its start stays
      }
      r.vertices.push_back(pc.a);
      r.edges.emplace_back(pc.kind, pc.name);
    }
    if (r.vertices.size() >= 2 && r.edges.back() == r.edges.front() &&
        CGAL::orientation(r.vertices.back(), r.vertices.front(), r.vertices[1]) == CGAL::COLLINEAR) {
      r.vertices.erase(r.vertices.begin());
      r.edges.erase(r.edges.begin());
    }
    if (r.vertices.size() < 3) continue;
    FT a2 = 0;
    for (size_t i = 0; i < r.vertices.size(); ++i) {
      const P2& p = r.vertices[i];
      const P2& q = r.vertices[(i + 1) % r.vertices.size()];
      a2 += p.x() * q.y() - p.y() * q.x();
    }
    r.area2 = a2;
    if (CGAL::sign(a2) == CGAL::ZERO) continue;
    rings.push_back(std::move(r));
  }
  return rings;
}

Region Sweep::ToRegion(const std::vector<ExactRing>& rings) const {
  Region region;
  FT total = 0;
  std::vector<const ExactRing*> outers, holes;
  for (const auto& r : rings) {
    total += r.area2;
    (CGAL::sign(r.area2) == CGAL::POSITIVE ? outers : holes).push_back(&r);
  }
  region.area = CGAL::to_double(total / (2 * rot_.Scale2()));
  std::map<int, const Source*> static_lines;  // a static edge's name -> the segment it comes from (RegionEdge::line)
  for (const Source& src : sources_) static_lines.emplace(src.name, &src);
  auto convert = [&](const ExactRing& r) {
    RegionRing out;
    for (size_t i = 0; i < r.vertices.size(); ++i) {
      out.vertices.push_back(rot_.InvertExact(r.vertices[i]) + Vector2d::Zero());  // + 0: no negative zeros
      RegionEdge edge{r.edges[i].first, names_[r.edges[i].second], Vector2d::Zero(), {}};
      if (const auto it = free_sources_.find(r.edges[i].second); it != free_sources_.end()) {
        edge.source = rot_.InvertExact(it->second.point) + Vector2d::Zero();
        edge.sign = it->second.sign;
      } else if (const auto st = static_lines.find(r.edges[i].second); st != static_lines.end()) {
        edge.line = WorldLine(*st->second);
      }
      out.edges.push_back(std::move(edge));
    }
    return out;
  };
  // Deterministic order: outer rings by their lowest-leftmost vertex in the sweep frame.
  auto lowest = [](const ExactRing* r) { return *std::min_element(r->vertices.begin(), r->vertices.end(), LessYX()); };
  std::sort(outers.begin(), outers.end(),
            [&](const ExactRing* a, const ExactRing* b) { return LessYX()(lowest(a), lowest(b)); });
  for (const ExactRing* o : outers) region.polygons.push_back({convert(*o), {}});
  for (const ExactRing* h : holes) {
    // The smallest outer ring that contains the hole. Rings do not cross, so any point of the hole's boundary that
    // is not on an outer ring decides, exactly: the midpoints of its edges are tried in turn.
    int best = -1;
    for (size_t e = 0; e < h->vertices.size() && best < 0; ++e) {
      const P2 mid = CGAL::midpoint(h->vertices[e], h->vertices[(e + 1) % h->vertices.size()]);
      bool on_some_boundary = false;
      for (size_t i = 0; i < outers.size(); ++i) {
        const auto side = RingSide(outers[i]->vertices, mid);
        if (side == CGAL::ON_BOUNDARY) on_some_boundary = true;
        if (side != CGAL::ON_BOUNDED_SIDE) continue;
        if (best < 0 || CGAL::abs(outers[i]->area2) < CGAL::abs(outers[best]->area2)) best = static_cast<int>(i);
      }
      if (on_some_boundary) best = -1;  // try another edge: this midpoint cannot tell touching from inside
    }
    if (best < 0) {
      const Vector2d w = rot_.InvertExact(h->vertices[0]);
      throw std::logic_error("backprojection: a hole at (" + std::to_string(w.x()) + ", " + std::to_string(w.y()) +
                             ") lies in no outer ring (a bug: please report the scene and θ)");
    }
    region.polygons[best].holes.push_back(convert(*h));
  }
  return region;
}

}  // namespace visco::planning::internal

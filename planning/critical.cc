#include "planning/critical.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <deque>
#include <exception>
#include <initializer_list>
#include <mutex>
#include <set>
#include <thread>
#include <tuple>
#include <utility>

#include "planning/geometry.h"

namespace visco::planning {
namespace {

using Eigen::Vector2d;

enum class SegKind : std::uint8_t { kObstacle, kGoal, kBounds, kRay, kStart };

struct Seg {
  Vector2d a, b;
  std::string ref;
  SegKind kind;
};

struct Pt {
  Vector2d p;
  std::string ref;
  bool start = false;  // a vertex of R or a crossing with one of R's edges
  bool ray = false;    // only CVC rays make it (CandidateScope): a ray's end or cut, or a crossing with a ray
};

double Cross(const Vector2d& u, const Vector2d& v) { return u.x() * v.y() - u.y() * v.x(); }

// A ring's refs, filled in where the polygon has none.
std::string VertexRef(const NamedPolygon& poly, size_t k, const std::string& prefix) {
  if (k < poly.vertex_refs.size() && !poly.vertex_refs[k].empty()) return poly.vertex_refs[k];
  return prefix + ".v[" + std::to_string(k) + "]";
}
std::string EdgeRef(const NamedPolygon& poly, size_t k, const std::string& prefix) {
  if (k < poly.edge_refs.size() && !poly.edge_refs[k].empty()) return poly.edge_refs[k];
  return prefix + ".e[" + std::to_string(k) + "]";
}

// A uniform grid over the static arrangement. Each cell lists the segments (and obstacle pieces) that come within
// `pad` of it, so a query looks at the few segments near a segment, a circle or a point instead of all of them. Every
// query visits a superset of the cells within its pad of the query shape; the callers then run the same arithmetic
// as a scan over all segments would, on fewer segments, and get the same result (tested against the scan).
class SegmentGrid {
 public:
  void Build(const std::vector<Seg>& segs, const Eigen::AlignedBox2d& extent, double pad) {
    pad_ = pad;
    Eigen::AlignedBox2d box = extent;
    for (const auto& s : segs) {
      box.extend(s.a);
      box.extend(s.b);
    }
    lo_ = box.min() - Vector2d::Constant(2 * pad);
    const Vector2d size = box.max() + Vector2d::Constant(2 * pad) - lo_;
    // About one segment per cell on each axis: a segment crosses O(√n) cells.
    const int side = std::clamp(static_cast<int>(std::ceil(std::sqrt(static_cast<double>(segs.size())))), 1, 1024);
    nx_ = ny_ = side;
    cell_ = {size.x() / nx_, size.y() / ny_};
    cells_.assign(static_cast<size_t>(nx_) * ny_, {});
    for (size_t k = 0; k < segs.size(); ++k) {
      ForCellsNearSegment(segs[k].a, segs[k].b, pad_, [&](size_t c) {
        cells_[c].push_back(static_cast<int>(k));
        return true;
      });
    }
    mark_.assign(segs.size(), 0);
  }

  // The pieces whose bounding boxes overlap each cell (for point-in-CB tests).
  void AddBoxes(const std::vector<Eigen::AlignedBox2d>& boxes) {
    piece_cells_.assign(cells_.size(), {});
    for (size_t k = 0; k < boxes.size(); ++k) {
      if (boxes[k].isEmpty()) continue;
      const int i0 = Column(boxes[k].min().x() - pad_), i1 = Column(boxes[k].max().x() + pad_);
      const int j0 = Row(boxes[k].min().y() - pad_), j1 = Row(boxes[k].max().y() + pad_);
      for (int i = i0; i <= i1; ++i)
        for (int j = j0; j <= j1; ++j) piece_cells_[Cell(i, j)].push_back(static_cast<int>(k));
    }
  }

  // Calls f(k) once for every segment k within `pad` of segment ab (and some more), roughly in order from a to b;
  // f returns false to stop.
  template <typename F>
  void ForNearSegment(const Vector2d& a, const Vector2d& b, F&& f) const {
    Begin();
    ForCellsNearSegment(a, b, pad_, [&](size_t c) {
      for (int k : cells_[c]) {
        if (mark_[k] == stamp_) continue;
        mark_[k] = stamp_;
        if (!f(k)) return false;
      }
      return true;
    });
  }

  // Segments within `pad` of the circle (and some more), each once, in no particular order.
  const std::vector<int>& NearCircle(const Vector2d& c, double r) const {
    Begin();
    // sqrt(r² − dx²) loses about √ε·r near the circle's sides: widen the band by far more than that.
    const double p = pad_ + 1e-6 * r;
    const int i0 = Column(c.x() - r - p), i1 = Column(c.x() + r + p);
    for (int i = i0; i <= i1; ++i) {
      const double x0 = std::max(lo_.x() + i * cell_.x() - p, c.x() - r);
      const double x1 = std::min(lo_.x() + (i + 1) * cell_.x() + p, c.x() + r);
      if (x0 > x1) continue;
      auto h = [&](double x) { return std::sqrt(std::max(0.0, r * r - (x - c.x()) * (x - c.x()))); };
      const bool top = x0 <= c.x() && c.x() <= x1;
      const double near_x = std::abs(x0 - c.x()) < std::abs(x1 - c.x()) ? x0 : x1;
      const double far_x = near_x == x0 ? x1 : x0;
      const double hmax = top ? r : h(near_x), hmin = h(far_x);
      for (double sign : {1.0, -1.0}) {
        const double y0 = sign > 0 ? c.y() + hmin : c.y() - hmax, y1 = sign > 0 ? c.y() + hmax : c.y() - hmin;
        const int j0 = Row(y0 - p), j1 = Row(y1 + p);
        for (int j = j0; j <= j1; ++j) Collect(Cell(i, j));
      }
    }
    return found_;
  }

  // Segments and pieces within `pad` of point p (and some more; one cell: no repeats, any order).
  const std::vector<int>& NearPoint(const Vector2d& p) const { return cells_[Cell(Column(p.x()), Row(p.y()))]; }
  const std::vector<int>& PiecesAt(const Vector2d& p) const {
    static const std::vector<int> none;
    if (piece_cells_.empty()) return none;
    return piece_cells_[Cell(Column(p.x()), Row(p.y()))];
  }

 private:
  // Clamped in floating point first: far-away coordinates (a huge circle's extent, NaN) never overflow the cast.
  static int Index(double x, double lo, double cell, int n) {
    const double i = std::floor((x - lo) / cell);
    return i >= 0 ? (i < n ? static_cast<int>(i) : n - 1) : 0;
  }
  int Column(double x) const { return Index(x, lo_.x(), cell_.x(), nx_); }
  int Row(double y) const { return Index(y, lo_.y(), cell_.y(), ny_); }
  size_t Cell(int i, int j) const { return static_cast<size_t>(j) * nx_ + i; }

  // Calls f(cell) for every cell within `pad` of segment ab, strip by strip along the segment's longer axis from a
  // towards b (within a strip, from a's side too); f returns false to stop. A strip's cells are those of the
  // segment's range on the other axis over the strip's padded extent, widened by pad.
  template <typename F>
  void ForCellsNearSegment(const Vector2d& a, const Vector2d& b, double pad, F&& f) const {
    const bool along_x = std::abs(b.x() - a.x()) >= std::abs(b.y() - a.y());
    const int u = along_x ? 0 : 1, v = 1 - u;  // the strips' axis and the other
    const double umin = std::min(a[u], b[u]), umax = std::max(a[u], b[u]);
    const double vmin = std::min(a[v], b[v]), vmax = std::max(a[v], b[v]);
    auto index = [&](int axis, double x) { return axis == 0 ? Column(x) : Row(x); };
    const int s0 = index(u, umin - pad), s1 = index(u, umax + pad);
    const double du = b[u] - a[u], dv = b[v] - a[v];
    const bool forward_u = du >= 0, forward_v = dv >= 0;
    for (int step = 0; step <= s1 - s0; ++step) {
      const int i = forward_u ? s0 + step : s1 - step;
      const double x0 = std::clamp(lo_[u] + i * cell_[u] - pad, umin, umax);
      const double x1 = std::clamp(lo_[u] + (i + 1) * cell_[u] + pad, umin, umax);
      double y0 = vmin, y1 = vmax;
      if (du != 0) {
        const double ya = a[v] + (x0 - a[u]) * (dv / du), yb = a[v] + (x1 - a[u]) * (dv / du);
        y0 = std::clamp(std::min(ya, yb), vmin, vmax);
        y1 = std::clamp(std::max(ya, yb), vmin, vmax);
      }
      const int j0 = index(v, y0 - pad), j1 = index(v, y1 + pad);
      for (int k = 0; k <= j1 - j0; ++k) {
        const int j = forward_v ? j0 + k : j1 - k;
        if (!f(along_x ? Cell(i, j) : Cell(j, i))) return;
      }
    }
  }

  void Begin() const {
    found_.clear();
    if (++stamp_ == 0) {
      std::fill(mark_.begin(), mark_.end(), 0);
      stamp_ = 1;
    }
  }
  void Collect(size_t c) const {
    for (int k : cells_[c]) {
      if (mark_[k] == stamp_) continue;
      mark_[k] = stamp_;
      found_.push_back(k);
    }
  }

  double pad_ = 0;
  Vector2d lo_ = Vector2d::Zero(), cell_ = Vector2d::Ones();
  int nx_ = 1, ny_ = 1;
  std::vector<std::vector<int>> cells_, piece_cells_;
  mutable std::vector<std::uint32_t> mark_;
  mutable std::uint32_t stamp_ = 0;
  mutable std::vector<int> found_;
};

// The obstacle region CB as rings with their holes (inside CB: inside a solid ring and none of its holes).
struct ObstacleRegion {
  struct Piece {
    std::vector<Vector2d> outer;
    std::vector<std::vector<Vector2d>> holes;
    Eigen::AlignedBox2d box;
  };
  std::vector<Piece> pieces;
  std::vector<Seg> edges;
  double tolerance = 1e-12;
  bool indexed = false;  // queries through `grid` (else scans of every edge: the reference)
  SegmentGrid grid;

  void Index(const Eigen::AlignedBox2d& extent, double pad) {
    grid.Build(edges, extent, pad);
    std::vector<Eigen::AlignedBox2d> boxes;
    for (const auto& piece : pieces) boxes.push_back(piece.box);
    grid.AddBoxes(boxes);
    indexed = true;
  }

  static bool InsideRing(const std::vector<Vector2d>& ring, const Vector2d& p) {
    bool in = false;
    for (size_t i = 0, j = ring.size() - 1; i < ring.size(); j = i++) {
      const Vector2d &a = ring[i], &b = ring[j];
      if ((a.y() > p.y()) != (b.y() > p.y()) && p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) {
        in = !in;
      }
    }
    return in;
  }

  // Strictly inside CB, by more than the tolerance (points on the boundary are not).
  bool StrictlyInside(const Vector2d& p) const {
    auto near_edge = [&](const Seg& e) {
      const Vector2d d = e.b - e.a;
      const double t = std::clamp((p - e.a).dot(d) / d.squaredNorm(), 0.0, 1.0);
      return (e.a + t * d - p).norm() <= tolerance;
    };
    auto in_piece = [&](const Piece& piece) {
      if (!piece.box.contains(p) || !InsideRing(piece.outer, p)) return false;
      bool in_hole = false;
      for (const auto& h : piece.holes) in_hole = in_hole || InsideRing(h, p);
      return !in_hole;
    };
    if (indexed) {
      for (int k : grid.NearPoint(p))
        if (near_edge(edges[k])) return false;
      for (int k : grid.PiecesAt(p))
        if (in_piece(pieces[k])) return true;
      return false;
    }
    for (const auto& e : edges)
      if (near_edge(e)) return false;
    for (const auto& piece : pieces)
      if (in_piece(piece)) return true;
    return false;
  }

  // Whether the open segment (p, q) avoids CB's interior. First a certificate that it does not: it crosses an edge of
  // CB transversally (by more than 1e-6 rad) at a point inside both (by 1e-8 of their lengths), so one side of that
  // edge, inside its ring and so inside CB, is on the segment. Found near p first, that ends most queries early.
  // Otherwise the segment is split where it meets CB's edges and the middle of every piece is tested (a segment
  // along an edge sees along it). Conservative: doubtful cases see.
  bool Sees(const Vector2d& p, const Vector2d& q) const {
    const Vector2d d = q - p;
    const double dn = d.norm();
    std::vector<double> cuts = {0.0, 1.0};
    // One edge: false when it certifies the block; else its cut, if it meets the segment.
    auto visit = [&](const Seg& e) {
      const Vector2d f = e.b - e.a;
      const double den = Cross(d, f);
      if (std::abs(den) < 1e-300) return true;
      const double t = Cross(e.a - p, f) / den;
      const double u = Cross(e.a - p, d) / den;
      if (std::abs(den) >= 1e-6 * dn * f.norm() && t > 1e-8 && t < 1 - 1e-8 && u > 1e-8 && u < 1 - 1e-8) return false;
      if (t > 0 && t < 1 && u >= -1e-12 && u <= 1 + 1e-12) cuts.push_back(t);
      return true;
    };
    bool blocked = false;
    if (indexed) {
      grid.ForNearSegment(p, q, [&](int k) {
        blocked = !visit(edges[k]);
        return !blocked;
      });
    } else {
      for (const auto& e : edges) {
        blocked = !visit(e);
        if (blocked) break;
      }
    }
    if (blocked) return false;
    std::sort(cuts.begin(), cuts.end());
    for (size_t i = 0; i + 1 < cuts.size(); ++i) {
      if (cuts[i + 1] - cuts[i] < 1e-12) continue;
      if (StrictlyInside(p + 0.5 * (cuts[i] + cuts[i + 1]) * d)) return false;
    }
    return true;
  }
};

// The crossing of two segments, if they meet in one point (collinear overlaps add nothing new: their ends are
// points already).
bool Crossing(const Seg& s, const Seg& t, Vector2d* out) {
  const Vector2d d = s.b - s.a, f = t.b - t.a;
  const double den = Cross(d, f);
  const double scale = d.norm() * f.norm();
  if (std::abs(den) <= 1e-14 * scale) return false;
  const double u = Cross(t.a - s.a, f) / den;
  const double v = Cross(t.a - s.a, d) / den;
  if (u < -1e-12 || u > 1 + 1e-12 || v < -1e-12 || v > 1 + 1e-12) return false;
  *out = s.a + u * d;
  return true;
}

static_assert(sizeof(CandidateEntry) == 40, "a candidate's size is what bounds the listing's memory");

// How many refs and sources a compact candidate has, and their indices (CandidateEntry::Form).
size_t RefCount(const CandidateEntry& e) {
  switch (e.form) {
    case CandidateEntry::kRefs:
      return static_cast<size_t>(std::count_if(std::begin(e.ids), std::end(e.ids),
                                               [](std::uint32_t id) { return id != CandidateEntry::kNoIndex; }));
    case CandidateEntry::kSlidingFeature:
      return 1;
    case CandidateEntry::kThroughPoint:
      return 2;
    case CandidateEntry::kFreeVertex:
      return 3;
  }
  return 0;
}
size_t SourceCount(const CandidateEntry& e) {
  return e.form == CandidateEntry::kThroughPoint ? 1 : e.form == CandidateEntry::kFreeVertex ? 2 : 0;
}
std::uint32_t SourceId(const CandidateEntry& e, size_t k) {
  return e.form == CandidateEntry::kThroughPoint ? e.ids[e.flags & 1] : e.ids[k];
}
std::int8_t SourceSign(const CandidateEntry& e, size_t k) {
  if (e.form == CandidateEntry::kThroughPoint) return (e.flags & 2) != 0 ? -1 : 1;
  return k == 0 ? 1 : -1;
}

// A compact candidate as a CriticalOrientation (its refs only `with_refs`), into `out` (whose vectors keep their
// capacity).
void Materialize(const CandidateEntry& e, const std::vector<std::string>& strings, const std::vector<Vector2d>& points,
                 CriticalOrientation& out, bool with_refs) {
  out.theta = e.theta;
  out.kind = e.kind;
  out.sliding = e.sliding;
  out.refs.clear();
  if (with_refs) {
    for (size_t k = 0; k < RefCount(e); ++k) out.refs.push_back(strings[e.ids[k]]);
  }
  out.sources.clear();
  out.source_signs.clear();
  for (size_t k = 0; k < SourceCount(e); ++k) {
    out.sources.push_back(points[SourceId(e, k)]);
    out.source_signs.push_back(SourceSign(e, k));
  }
  out.feature.clear();
  out.point.clear();
  switch (e.form) {
    case CandidateEntry::kRefs:
      break;
    case CandidateEntry::kSlidingFeature:
      for (size_t k = 1; k < 3; ++k)
        if (e.ids[k] != CandidateEntry::kNoIndex) out.feature.push_back(points[e.ids[k]]);
      break;
    case CandidateEntry::kThroughPoint:
      if ((e.flags & 4) != 0) {
        out.feature = {points[e.ids[0]], points[e.ids[1]]};
      } else {
        out.point.push_back(points[e.ids[1 - (e.flags & 1)]]);
      }
      break;
    case CandidateEntry::kFreeVertex:
      out.point.emplace_back(e.point[0], e.point[1]);
      break;
  }
}

}  // namespace

// What ListStaticCandidates lists (critical.h), in the numbering of a generator of the C-obstacles and bounds alone:
// its points (sorted by x) and segments, and the events of its pairs of points, whose ids are those points and
// segments (a segment k as points.size() + k, like the generator's SegRef).
class StaticCandidates {
 public:
  // What they were listed from: a problem that differs lists its candidates itself.
  std::vector<NamedPolygon> obstacles;
  Vector2d bounds_min = Vector2d::Zero(), bounds_max = Vector2d::Zero();
  double velocity_cone = 0.0, friction_cone = 0.0;
  struct Point {
    Vector2d p;
    std::string ref;
  };
  struct Segment {
    Vector2d a, b;
    std::string ref;
  };
  std::vector<Point> points;
  std::vector<Segment> segments;
  std::deque<CandidateEntry> entries;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> visible_pairs;  // the pairs that see each other
  std::set<std::pair<size_t, size_t>> along_static;                    // the generator's PairsAlongStaticSegments

  bool FitsProblem(const BackprojectionProblem& pr) const {
    auto same = [](const NamedPolygon& x, const NamedPolygon& y) {
      return x.vertices == y.vertices && x.vertex_refs == y.vertex_refs && x.edge_refs == y.edge_refs &&
             x.hole == y.hole;
    };
    return pr.bounds_min == bounds_min && pr.bounds_max == bounds_max && pr.velocity_cone == velocity_cone &&
           pr.friction_cone == friction_cone && pr.obstacles.size() == obstacles.size() &&
           std::equal(obstacles.begin(), obstacles.end(), pr.obstacles.begin(), same);
  }
};

namespace {

class CandidateGenerator {
 public:
  CandidateGenerator(const BackprojectionProblem& pr, const NamedPolygon* start, CandidateSearch search,
                     const std::atomic<bool>* stop = nullptr, const CandidateScope* scope = nullptr,
                     const StaticCandidates* statics = nullptr)
      : pr_(pr), stop_(stop) {
    eps_ = std::max(pr.velocity_cone, 1e-9);
    phi_ = pr.friction_cone;
    with_start_ = start != nullptr;
    Collect(start);
    Scope(scope);
    if (search == CandidateSearch::kIndexed) {
      const Eigen::AlignedBox2d extent(pr.bounds_min, pr.bounds_max);
      const double pad = 1e-9 * (pr.bounds_max - pr.bounds_min).norm();
      cb_.Index(extent, pad);
      seg_grid_.Build(segs_, extent, pad);
      indexed_ = true;
      grid_pad_ = pad;
      for (size_t k = 0; k < segs_.size(); ++k)
        if (segs_[k].kind == SegKind::kStart) start_segs_.Add(k, segs_[k]);
      if (statics != nullptr && statics->FitsProblem(pr)) UseStatics(*statics);
    }
  }

  // The static candidates of this problem's C-obstacles and bounds (ListStaticCandidates): the events of the pairs of
  // points, unsorted, in this generator's numbering.
  std::shared_ptr<StaticCandidates> ListStatics(int threads) {
    MakeTables();
    along_static_ = PairsAlongStaticSegments();
    record_visible_ = true;
    if (threads > 1) {
      PairEventsInParallel(threads);
    } else {
      VisibilityEvents(0, points_.size());
      FreeVertexEvents(0, points_.size());
    }
    auto statics = std::make_shared<StaticCandidates>();
    statics->obstacles = pr_.obstacles;
    statics->bounds_min = pr_.bounds_min;
    statics->bounds_max = pr_.bounds_max;
    statics->velocity_cone = pr_.velocity_cone;
    statics->friction_cone = pr_.friction_cone;
    for (const auto& p : points_) statics->points.push_back({p.p, p.ref});
    for (const auto& sg : segs_) statics->segments.push_back({sg.a, sg.b, sg.ref});
    statics->entries = std::move(entries_);
    statics->visible_pairs = std::move(visible_log_);
    statics->along_static = std::move(along_static_);
    return statics;
  }

  // The candidates as a compact list (reference = false) or, as before CandidateList, as CriticalOrientations in
  // `reference_out` (the tests compare the two).
  CandidateList Run(CriticalCounts* counts, bool r_only = false,
                    std::vector<CriticalOrientation>* reference_out = nullptr, int threads = 1) {
    r_only_ = r_only;
    reference_ = reference_out != nullptr;
    MakeTables();
    if (!r_only) {
      SlidingEvents();
      RayEvents();
    }
    along_static_ = PairsAlongStaticSegments();
    if (r_only || reference_) statics_ = nullptr;
    if (statics_ != nullptr) AlongDiffers();
    if (threads > 1 && !reference_) {
      PairEventsInParallel(threads);
    } else {
      VisibilityEvents(0, points_.size());
      FreeVertexEvents(0, points_.size());
    }
    if (statics_ != nullptr) AppendStatics();
    if (reference_) {
      SortReference();
      if (counts) Count(counts, reference_out_.size(), [&](size_t i) { return reference_out_[i].kind; });
      *reference_out = std::move(reference_out_);
      return {};
    }
    auto entries = std::move(entries_);
    SortAndDeduplicate(entries, strings_, coords_);
    if (counts) Count(counts, entries.size(), [&](size_t i) { return entries[i].kind; });
    std::vector<Vector2d> ray_points;
    for (const auto& p : points_)
      if (p.ray) ray_points.push_back(p.p);  // points_ is sorted by x (Collect)
    CandidateList list(std::move(entries), std::move(strings_), std::move(coords_), std::move(ray_points));
    list.set_scoped(scoped_);
    return list;
  }

 private:
  // Which points' events are listed (CandidateScope): every point but the ray points the scope does not name.
  void Scope(const CandidateScope* scope) {
    listed_.assign(points_.size(), 1);
    if (scope == nullptr || scope->all) return;
    const auto ray_points = std::count_if(points_.begin(), points_.end(), [](const Pt& p) { return p.ray; });
    if (static_cast<double>(ray_points) * static_cast<double>(points_.size()) < scope->all_below_pairs) return;
    scoped_ = true;
    std::vector<Vector2d> wanted = scope->ray_points;
    std::sort(wanted.begin(), wanted.end(), [](const Vector2d& a, const Vector2d& b) { return a.x() < b.x(); });
    const double tol = 1e-9 * (pr_.bounds_max - pr_.bounds_min).norm();  // the walk's match of a source
    for (size_t i = 0; i < points_.size(); ++i) {
      if (!points_[i].ray) continue;
      const Vector2d& p = points_[i].p;
      bool named = false;
      for (auto it = std::lower_bound(wanted.begin(), wanted.end(), p.x() - tol,
                                      [](const Vector2d&w, double x) { return w.x() < x; });
           it != wanted.end() && it->x() <= p.x() + tol && !named; ++it) {
        named = (*it - p).norm() <= tol;
      }
      listed_[i] = named ? 1 : 0;
    }
  }

  // Which points and segments are the static candidates' (the same position and ref, and not the start region's), so
  // that the events of a pair of them are taken from there. The events of a pair whose order differs here are listed
  // again (its refs would come in the other order), and so are those of the other points and segments.
  void UseStatics(const StaticCandidates& statics) {
    statics_ = &statics;
    const size_t n = statics.points.size();
    static_of_.assign(points_.size(), CandidateEntry::kNoIndex);
    point_of_static_.assign(n, CandidateEntry::kNoIndex);
    auto by_x = [](const StaticCandidates::Point& p, double x) { return p.p.x() < x; };
    for (size_t i = 0; i < points_.size(); ++i) {
      if (points_[i].start || points_[i].ray) continue;
      for (auto it = std::lower_bound(statics.points.begin(), statics.points.end(), points_[i].p.x(), by_x);
           it != statics.points.end() && it->p.x() == points_[i].p.x(); ++it) {
        const size_t s = static_cast<size_t>(it - statics.points.begin());
        if (it->p == points_[i].p && it->ref == points_[i].ref && point_of_static_[s] == CandidateEntry::kNoIndex) {
          static_of_[i] = static_cast<std::uint32_t>(s);
          point_of_static_[s] = static_cast<std::uint32_t>(i);
          break;
        }
      }
    }
    // The segments come in the same order (C-obstacles, then bounds), the problem's own among them.
    std::vector<char> static_segment(segs_.size(), 0);
    segment_of_static_.assign(statics.segments.size(), CandidateEntry::kNoIndex);
    size_t k = 0;
    for (size_t s = 0; s < statics.segments.size(); ++s) {
      const auto& sg = statics.segments[s];
      while (k < segs_.size() && !(segs_[k].a == sg.a && segs_[k].b == sg.b && segs_[k].ref == sg.ref)) ++k;
      if (k == segs_.size()) {  // not found in order: no statics
        statics_ = nullptr;
        return;
      }
      static_segment[k] = 1;
      segment_of_static_[s] = static_cast<std::uint32_t>(k++);
    }
    for (size_t k2 = 0; k2 < segs_.size(); ++k2)
      if (static_segment[k2] == 0) own_segs_.Add(k2, segs_[k2]);
  }

  // Both points' pair events are the static candidates' (i < j).
  bool StaticPair(size_t i, size_t j) const {
    return statics_ != nullptr && static_of_[i] != CandidateEntry::kNoIndex &&
           static_of_[j] != CandidateEntry::kNoIndex && static_of_[i] < static_of_[j];
  }

  // The static pairs that lie on one static segment here and not there, or there and not here (a goal or forbidden
  // edge through two C-obstacle points): their free edges' events are listed again.
  void AlongDiffers() {
    for (const auto& [i, j] : along_static_) {
      if (StaticPair(i, j) && statics_->along_static.count({static_of_[i], static_of_[j]}) == 0) {
        along_differs_.insert({i, j});
      }
    }
    for (const auto& [a, b] : statics_->along_static) {
      const auto i = point_of_static_[a], j = point_of_static_[b];
      if (i == CandidateEntry::kNoIndex || j == CandidateEntry::kNoIndex || i > j) continue;
      if (along_static_.count({i, j}) == 0) along_differs_.insert({i, j});
    }
  }

  // The static candidates of the pairs not listed here, in this generator's numbering.
  void AppendStatics() {
    const std::uint32_t n = static_cast<std::uint32_t>(statics_->points.size());
    auto pair_of = [&](std::uint32_t a, std::uint32_t b, size_t* i, size_t* j) {
      const std::uint32_t pa = point_of_static_[a], pb = point_of_static_[b];
      if (pa == CandidateEntry::kNoIndex || pb == CandidateEntry::kNoIndex) return false;
      *i = std::min(pa, pb);
      *j = std::max(pa, pb);
      return StaticPair(*i, *j);
    };
    for (const auto& [a, b] : statics_->visible_pairs) {
      size_t i = 0, j = 0;
      if (pair_of(a, b, &i, &j) && along_differs_.count({i, j}) == 0) ++visible_pairs_;
    }
    for (CandidateEntry e : statics_->entries) {
      size_t i = 0, j = 0;
      if (!pair_of(e.ids[0], e.ids[1], &i, &j)) continue;
      if (e.form == CandidateEntry::kThroughPoint) {
        if (along_differs_.count({i, j}) != 0) continue;
      } else if (e.form == CandidateEntry::kFreeVertex) {
        e.ids[2] = SegRef(segment_of_static_[e.ids[2] - n]);
      } else {
        continue;  // pairs make no other form
      }
      e.ids[0] = point_of_static_[e.ids[0]];
      e.ids[1] = point_of_static_[e.ids[1]];
      CheckStop();
      Push(e);
    }
  }

  void Add(double theta, CriticalKind kind, std::initializer_list<std::uint32_t> refs,
           std::initializer_list<std::uint32_t> sources = {}, std::initializer_list<std::int8_t> signs = {},
           const std::vector<std::uint32_t>& feature = {}, const Vector2d* point = nullptr) {
    if (!std::isfinite(theta)) return;
    if (r_only_ && kind != CriticalKind::kR) return;
    CheckStop();
    CandidateEntry e;
    e.theta = WrapAngle(theta);
    e.kind = kind;
    Fill(e.ids, refs);
    if (refs.size() == 3) {  // a free vertex: sources the first two refs' points (+1, −1), its point
      e.form = CandidateEntry::kFreeVertex;
      e.point[0] = point->x();
      e.point[1] = point->y();
    } else if (sources.size() == 1) {  // a free edge through a point: the source and the point are the two refs'
      e.form = CandidateEntry::kThroughPoint;
      e.flags = static_cast<std::uint8_t>((*sources.begin() == *(refs.begin() + 1) ? 1 : 0) |
                                          (*signs.begin() < 0 ? 2 : 0) | (feature.empty() ? 0 : 4));
    }
    Push(e);
  }

  void AddSliding(double theta, std::uint32_t ref, std::initializer_list<std::uint32_t> feature, SlidingCause cause) {
    if (!std::isfinite(theta) || r_only_) return;
    CheckStop();
    CandidateEntry e;
    e.theta = WrapAngle(theta);
    e.kind = CriticalKind::kSliding;
    e.form = CandidateEntry::kSlidingFeature;
    e.ids[0] = ref;
    size_t k = 1;
    for (auto id : feature) e.ids[k++] = id;
    e.sliding = cause;
    Push(e);
  }

  template <size_t N>
  static void Fill(std::uint32_t (&to)[N], std::initializer_list<std::uint32_t> ids) {
    size_t k = 0;
    for (auto id : ids) to[k++] = id;
  }

  // The tables candidates point into: every point's ref, then every segment's, then every CB vertex's; every point's
  // position (positions the events add, a sliding feature's or a free vertex's, are appended).
  void MakeTables() {
    for (const auto& p : points_) {
      strings_.push_back(p.ref);
      coords_.push_back(p.p);
    }
    for (const auto& s : segs_) strings_.push_back(s.ref);
    for (const auto& r : ring_vertex_refs_) strings_.push_back(r);
  }
  std::uint32_t PointId(size_t i) const { return static_cast<std::uint32_t>(i); }
  std::uint32_t SegRef(size_t k) const { return static_cast<std::uint32_t>(points_.size() + k); }
  std::uint32_t RingVertexRef(size_t i) const { return static_cast<std::uint32_t>(points_.size() + segs_.size() + i); }
  std::uint32_t NewPoint(const Vector2d& p) {
    coords_.push_back(p);
    return static_cast<std::uint32_t>(coords_.size() - 1);
  }

  // Stored in a deque while they are generated and sorted (small blocks: neither a doubling of one huge vector nor
  // a copy of it), as CriticalOrientations in the reference.
  void Push(const CandidateEntry& e) {
    ++generated_;
    if (reference_) {
      reference_out_.emplace_back();
      Materialize(e, strings_, coords_, reference_out_.back(), true);
      return;
    }
    entries_.push_back(e);
  }

  // The order and the duplicates of the reference below, on the compact entries: θ, kind, refs (as strings), then
  // the sources' positions ((x, y) order).
  static void SortAndDeduplicate(std::deque<CandidateEntry>& v, const std::vector<std::string>& str,
                                 const std::vector<Vector2d>& pts) {
    // Lexicographic, a shorter list before a longer one it begins.
    auto refs_less = [&](const CandidateEntry& x, const CandidateEntry& y) {
      const size_t nx = RefCount(x), ny = RefCount(y);
      for (size_t k = 0; k < std::min(nx, ny); ++k) {
        const int c = str[x.ids[k]].compare(str[y.ids[k]]);
        if (c != 0) return c < 0;
      }
      return nx < ny;
    };
    auto refs_equal = [&](const CandidateEntry& x, const CandidateEntry& y) {
      const size_t n = RefCount(x);
      if (n != RefCount(y)) return false;
      for (size_t k = 0; k < n; ++k)
        if (x.ids[k] != y.ids[k] && str[x.ids[k]] != str[y.ids[k]]) return false;
      return true;
    };
    auto sources_less = [&](const CandidateEntry& x, const CandidateEntry& y) {
      const size_t nx = SourceCount(x), ny = SourceCount(y);
      for (size_t k = 0; k < std::min(nx, ny); ++k) {
        const Vector2d &a = pts[SourceId(x, k)], &b = pts[SourceId(y, k)];
        if (a.x() < b.x() || (a.x() == b.x() && a.y() < b.y())) return true;
        if (b.x() < a.x() || (a.x() == b.x() && b.y() < a.y())) return false;
      }
      return nx < ny;
    };
    auto sources_equal = [&](const CandidateEntry& x, const CandidateEntry& y) {
      const size_t n = SourceCount(x);
      if (n != SourceCount(y)) return false;
      for (size_t k = 0; k < n; ++k)
        if (pts[SourceId(x, k)] != pts[SourceId(y, k)]) return false;
      return true;
    };
    // A sliding candidate's feature: pieces of one edge (one ref) are candidates at one θ, each with its own piece,
    // and the walk's rule reads the piece. Kept apart and ordered by it, so the list is the same whatever the order
    // it was generated in (the listing of a CandidateScope is a part of the full one's).
    auto feature_of = [&](const CandidateEntry& e) {
      std::array<Vector2d, 2> f = {Vector2d::Zero(), Vector2d::Zero()};
      if (e.form != CandidateEntry::kSlidingFeature) return std::make_pair(0, f);
      int n = 0;
      for (size_t k = 1; k < 3; ++k)
        if (e.ids[k] != CandidateEntry::kNoIndex) f[static_cast<size_t>(n++)] = pts[e.ids[k]];
      return std::make_pair(n, f);
    };
    auto features_less = [&](const CandidateEntry& x, const CandidateEntry& y) {
      const auto [nx, fx] = feature_of(x);
      const auto [ny, fy] = feature_of(y);
      for (size_t k = 0; k < static_cast<size_t>(std::min(nx, ny)); ++k) {
        if (fx[k].x() != fy[k].x()) return fx[k].x() < fy[k].x();
        if (fx[k].y() != fy[k].y()) return fx[k].y() < fy[k].y();
      }
      return nx < ny;
    };
    auto features_equal = [&](const CandidateEntry& x, const CandidateEntry& y) {
      return !features_less(x, y) && !features_less(y, x);
    };
    std::sort(v.begin(), v.end(), [&](const CandidateEntry& x, const CandidateEntry& y) {
      if (x.theta != y.theta) return x.theta < y.theta;
      if (x.kind != y.kind) return x.kind < y.kind;
      if (refs_less(x, y)) return true;
      if (refs_less(y, x)) return false;
      if (sources_less(x, y)) return true;
      if (sources_less(y, x)) return false;
      return features_less(x, y);
    });
    v.erase(std::unique(v.begin(), v.end(),
                        [&](const CandidateEntry& x, const CandidateEntry& y) {
                          return x.theta == y.theta && x.kind == y.kind && refs_equal(x, y) && sources_equal(x, y) &&
                                 features_equal(x, y);
                        }),
            v.end());
    v.shrink_to_fit();
  }

  // The listing before CandidateList (the reference): sorted and deduplicated as CriticalOrientations.
  void SortReference() {
    auto& out = reference_out_;
    const auto points_less = [](const std::vector<Vector2d>& x, const std::vector<Vector2d>& y) {
      return std::lexicographical_compare(
          x.begin(), x.end(), y.begin(), y.end(),
          [](const Vector2d& a, const Vector2d& b) { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
    };
    // A sliding candidate's feature (SortAndDeduplicate says why; the others' follows from their refs).
    const auto feature = [](const CriticalOrientation& c) {
      return c.kind == CriticalKind::kSliding ? c.feature : std::vector<Vector2d>{};
    };
    // Sources break ties (an edge's two ends are both candidates at one orientation), so both searches give one order.
    std::sort(out.begin(), out.end(), [&](const CriticalOrientation& x, const CriticalOrientation& y) {
      const auto kx = std::tie(x.theta, x.kind, x.refs), ky = std::tie(y.theta, y.kind, y.refs);
      if (kx != ky) return kx < ky;
      if (points_less(x.sources, y.sources)) return true;
      if (points_less(y.sources, x.sources)) return false;
      return points_less(feature(x), feature(y));
    });
    out.erase(std::unique(out.begin(), out.end(),
                          [&](const CriticalOrientation& x, const CriticalOrientation& y) {
                            return x.theta == y.theta && x.kind == y.kind && x.refs == y.refs &&
                                   x.sources == y.sources && feature(x) == feature(y);
                          }),
              out.end());
  }

  template <typename KindOf>
  void Count(CriticalCounts* counts, size_t n, KindOf kind_of) const {
    *counts = CriticalCounts{};
    for (size_t i = 0; i < n; ++i) ++counts->by_kind[static_cast<int>(kind_of(i))];
    counts->points = static_cast<std::int64_t>(points_.size());
    counts->segments = static_cast<std::int64_t>(segs_.size());
    counts->visible_pairs = visible_pairs_;
  }

  void Collect(const NamedPolygon* start) {
    // C-obstacles: solid rings with the holes that follow them.
    for (size_t i = 0; i < pr_.obstacles.size(); ++i) {
      const NamedPolygon& poly = pr_.obstacles[i];
      const std::string prefix = "obstacle#" + std::to_string(i);
      if (!poly.hole || cb_.pieces.empty()) cb_.pieces.push_back({});
      auto& piece = cb_.pieces.back();
      if (poly.hole) {
        piece.holes.push_back(poly.vertices);
      } else {
        piece.outer = poly.vertices;
        for (const auto& v : poly.vertices) piece.box.extend(v);
      }
      AddRing(poly, prefix, SegKind::kObstacle, false);
    }
    for (const auto& s : segs_) cb_.edges.push_back(s);
    for (size_t i = 0; i < pr_.goal.size(); ++i)
      AddRing(pr_.goal[i], "goal#" + std::to_string(i), SegKind::kGoal, false);
    const Vector2d lo = pr_.bounds_min, hi = pr_.bounds_max;
    const Vector2d corners[4] = {lo, {hi.x(), lo.y()}, hi, {lo.x(), hi.y()}};
    const char* sides[4] = {"ymin", "xmax", "ymax", "xmin"};
    const char* corner_names[4] = {"bounds.corner[xmin,ymin]", "bounds.corner[xmax,ymin]", "bounds.corner[xmax,ymax]",
                                   "bounds.corner[xmin,ymax]"};
    for (int k = 0; k < 4; ++k) {
      points_.push_back({corners[k], corner_names[k]});
      segs_.push_back({corners[k], corners[(k + 1) % 4], sides[k], SegKind::kBounds});
    }
    for (size_t i = 0; i < pr_.forbidden.size(); ++i) {
      AddRing(pr_.forbidden[i], "forbidden#" + std::to_string(i), SegKind::kBounds, false);
    }
    for (const auto& ray : pr_.rays) {
      for (size_t k = 0; k < ray.segments.size(); ++k) {
        const std::string ref = ray.segments.size() == 1 ? ray.id : ray.id + "#" + std::to_string(k);
        segs_.push_back({ray.segments[k][0], ray.segments[k][1], ray.id, SegKind::kRay});
        points_.push_back({ray.segments[k][0], ref + ".end[0]", false, true});
        points_.push_back({ray.segments[k][1], ref + ".end[1]", false, true});
        // Where the tracking error cuts the ray, a part of it starts to fail: a static point of the regions.
        const auto cuts = TrackingErrorCuts(pr_, ray.segments[k][0], ray.segments[k][1]);
        for (size_t c = 0; c < cuts.size(); ++c) {
          points_.push_back({cuts[c], ref + ".cut[" + std::to_string(c) + "]", false, true});
        }
      }
    }
    if (start) AddRing(*start, "start", SegKind::kStart, true);
    const double size = (hi - lo).norm();
    cb_.tolerance = 1e-12 * size;
    // Every crossing of two edges (bounding boxes first).
    std::vector<Eigen::AlignedBox2d> boxes;
    for (const auto& s : segs_) {
      Eigen::AlignedBox2d b(s.a.cwiseMin(s.b), s.a.cwiseMax(s.b));
      b.extend(b.min() - Vector2d::Constant(1e-9 * size));
      b.extend(b.max() + Vector2d::Constant(1e-9 * size));
      boxes.push_back(b);
    }
    std::vector<size_t> order(segs_.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](size_t x, size_t y) { return boxes[x].min().x() < boxes[y].min().x(); });
    for (size_t oi = 0; oi < order.size(); ++oi) {
      const size_t i = order[oi];
      for (size_t oj = oi + 1; oj < order.size(); ++oj) {
        const size_t j = order[oj];
        if (boxes[j].min().x() > boxes[i].max().x()) break;
        if (!boxes[i].intersects(boxes[j])) continue;
        const Seg &s = segs_[i], &t = segs_[j];
        Vector2d x;
        if (!Crossing(s, t, &x)) continue;
        // Shared ends are points already.
        const double tol = 1e-12 * size;
        if ((x - s.a).norm() <= tol || (x - s.b).norm() <= tol) {
          if ((x - t.a).norm() <= tol || (x - t.b).norm() <= tol) continue;
        }
        const bool with_start = s.kind == SegKind::kStart || t.kind == SegKind::kStart;
        const bool with_ray = s.kind == SegKind::kRay || t.kind == SegKind::kRay;
        points_.push_back({x, "x(" + s.ref + "," + t.ref + ")", with_start, with_ray});
      }
    }
    // Points outside the bounds never matter (nothing of the region is there).
    std::erase_if(points_, [&](const Pt& p) {
      const double tol = 1e-9 * size;
      return p.p.x() < lo.x() - tol || p.p.y() < lo.y() - tol || p.p.x() > hi.x() + tol || p.p.y() > hi.y() + tol;
    });
    // One point per position (a ray's end on an edge is also that edge's crossing with the ray).
    std::stable_sort(points_.begin(), points_.end(), [](const Pt& x, const Pt& y) { return x.p.x() < y.p.x(); });
    std::vector<Pt> unique;
    std::vector<bool> gone(points_.size(), false);
    const double tol = 1e-12 * size;
    for (size_t k = 0; k < points_.size(); ++k) {
      if (gone[k]) continue;
      Pt p = points_[k];
      for (size_t l = k + 1; l < points_.size() && points_[l].p.x() - p.p.x() <= tol; ++l) {
        if (!gone[l] && (points_[l].p - p.p).norm() <= tol) {
          gone[l] = true;
          p.start = p.start || points_[l].start;
          p.ray = p.ray && points_[l].ray;  // a ray point only if nothing but rays makes it
        }
      }
      unique.push_back(std::move(p));
    }
    points_ = std::move(unique);
  }

  void AddRing(const NamedPolygon& poly, const std::string& prefix, SegKind kind, bool start) {
    const size_t n = poly.vertices.size();
    for (size_t k = 0; k < n; ++k) {
      points_.push_back({poly.vertices[k], VertexRef(poly, k, prefix), start});
      segs_.push_back({poly.vertices[k], poly.vertices[(k + 1) % n], EdgeRef(poly, k, prefix), kind});
      if (kind == SegKind::kObstacle) {
        ring_vertices_.push_back({poly.vertices[(k + n - 1) % n], poly.vertices[k], poly.vertices[(k + 1) % n]});
        ring_vertex_refs_.push_back(VertexRef(poly, k, prefix));
      }
    }
  }

  // Sticking/sliding switches and the vertex rule's bisectors (docs/semantics.md "The motion model").
  void SlidingEvents() {
    for (size_t k = 0; k < segs_.size(); ++k) {
      const Seg& s = segs_[k];
      if (s.kind != SegKind::kObstacle) continue;
      const std::uint32_t ref = SegRef(k);
      std::uint32_t ends[2] = {CandidateEntry::kNoIndex, CandidateEntry::kNoIndex};
      if (!r_only_) ends[0] = NewPoint(s.a), ends[1] = NewPoint(s.b);
      const Vector2d d = s.b - s.a;
      const double dir = std::atan2(d.y(), d.x());
      const Vector2d mid = 0.5 * (s.a + s.b);
      const double h = 1e-7 * d.norm();
      for (double normal : {dir + M_PI / 2, dir - M_PI / 2}) {
        // Whether this normal points out of CB (the obstacle on the other side): then a cone edge reaching n ± φ
        // points away from the obstacle, and nothing about contact changes there. Or into it (the other way round).
        const Vector2d nv(std::cos(normal), std::sin(normal));
        const bool in_plus = cb_.StrictlyInside(mid + h * nv), in_minus = cb_.StrictlyInside(mid - h * nv);
        const bool away = !in_plus && in_minus, into = in_plus && !in_minus;
        // θ ± ε_v = ±n ± φ: an edge of the velocity cone parallel or antiparallel to an edge of the friction cone.
        // Where the normal points into CB, sticking needs some velocity within φ of it (docs/semantics.md): the
        // edge's sticking starts or stops where a cone edge reaches the friction cone's far edge (se = sf); where it
        // reaches the near one (se ≠ sf) the cone overlaps the friction cone on both sides, and the edge sticks
        // throughout (with φ = 0 the two coincide: then sticking).
        for (double sf : {-1.0, 1.0})
          for (double se : {-1.0, 1.0}) {
            SlidingCause cause = SlidingCause::kSticking;
            if (away) cause = SlidingCause::kAway;
            if (into && se != sf && phi_ > 1e-9) cause = SlidingCause::kStickingHeld;
            AddSliding(normal + sf * phi_ + se * eps_, ref, {ends[0], ends[1]}, cause);
          }
        // The cone reaches the edge's direction (pushing into it or not): θ ± ε_v = the edge's direction.
        for (double se : {-1.0, 1.0})
          AddSliding(normal + M_PI / 2 + se * eps_, ref, {ends[0], ends[1]}, SlidingCause::kContact);
        // The commanded direction along the edge (the sliding direction of its central velocity flips).
        AddSliding(normal + M_PI / 2, ref, {ends[0], ends[1]}, SlidingCause::kAlong);
      }
    }
    for (size_t i = 0; i < ring_vertices_.size(); ++i) {
      const auto& [prev, v, next] = ring_vertices_[i];
      const Vector2d u1 = (prev - v).normalized(), u2 = (next - v).normalized();
      // Equal tangential components along both edges: v ⊥ (u1 − u2).
      const Vector2d bis = u1 + u2;
      if (bis.norm() < 1e-12) continue;
      const double b = std::atan2(bis.y(), bis.x());
      const double h = 1e-7 * std::min((prev - v).norm(), (next - v).norm());
      const std::uint32_t vertex = NewPoint(v);
      for (double base : {b, b + M_PI}) {
        // Out of CB along the bisector (the other way into it): velocities beside it push into neither edge.
        const Vector2d w(std::cos(base), std::sin(base));
        const bool away = !cb_.StrictlyInside(v + h * w) && cb_.StrictlyInside(v - h * w);
        for (double se : {-1.0, 1.0})
          AddSliding(base + se * eps_, RingVertexRef(i), {vertex},
                     away ? SlidingCause::kVertexAway : SlidingCause::kVertexRule);
      }
    }
  }

  // A free edge parallel to a CVC ray, and the ray's reliability boundary.
  void RayEvents() {
    for (size_t k = 0; k < segs_.size(); ++k) {
      const Seg& s = segs_[k];
      if (s.kind != SegKind::kRay) continue;
      const Vector2d d = s.b - s.a;
      const double rho = std::atan2(d.y(), d.x());
      for (double base : {rho, rho + M_PI})
        for (double se : {-1.0, 1.0}) {
          Add(base + se * eps_, CriticalKind::kVc, {SegRef(k)});
          Add(base + M_PI / 2 + se * eps_, CriticalKind::kVc, {SegRef(k)});
        }
    }
  }

  // Pairs of points (i < j) that lie on one static segment (a C-obstacle, goal or bounds edge): where a free edge runs
  // along the segment, the free edges of that sign of *both* points are parallel to it, and either can change the
  // structure (the one of the point the other's free edge passes through swings across the segment's line there).
  std::set<std::pair<size_t, size_t>> PairsAlongStaticSegments() const {
    std::set<std::pair<size_t, size_t>> pairs;
    const double tol = 1e-9 * (pr_.bounds_max - pr_.bounds_min).norm();
    // points_ is sorted by x (Collect).
    auto by_x = [](const Pt& p, double x) { return p.p.x() < x; };
    for (const auto& sg : segs_) {
      if (sg.kind == SegKind::kRay || sg.kind == SegKind::kStart) continue;  // vc and R events cover those
      const double x0 = std::min(sg.a.x(), sg.b.x()) - tol, x1 = std::max(sg.a.x(), sg.b.x()) + tol;
      std::vector<size_t> on;
      for (auto it = std::lower_bound(points_.begin(), points_.end(), x0, by_x); it != points_.end() && it->p.x() <= x1;
           ++it) {
        if (PointSegmentDistance(it->p, sg.a, sg.b) <= tol) on.push_back(static_cast<size_t>(it - points_.begin()));
      }
      for (size_t u = 0; u < on.size(); ++u)  // `on` is ascending (points_ is walked in order)
        for (size_t v = u + 1; v < on.size(); ++v) pairs.insert({on[u], on[v]});
    }
    return pairs;
  }

  // The events of pairs of points (visibility, then free vertices) on `threads` threads: the first points cut into
  // blocks, each block's events listed by a copy of the generator (the grids' query marks are its own) into a list
  // of its own, and the lists joined in block order, each freed as it is joined. The same entries in the same order
  // as one thread lists them, so the sort that follows gives the same list.
  void PairEventsInParallel(int threads) {
    const size_t n = points_.size();
    const size_t per_kind = std::min<size_t>(n, 64 * static_cast<size_t>(threads));
    // Free-vertex blocks shrink towards the first points: point i pairs with the n − i − 1 after it.
    std::vector<size_t> cuts = {0};
    for (size_t b = 1; b < per_kind; ++b) {
      const double f = static_cast<double>(b) / static_cast<double>(per_kind);
      cuts.push_back(static_cast<size_t>(static_cast<double>(n) * (1.0 - std::sqrt(1.0 - f))));
    }
    cuts.push_back(n);
    cuts.erase(std::unique(cuts.begin(), cuts.end()), cuts.end());
    const size_t blocks = cuts.size() - 1;
    std::vector<std::deque<CandidateEntry>> lists(2 * blocks);
    std::vector<std::int64_t> pairs(static_cast<size_t>(threads), 0);
    std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> visible_logs(static_cast<size_t>(threads));
    std::atomic<size_t> next{0};
    std::atomic<bool> failed{false};
    std::exception_ptr error;
    std::mutex error_mutex;
    auto work = [&](size_t t) {
      CandidateGenerator copy = *this;
      copy.entries_.clear();
      copy.visible_log_.clear();
      try {
        for (size_t task = next++; task < 2 * blocks && !failed; task = next++) {
          const size_t b = task % blocks;
          if (task < blocks) {
            copy.VisibilityEvents(cuts[b], cuts[b + 1]);
          } else {
            copy.FreeVertexEvents(cuts[b], cuts[b + 1]);
          }
          lists[task] = std::move(copy.entries_);
          copy.entries_.clear();
        }
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        failed = true;
      }
      pairs[t] = copy.visible_pairs_;
      visible_logs[t] = std::move(copy.visible_log_);
    };
    std::vector<std::thread> pool;
    for (size_t t = 1; t < static_cast<size_t>(threads); ++t) pool.emplace_back(work, t);
    work(0);
    for (auto& th : pool) th.join();
    if (error) std::rethrow_exception(error);
    for (auto& list : lists) {
      entries_.insert(entries_.end(), list.begin(), list.end());
      std::deque<CandidateEntry>().swap(list);
    }
    for (const std::int64_t p : pairs) visible_pairs_ += p;
    for (const auto& log : visible_logs) visible_log_.insert(visible_log_.end(), log.begin(), log.end());
    generated_ = static_cast<std::int64_t>(entries_.size());
  }

  // A free edge from one point i in [i0, i1) through another point j > i it sees.
  void VisibilityEvents(size_t i0, size_t i1) {
    const size_t n = points_.size();
    const auto& along_static = along_static_;
    for (size_t i = i0; i < i1; ++i) {
      for (size_t j = i + 1; j < n; ++j) {
        if (StaticPair(i, j) && along_differs_.count({i, j}) == 0) continue;  // AppendStatics
        if (r_only_ && !points_[i].start && !points_[j].start) continue;      // not an R event
        const Vector2d d = points_[j].p - points_[i].p;
        if (d.norm() <= cb_.tolerance) continue;
        // A free edge of a ray point that is not listed: only along a static segment or with the start region.
        const bool listed_i = listed_[i] != 0, listed_j = listed_[j] != 0;
        const bool always = points_[i].start || points_[j].start || along_static.count({i, j}) != 0;
        if (!listed_i && !listed_j && !always) continue;
        if (!cb_.Sees(points_[i].p, points_[j].p)) continue;
        ++visible_pairs_;
        if (record_visible_) visible_log_.push_back({PointId(i), PointId(j)});
        const double beta = std::atan2(d.y(), d.x());
        const CriticalKind kind = points_[i].start || points_[j].start ? CriticalKind::kR : CriticalKind::kVgraph;
        // Along β the free edge runs from b (its direction θ + π ± ε_v is β + π); along β + π from a. At
        // θ = β + se·ε_v (+π) that is the free edge of sign −se.
        const bool along = along_static.count({i, j}) != 0;
        // Along a static segment, the segment itself is where the event acts (a part of the region can appear
        // between it and the free edges turning across its line).
        std::vector<std::uint32_t> feature;
        if (along) feature = {PointId(i), PointId(j)};
        const auto pi = PointId(i), pj = PointId(j);
        for (double se : {-1.0, 1.0}) {
          const std::int8_t sign = se > 0 ? -1 : 1;
          // Along a segment the feature decides; elsewhere the point the free edge passes through.
          if (along) {
            Add(beta + se * eps_, kind, {pi, pj}, {pj}, {sign}, feature);
            Add(beta + M_PI + se * eps_, kind, {pi, pj}, {pi}, {sign}, feature);
            // The other end's free edge of the same sign, parallel to the segment beyond that end.
            Add(beta + se * eps_, kind, {pi, pj}, {pi}, {sign}, feature);
            Add(beta + M_PI + se * eps_, kind, {pi, pj}, {pj}, {sign}, feature);
          } else {
            if (listed_j || always) Add(beta + se * eps_, kind, {pi, pj}, {pj}, {sign}, feature, &points_[i].p);
            if (listed_i || always) Add(beta + M_PI + se * eps_, kind, {pi, pj}, {pi}, {sign}, feature, &points_[j].p);
          }
        }
      }
    }
  }

  // A free vertex f: the +ε_v free edge from a (direction θ + π + ε_v) meets the −ε_v one from b. Seen from f, a is at
  // θ + ε_v and b at θ − ε_v, so f lies on a fixed circle through a and b on which ab subtends 2ε_v; its crossings
  // with every edge give the orientations.
  // (For the first points i in [i0, i1).)
  void FreeVertexEvents(size_t i0, size_t i1) {
    const size_t n = points_.size();
    const double two_eps = 2 * eps_;
    if (two_eps < 1e-6) return;  // parallel free edges: no free vertex inside the bounds
    // The circles of (a, b) and of (b, a) are the same two, bit for bit (the midpoint, the negated normal and the
    // sign of the side cancel exactly): the index walks each once for both orders; the scan keeps every order.
    for (size_t i = i0; i < i1; ++i) {
      for (size_t j = indexed_ ? i + 1 : 0; j < n; ++j) {
        if (i == j) continue;
        // A free vertex of a ray point that is not listed: only where it crosses the start region's edges.
        const bool listed = listed_[i] != 0 && listed_[j] != 0;
        if (!listed && !with_start_) continue;
        const Vector2d a = points_[i].p, b = points_[j].p;
        const Vector2d ab = b - a;
        const double len = ab.norm();
        if (len <= cb_.tolerance) continue;
        const Vector2d m = 0.5 * (a + b);
        const Vector2d nrm(-ab.y() / len, ab.x() / len);
        const double r = len / (2 * std::sin(two_eps));
        const double h = len / (2 * std::tan(two_eps));
        // A static pair's crossings with the static segments are the static candidates' (AppendStatics).
        const bool static_pair = indexed_ && StaticPair(i, j);
        for (double side : {-1.0, 1.0}) {
          const Vector2d c = m + side * h * nrm;
          auto meet = [&](size_t k) {
            if ((r_only_ || !listed) && segs_[k].kind != SegKind::kStart) return;
            CircleMeetsSegment(i, j, c, r, k);
            if (indexed_) CircleMeetsSegment(j, i, c, r, k);  // (b, a): the same circle, not walked on its own
          };
          auto meet_few = [&](const FewSegments& few) {
            if (!NearCircle(few.box, c, r)) return;
            for (const size_t k : few.index)
              if (NearCircle(segs_[k], c, r)) meet(k);
          };
          if (r_only_ && indexed_) {
            meet_few(start_segs_);  // only the start region's edges make R events here
          } else if (static_pair) {
            meet_few(own_segs_);
          } else if (indexed_) {
            for (int k : seg_grid_.NearCircle(c, r)) meet(static_cast<size_t>(k));
          } else {
            for (size_t k = 0; k < segs_.size(); ++k) meet(k);
          }
        }
      }
    }
  }

  // Whether segment s comes within the grids' pad (and then some) of the circle: its nearest point inside the
  // circle's padded outside, its farthest end outside its padded inside. A superset of the segments CircleMeetsSegment
  // finds a crossing on, like SegmentGrid::NearCircle's, for few segments (a child's own, the start region's).
  bool NearCircle(const Seg& s, const Vector2d& c, double r) const {
    const double p = 2 * grid_pad_ + 1e-6 * r;
    const Vector2d d = s.b - s.a;
    const double t = d.squaredNorm() > 0 ? std::clamp((c - s.a).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
    const double nearest = (s.a + t * d - c).norm();
    const double farthest = std::max((s.a - c).norm(), (s.b - c).norm());
    return nearest <= r + p && farthest >= r - p;
  }

  // The same for a box (around all of them): its nearest point and its farthest corner.
  bool NearCircle(const Eigen::AlignedBox2d& box, const Vector2d& c, double r) const {
    if (box.isEmpty()) return false;
    const double p = 2 * grid_pad_ + 1e-6 * r;
    const double nearest = (c.cwiseMax(box.min()).cwiseMin(box.max()) - c).norm();
    const Vector2d far_corner((c.x() - box.min().x() > box.max().x() - c.x()) ? box.min().x() : box.max().x(),
                              (c.y() - box.min().y() > box.max().y() - c.y()) ? box.min().y() : box.max().y());
    return nearest <= r + p && (far_corner - c).norm() >= r - p;
  }

  void CircleMeetsSegment(size_t i, size_t j, const Vector2d& c, double r, size_t k) {
    const Seg& s = segs_[k];
    const Vector2d d = s.b - s.a, w = s.a - c;
    const double A = d.squaredNorm(), B = 2 * w.dot(d), C = w.squaredNorm() - r * r;
    const double disc = B * B - 4 * A * C;
    if (disc < 0) return;
    const double sq = std::sqrt(disc);
    for (double t : {(-B - sq) / (2 * A), (-B + sq) / (2 * A)}) {
      if (t < 0 || t > 1) continue;
      const Vector2d f = s.a + t * d;
      const Vector2d a = points_[i].p, b = points_[j].p;
      if ((f - a).norm() <= cb_.tolerance || (f - b).norm() <= cb_.tolerance) continue;
      const double theta = std::atan2((f - a).y(), (f - a).x()) - M_PI - eps_;
      const double check = std::atan2((f - b).y(), (f - b).x()) - M_PI + eps_;
      if (std::abs(WrapAngle(theta - check)) > 1e-7) continue;  // the other arc: the roles are swapped
      if (!cb_.Sees(a, f) || !cb_.Sees(b, f)) continue;
      CriticalKind kind = CriticalKind::kVertex;
      if (s.kind == SegKind::kRay) kind = CriticalKind::kFreeEdge;
      if (s.kind == SegKind::kStart) kind = CriticalKind::kR;
      // A ray that cannot be relied on at θ is never active: its crossings change nothing.
      if (s.kind == SegKind::kRay && !IsReliableRay(s.a, s.b, theta, pr_.velocity_cone)) continue;
      Add(theta, kind, {PointId(i), PointId(j), SegRef(k)}, {PointId(i), PointId(j)}, {1, -1}, {}, &f);
    }
  }

  // The stop flag, read every 4096 candidates: the candidates of a large scene with a camera can take gigabytes.
  void CheckStop() {
    if (stop_ != nullptr && (generated_ & 4095) == 0 && stop_->load(std::memory_order_relaxed)) {
      throw NondirectionalStopped();
    }
  }

  const BackprojectionProblem& pr_;
  const std::atomic<bool>* stop_ = nullptr;
  bool r_only_ = false;
  double eps_ = 0, phi_ = 0;
  std::vector<Pt> points_;
  std::vector<Seg> segs_;
  std::vector<std::array<Vector2d, 3>> ring_vertices_;
  std::vector<std::string> ring_vertex_refs_;
  ObstacleRegion cb_;
  SegmentGrid seg_grid_;  // every segment (the circles of free vertices meet them)
  bool indexed_ = false;
  double grid_pad_ = 0;  // the grids' pad (within it a segment is near)
  // A few segments tested against a circle one by one (NearCircle) instead of through the grid, and a box around them.
  struct FewSegments {
    std::vector<size_t> index;
    Eigen::AlignedBox2d box;  // empty: none
    void Add(size_t k, const Seg& s) {
      index.push_back(k);
      box.extend(s.a);
      box.extend(s.b);
    }
  };
  FewSegments start_segs_;  // the start region's edges (R events)
  bool with_start_ = false;
  // The static candidates taken (UseStatics): per point its index there or kNoIndex, and back; per static segment its
  // index here; the problem's own segments; the static pairs listed again.
  const StaticCandidates* statics_ = nullptr;
  std::vector<std::uint32_t> static_of_, point_of_static_, segment_of_static_;
  FewSegments own_segs_;
  std::set<std::pair<size_t, size_t>> along_differs_;
  bool record_visible_ = false;  // ListStatics: which pairs see each other
  std::vector<std::pair<std::uint32_t, std::uint32_t>> visible_log_;
  std::vector<char> listed_;  // per point: its events are listed (Scope)
  bool scoped_ = false;       // some points' events are not listed
  std::int64_t visible_pairs_ = 0;
  std::set<std::pair<size_t, size_t>> along_static_;  // PairsAlongStaticSegments
  bool reference_ = false;
  std::int64_t generated_ = 0;
  std::vector<std::string> strings_;  // the tables (MakeTables)
  std::vector<Vector2d> coords_;
  std::deque<CandidateEntry> entries_;
  std::vector<CriticalOrientation> reference_out_;
};

}  // namespace

void CandidateList::Get(std::size_t i, CriticalOrientation& out, bool with_refs) const {
  Materialize(entries_[i], strings_, points_, out, with_refs);
}

CriticalOrientation CandidateList::Get(std::size_t i) const {
  CriticalOrientation o;
  Get(i, o, true);
  return o;
}

std::vector<std::string> CandidateList::Refs(std::size_t i) const {
  std::vector<std::string> refs;
  for (size_t k = 0; k < RefCount(entries_[i]); ++k) refs.push_back(strings_[entries_[i].ids[k]]);
  return refs;
}

std::vector<CriticalOrientation> CandidateList::TakeKind(CriticalKind kind) {
  std::vector<CriticalOrientation> taken;
  for (std::size_t i = 0; i < entries_.size(); ++i)
    if (entries_[i].kind == kind) taken.push_back(Get(i));
  std::erase_if(entries_, [&](const CandidateEntry& e) { return e.kind == kind; });
  return taken;
}

const char* CriticalKindName(CriticalKind kind) {
  switch (kind) {
    case CriticalKind::kVgraph:
      return "vgraph";
    case CriticalKind::kSliding:
      return "sliding";
    case CriticalKind::kVertex:
      return "vertex";
    case CriticalKind::kR:
      return "R";
    case CriticalKind::kFreeEdge:
      return "free-edge";
    case CriticalKind::kVc:
      return "vc";
    case CriticalKind::kSelection:
      return "selection";
  }
  return "?";
}

const char* SlidingCauseName(SlidingCause cause) {
  switch (cause) {
    case SlidingCause::kNone:
      return "";
    case SlidingCause::kSticking:
      return "sticking";
    case SlidingCause::kAway:
      return "away";
    case SlidingCause::kContact:
      return "contact";
    case SlidingCause::kAlong:
      return "along";
    case SlidingCause::kVertexRule:
      return "vertex-rule";
    case SlidingCause::kVertexAway:
      return "vertex-away";
    case SlidingCause::kStickingHeld:
      return "sticking-held";
  }
  return "?";
}

bool SlidingCauseChangesNothing(SlidingCause cause) {
  return cause == SlidingCause::kAway || cause == SlidingCause::kAlong || cause == SlidingCause::kVertexAway ||
         cause == SlidingCause::kStickingHeld;
}

std::int64_t CriticalCounts::total() const {
  std::int64_t t = 0;
  for (auto c : by_kind) t += c;
  return t;
}

double WrapAngle(double theta) {
  double t = std::fmod(theta + M_PI, 2 * M_PI);
  if (t < 0) t += 2 * M_PI;
  t -= M_PI;
  if (t >= M_PI) t -= 2 * M_PI;
  return t;
}

CandidateList CriticalCandidateList(const BackprojectionProblem& problem, const NamedPolygon* start,
                                    CriticalCounts* counts, CandidateSearch search, const std::atomic<bool>* stop,
                                    int threads, const CandidateScope* scope, const StaticCandidates* statics) {
  return CandidateGenerator(problem, start, search, stop, scope, statics).Run(counts, false, nullptr, threads);
}

std::shared_ptr<const StaticCandidates> ListStaticCandidates(const BackprojectionProblem& problem, int threads,
                                                             const std::atomic<bool>* stop) {
  BackprojectionProblem statics = problem;
  statics.goal.clear();
  statics.rays.clear();
  statics.forbidden.clear();
  return CandidateGenerator(statics, nullptr, CandidateSearch::kIndexed, stop).ListStatics(std::max(1, threads));
}

namespace {
std::vector<CriticalOrientation> AllOf(const CandidateList& list) {
  std::vector<CriticalOrientation> out(list.size());
  for (std::size_t i = 0; i < list.size(); ++i) list.Get(i, out[i], true);
  return out;
}
}  // namespace

std::vector<CriticalOrientation> CriticalCandidates(const BackprojectionProblem& problem, const NamedPolygon* start,
                                                    CriticalCounts* counts, CandidateSearch search,
                                                    const std::atomic<bool>* stop) {
  return AllOf(CriticalCandidateList(problem, start, counts, search, stop));
}

std::vector<CriticalOrientation> CriticalCandidatesReference(const BackprojectionProblem& problem,
                                                             const NamedPolygon* start, CriticalCounts* counts) {
  std::vector<CriticalOrientation> out;
  CandidateGenerator(problem, start, CandidateSearch::kIndexed).Run(counts, false, &out);
  return out;
}

std::vector<CriticalOrientation> RCriticalCandidates(const BackprojectionProblem& problem, const NamedPolygon& start,
                                                     CandidateSearch search) {
  return AllOf(CandidateGenerator(problem, &start, search).Run(nullptr, true));
}

}  // namespace visco::planning

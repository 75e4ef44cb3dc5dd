// Rotational sweep for unoccluded vertices with CM vertices interleaved (Fox & Hutchinson §III-C-3), its O(n^2)
// reference, and the CVC rays.

#include "planning/vc_rays.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/convex_hull_2.h>
#include <fmt/format.h>

#include <algorithm>
#include <map>
#include <numeric>
#include <set>

namespace visco::planning {
namespace {

// An obstacle vertex with its neighbours on the counter-clockwise polygon.
struct VertexRef {
  int obstacle;
  int index;
  Point point, prev, next;
};

std::vector<VertexRef> AllVertices(const Scene& scene) {
  std::vector<VertexRef> vertices;
  for (std::size_t o = 0; o < scene.obstacles.size(); ++o) {
    const Polygon& p = scene.obstacles[o].shape.polygon;
    const std::size_t n = p.size();
    for (std::size_t i = 0; i < n; ++i) {
      vertices.push_back({static_cast<int>(o), static_cast<int>(i), p[i], p[(i + n - 1) % n], p[(i + 1) % n]});
    }
  }
  return vertices;
}

// The robot's convex hull corners (counter-clockwise, no collinear points) as indices into its normalised polygon.
std::vector<int> RobotHull(const Scene& scene) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  const Polygon& robot = scene.robot.polygon;
  std::vector<K::Point_2> points, hull;
  for (const Point& p : robot.vertices) points.emplace_back(p.x(), p.y());
  CGAL::convex_hull_2(points.begin(), points.end(), std::back_inserter(hull));
  std::vector<int> indices;
  for (const K::Point_2& h : hull) {
    for (std::size_t i = 0; i < robot.size(); ++i) {
      if (robot[i].x() == h.x() && robot[i].y() == h.y()) {
        indices.push_back(static_cast<int>(i));
        break;
      }
    }
  }
  return indices;
}

// CM vertex choice for the direction P -> b: side +1 maximises cross(b - P, a) (extreme left), side -1 minimises.
// better(x, y): x is strictly more extreme than y.
bool MoreExtreme(const Point& p, const Point& b, const Point& x, const Point& y, int side) {
  return side * CrossSign(p, b, y, x) > 0;
}

// Among two tied hull corners, the one with the lower file index.
int LowerFileIndex(const Scene& scene, int i, int j) {
  return scene.robot.source_index[i] <= scene.robot.source_index[j] ? i : j;
}

// The CM vertex on `side` by scanning all hull corners (reference; also seeds the calipers).
int ScanCm(const Scene& scene, const std::vector<int>& hull, const Point& p, const Point& b, int side) {
  const Polygon& robot = scene.robot.polygon;
  int best = hull[0];
  for (int h : hull) {
    if (MoreExtreme(p, b, robot[h], robot[best], side)) {
      best = h;
    } else if (CrossSign(p, b, robot[best], robot[h]) == 0) {
      best = LowerFileIndex(scene, best, h);
    }
  }
  return best;
}

// Rotating caliper for one side: the extreme hull corner moves counter-clockwise as the direction turns
// counter-clockwise (by less than 180 degrees over the whole sweep).
class Caliper {
 public:
  Caliper(const Scene& scene, const std::vector<int>& hull, int side) : scene_(scene), hull_(hull), side_(side) {}

  int Query(const Point& p, const Point& b) {
    const Polygon& robot = scene_.robot.polygon;
    const std::size_t h = hull_.size();
    const auto at = [&](std::size_t k) -> const Point& { return robot[hull_[k % h]]; };
    if (!started_) {
      const int best = ScanCm(scene_, hull_, p, b, side_);
      pos_ = static_cast<std::size_t>(std::find(hull_.begin(), hull_.end(), best) - hull_.begin());
      // Rest on the first corner of a tied pair.
      if (CrossSign(p, b, at(pos_ + h - 1), at(pos_)) == 0) pos_ = (pos_ + h - 1) % h;
      started_ = true;
    }
    for (std::size_t steps = 0; steps < h && MoreExtreme(p, b, at(pos_ + 1), at(pos_), side_); ++steps) {
      pos_ = (pos_ + 1) % h;
    }
    if (CrossSign(p, b, at(pos_), at(pos_ + 1)) == 0) {
      return LowerFileIndex(scene_, hull_[pos_], hull_[(pos_ + 1) % h]);
    }
    return hull_[pos_];
  }

 private:
  const Scene& scene_;
  const std::vector<int>& hull_;
  int side_;
  bool started_ = false;
  std::size_t pos_ = 0;
};

// An obstacle edge that is not collinear with P, oriented by the sweep: `start` comes first counter-clockwise.
struct SweepEdge {
  Point a, b;  // as on the counter-clockwise polygon (interior to the left of a -> b)
  Point start, end;
  int id;
};

// Which of two non-crossing edges, both met by some ray from P in their relative interiors, is nearer to P along
// every such ray. Ties (collinear overlapping edges) go to the lower id.
struct NearerFirst {
  const std::vector<SweepEdge>* edges;
  Point p;
  bool operator()(int i, int j) const {
    if (i == j) return false;
    const SweepEdge& e = (*edges)[i];
    const SweepEdge& f = (*edges)[j];
    const int s1 = Orientation(f.a, f.b, e.a), t1 = Orientation(f.a, f.b, e.b);
    if (s1 * t1 >= 0 && (s1 != 0 || t1 != 0)) {
      const int side = s1 != 0 ? s1 : t1;  // e lies on this side of f's line
      return side == Orientation(f.a, f.b, p);
    }
    if (s1 == 0 && t1 == 0) return i < j;  // collinear
    const int s2 = Orientation(e.a, e.b, f.a), t2 = Orientation(e.a, e.b, f.b);
    const int side = s2 != 0 ? s2 : t2;  // f lies on this side of e's line
    return side != Orientation(e.a, e.b, p);
  }
};

// The sectors at P of the obstacles whose boundary contains P: (first, second) with the interior swept
// counter-clockwise from P->first to P->second.
std::vector<std::pair<Point, Point>> SectorsAtCamera(const Scene& scene, const Point& p) {
  std::vector<std::pair<Point, Point>> sectors;
  for (const Obstacle& o : scene.obstacles) {
    const Polygon& poly = o.shape.polygon;
    const std::size_t n = poly.size();
    for (std::size_t i = 0; i < n; ++i) {
      if (poly[i] == p) sectors.emplace_back(poly[(i + 1) % n], poly[(i + n - 1) % n]);
      if (InSegmentInterior(poly.Edge(i), p)) sectors.emplace_back(poly.Vertex(i + 1), poly[i]);
    }
  }
  return sectors;
}

}  // namespace

std::vector<UnoccludedVertex> FindUnoccludedVertices(const Scene& scene) {
  std::vector<UnoccludedVertex> result;
  if (!scene.camera) return result;
  // The sweep's status order needs edges that do not cross; overlapping obstacles (allowed, docs/semantics.md) fall
  // back to the O(n^2) test, which handles a vertex inside another obstacle (its segment to P starts in that interior).
  // With heights (2.5D) a prism hides only part of what lies behind it; the same O(n^2) test decides that per prism.
  if (FindOverlappingObstacles(scene.obstacles) || UsesHeights(scene)) return FindUnoccludedVerticesReference(scene);
  const Camera& camera = *scene.camera;
  const Point p = camera.center;
  const Point origin(0, 0), d0(camera.fov_first);

  const std::vector<VertexRef> vertices = AllVertices(scene);
  // Events: vertices in the field of view, by angle, then by distance from P.
  std::vector<int> events;
  for (std::size_t v = 0; v < vertices.size(); ++v) {
    if (camera.Sees(vertices[v].point)) events.push_back(static_cast<int>(v));
  }
  std::sort(events.begin(), events.end(), [&](int i, int j) {
    const Point& u = vertices[i].point;
    const Point& w = vertices[j].point;
    const int o = Orientation(p, u, w);
    if (o != 0) return o > 0;
    const int c = CompareDistance(p, u, w);
    if (c != 0) return c < 0;
    return std::tie(vertices[i].obstacle, vertices[i].index) < std::tie(vertices[j].obstacle, vertices[j].index);
  });

  // Edges not collinear with P, and for each vertex the edges that start or end there.
  std::vector<SweepEdge> edges;
  std::vector<std::vector<int>> starting(vertices.size()), ending(vertices.size());
  {
    std::size_t base = 0;
    for (const Obstacle& o : scene.obstacles) {
      const Polygon& poly = o.shape.polygon;
      const std::size_t n = poly.size();
      for (std::size_t i = 0; i < n; ++i) {
        const Point& a = poly[i];
        const Point& b = poly[(i + 1) % n];
        const int orient = Orientation(p, a, b);
        if (orient == 0) continue;
        const int id = static_cast<int>(edges.size());
        const std::size_t va = base + i, vb = base + (i + 1) % n;
        if (orient > 0) {
          edges.push_back({a, b, a, b, id});
          starting[va].push_back(id);
          ending[vb].push_back(id);
        } else {
          edges.push_back({a, b, b, a, id});
          starting[vb].push_back(id);
          ending[va].push_back(id);
        }
      }
      base += n;
    }
  }

  std::set<int, NearerFirst> status(NearerFirst{&edges, p});
  std::vector<std::set<int, NearerFirst>::iterator> where(edges.size(), status.end());
  for (const SweepEdge& e : edges) {
    // Strictly spans the first limit direction.
    if (CrossSign(p, e.start, origin, d0) > 0 && CrossSign(origin, d0, p, e.end) > 0) {
      where[e.id] = status.insert(e.id).first;
    }
  }

  const std::vector<std::pair<Point, Point>> camera_sectors = SectorsAtCamera(scene, p);
  const std::vector<int> hull = RobotHull(scene);
  Caliper left(scene, hull, +1), right(scene, hull, -1);

  std::size_t g = 0;
  while (g < events.size()) {
    std::size_t g_end = g + 1;
    while (g_end < events.size() && Orientation(p, vertices[events[g]].point, vertices[events[g_end]].point) == 0) {
      ++g_end;
    }
    for (std::size_t k = g; k < g_end; ++k) {
      for (int e : ending[events[k]]) {
        if (where[e] != status.end()) {
          status.erase(where[e]);
          where[e] = status.end();
        }
      }
    }
    bool blocked_beyond = false;  // some nearer point on this ray lets the ray into an interior
    std::size_t k = g;
    while (k < g_end) {
      const Point x = vertices[events[k]].point;
      std::size_t k_end = k + 1;
      while (k_end < g_end && vertices[events[k_end]].point == x) ++k_end;
      bool occluded = blocked_beyond;
      // Edges crossing the ray's interior strictly before x, or through x with P on their interior side.
      for (auto it = status.begin(); !occluded && it != status.end(); ++it) {
        const SweepEdge& e = edges[*it];
        const int sx = Orientation(e.a, e.b, x), sp = Orientation(e.a, e.b, p);
        if (sx * sp < 0) {
          occluded = true;
        } else if (sx == 0) {
          occluded = sp > 0;
        } else {
          break;
        }
      }
      // The segment leaves x towards P into an interior (x's own obstacle or one touching it), or leaves P towards
      // x into an interior.
      for (std::size_t q = k; !occluded && q < k_end; ++q) {
        const VertexRef& v = vertices[events[q]];
        occluded = InOpenSector(x, v.next, v.prev, p);
      }
      for (std::size_t s = 0; !occluded && s < camera_sectors.size(); ++s) {
        occluded = InOpenSector(p, camera_sectors[s].first, camera_sectors[s].second, x);
      }
      if (!occluded) {
        const int cm_left = left.Query(p, x), cm_right = right.Query(p, x);
        for (std::size_t q = k; q < k_end; ++q) {
          result.push_back({vertices[events[q]].obstacle, vertices[events[q]].index, {cm_left, cm_right}});
        }
      }
      for (std::size_t q = k; !blocked_beyond && q < k_end; ++q) {
        const VertexRef& v = vertices[events[q]];
        blocked_beyond = InOpenSector(x, v.next, v.prev, p) || InOpenSector(x, v.next, v.prev, p, /*reverse=*/true);
      }
      k = k_end;
    }
    for (std::size_t q = g; q < g_end; ++q) {
      for (int e : starting[events[q]]) where[e] = status.insert(e).first;
    }
    g = g_end;
  }
  // A pinhole camera sees a vertex in its sector only if it lies inside the image too (the sweep's occlusion is
  // independent of that: hidden is hidden).
  if (camera.pinhole) {
    std::erase_if(result, [&](const UnoccludedVertex& u) {
      return !camera.InView(scene.obstacles[u.obstacle].shape.polygon[u.vertex]);
    });
  }
  std::sort(result.begin(), result.end(), [](const UnoccludedVertex& a, const UnoccludedVertex& b) {
    return std::tie(a.obstacle, a.vertex) < std::tie(b.obstacle, b.vertex);
  });
  return result;
}

namespace {

// Whether the open segment (p, b) meets the interior of obstacle `o` (the planar occlusion test, restricted to one
// obstacle). Exact.
bool MeetsInterior(const Scene& scene, const std::vector<VertexRef>& vertices, int o, const Point& p, const Point& b) {
  const Segment sight{p, b};
  const Polygon& poly = scene.obstacles[o].shape.polygon;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Segment e = poly.Edge(i);
    if (SegmentsCrossProperly(sight, e) || (InSegmentInterior(e, b) && Orientation(e.source, e.target, p) > 0) ||
        (InSegmentInterior(e, p) && Orientation(e.source, e.target, b) > 0)) {
      return true;
    }
  }
  for (const VertexRef& w : vertices) {
    if (w.obstacle != o) continue;
    if (InSegmentInterior(sight, w.point)) {
      if (InOpenSector(w.point, w.next, w.prev, p) || InOpenSector(w.point, w.next, w.prev, p, true)) return true;
    } else if (w.point == b) {
      if (InOpenSector(w.point, w.next, w.prev, p)) return true;
    } else if (w.point == p) {
      if (InOpenSector(p, w.next, w.prev, b)) return true;
    }
  }
  return false;
}

// The first and last parameters s in [0, 1] at which b + s (p - b) touches the boundary of polygon `poly` (which the
// segment meets), the first being 0 when b lies inside it. Rounded.
std::pair<double, double> ContactRange(const Polygon& poly, const Point& b, const Point& p) {
  double first = 1, last = 0;
  // A point inside the footprint (overlapping parts) is covered from s = 0 on.
  if (Locate(poly, b) == Location::kInside) first = 0;
  const Vector d = p - b;
  const double dd = d.squaredNorm();
  auto note = [&](double s) {
    s = std::clamp(s, 0.0, 1.0);
    first = std::min(first, s);
    last = std::max(last, s);
  };
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Segment e = poly.Edge(i);
    if (!SegmentsIntersect({b, p}, e)) continue;
    const Vector f = e.target - e.source;
    const double denominator = d.x() * f.y() - d.y() * f.x();
    if (Orientation(b, p, e.source) == 0 && Orientation(b, p, e.target) == 0) {
      note((e.source - b).dot(d) / dd);  // collinear: the shared piece lies between the projections
      note((e.target - b).dot(d) / dd);
    } else if (denominator != 0) {
      const Vector w = e.source - b;
      note((w.x() * f.y() - w.y() * f.x()) / denominator);
    }
  }
  return {first, last};
}

// Relative tolerance of the 2.5D decisions (in doubles): ties and near-ties count as hidden.
constexpr double kHeightTolerance = 1e-9;

// With heights: whether the prism of obstacle `o`, whose footprint the open segment (p, b) enters, hides b (the line
// of sight from b rises to the camera height H at p and must pass above the prism where it first meets it).
bool PrismHides(const Scene& scene, int o, const Point& b, const Point& p) {
  const std::optional<double>& h = scene.obstacles[o].height;
  if (!h || !UsesHeights(scene)) return true;
  const double camera_height = *scene.camera->height;
  const double first = ContactRange(scene.obstacles[o].shape.polygon, b, p).first;
  return camera_height * first < *h * (1 + kHeightTolerance);
}

}  // namespace

bool UsesHeights(const Scene& scene) {
  if (!scene.camera || !scene.camera->height) return false;
  return std::any_of(scene.obstacles.begin(), scene.obstacles.end(), [](const Obstacle& o) { return o.height; });
}

std::vector<UnoccludedVertex> FindUnoccludedVerticesReference(const Scene& scene) {
  std::vector<UnoccludedVertex> result;
  if (!scene.camera) return result;
  const Point p = scene.camera->center;
  const std::vector<VertexRef> vertices = AllVertices(scene);
  const std::vector<int> hull = RobotHull(scene);
  for (const VertexRef& v : vertices) {
    if (!scene.camera->InView(v.point)) continue;
    bool occluded = false;
    for (int o = 0; o < static_cast<int>(scene.obstacles.size()) && !occluded; ++o) {
      occluded = MeetsInterior(scene, vertices, o, p, v.point) && PrismHides(scene, o, v.point, p);
    }
    if (!occluded) {
      result.push_back(
          {v.obstacle, v.index, {ScanCm(scene, hull, p, v.point, +1), ScanCm(scene, hull, p, v.point, -1)}});
    }
  }
  return result;
}

std::vector<std::pair<double, double>> VisibleRayParameters(const Scene& scene, const Point& b) {
  std::vector<std::pair<double, double>> visible;
  if (!scene.camera) return visible;
  const Point p = scene.camera->center;
  const auto view = scene.camera->ViewInterval(b, p);
  if (!view) return visible;
  visible.push_back(*view);
  if (UsesHeights(scene)) {
    const double camera_height = *scene.camera->height;
    const std::vector<VertexRef> vertices = AllVertices(scene);
    for (int o = 0; o < static_cast<int>(scene.obstacles.size()); ++o) {
      if (!scene.obstacles[o].height || !MeetsInterior(scene, vertices, o, p, b)) continue;
      // b's line of sight passes over this prism (b is unoccluded). A robot vertex at s before the prism is seen iff
      // its own line of sight, rising from 0 at s to H at 1, is above the prism's height h at the first contact:
      // H (first - s) / (1 - s) >= h, i.e. s <= (H first - h) / (H - h). Between the first and the last contact it
      // may stand in a gap of the footprint behind a part of the prism: counted hidden. Beyond the last contact
      // nothing of the prism lies between it and the camera.
      const double h = *scene.obstacles[o].height;
      const auto [first, last] = ContactRange(scene.obstacles[o].shape.polygon, b, p);
      const double before =
          camera_height > h ? (camera_height * first - h) / (camera_height - h) - kHeightTolerance : -1.0;
      const double after = last + kHeightTolerance;
      std::vector<std::pair<double, double>> kept;
      for (const auto& [lo, hi] : visible) {
        if (std::min(hi, before) >= lo) kept.emplace_back(lo, std::min(hi, before));
        if (hi >= std::max(lo, after)) kept.emplace_back(std::max(lo, after), hi);
      }
      visible = std::move(kept);
    }
  }
  std::erase_if(visible, [](const auto& interval) { return !(interval.second > interval.first); });
  return visible;
}

namespace {

// First file ordinal k of each obstacle's vertices (obstacles' vertices counted in file order).
std::vector<int> VertexOrdinalBases(const Scene& scene) {
  std::vector<int> bases;
  int k = 0;
  for (const Obstacle& o : scene.obstacles) {
    bases.push_back(k);
    k += *std::max_element(o.shape.source_index.begin(), o.shape.source_index.end()) + 1;
  }
  return bases;
}

}  // namespace

std::string VcRayId(const Scene& scene, int obstacle, int file_vertex) {
  return fmt::format("vc{}", VertexOrdinalBases(scene)[obstacle] + file_vertex);
}

std::string CvcRayId(const std::string& vc_ray_id, int robot_file_vertex) {
  return fmt::format("{}.cm{}", vc_ray_id, robot_file_vertex);
}

VcRays ComputeVcRays(const Scene& scene, const CSpace& cspace) {
  VcRays rays;
  if (!scene.camera) return rays;
  const Point p = scene.camera->center;
  const std::vector<int> bases = VertexOrdinalBases(scene);
  std::vector<std::pair<int, VcRay>> keyed;
  for (const UnoccludedVertex& u : FindUnoccludedVertices(scene)) {
    const Obstacle& o = scene.obstacles[u.obstacle];
    VcRay ray;
    ray.obstacle = u.obstacle;
    ray.vertex_normalised = u.vertex;
    ray.vertex = o.shape.source_index[u.vertex];
    const int ordinal = bases[u.obstacle] + ray.vertex;
    ray.id = fmt::format("vc{}", ordinal);
    ray.from = o.shape.polygon[u.vertex];
    ray.to = p;
    std::array<int, 2> cm = {scene.robot.source_index[u.cm[0]], scene.robot.source_index[u.cm[1]]};
    std::sort(cm.begin(), cm.end());
    ray.cm_vertices = cm;
    keyed.emplace_back(ordinal, std::move(ray));
  }
  std::sort(keyed.begin(), keyed.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<OffsetSegment> inputs;
  std::vector<int> owner;  // inputs[i] is a piece of cvc_rays[owner[i]]
  for (auto& [k, ray] : keyed) {
    const int index = static_cast<int>(rays.vc_rays.size());
    // Where on the workspace ray a CM vertex is seen (the whole ray in the planar model): one input per piece.
    const std::vector<std::pair<double, double>> visible = VisibleRayParameters(scene, ray.from);
    const auto at = [&](double s) -> Point {
      if (s == 0) return ray.from;
      if (s == 1) return ray.to;
      return ray.from + s * (ray.to - ray.from);
    };
    for (int j : ray.cm_vertices) {
      // Robot vertex with file index j.
      const auto& src = scene.robot.source_index;
      const int normalised = static_cast<int>(std::find(src.begin(), src.end(), j) - src.begin());
      const Point& a = scene.robot.polygon[normalised];
      CvcRay cvc;
      cvc.id = CvcRayId(ray.id, j);
      cvc.vc_ray = index;
      cvc.cm_vertex = j;
      cvc.offset = -a;
      cvc.full = {ray.from - a, ray.to - a};
      for (const auto& [lo, hi] : visible) {
        inputs.push_back({at(lo), at(hi), -a});
        owner.push_back(static_cast<int>(rays.cvc_rays.size()));
      }
      rays.cvc_rays.push_back(std::move(cvc));
    }
    rays.vc_rays.push_back(std::move(ray));
  }
  CutResult cut = cspace.CutSegments(inputs, scene.bounds, /*crossings=*/true);
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    CvcRay& cvc = rays.cvc_rays[owner[i]];
    for (std::size_t k = 0; k < cut.parts[i].size(); ++k) {
      cvc.segments.push_back(cut.parts[i][k]);
      const auto [source_on_cb, target_on_cb] = cut.on_cb[i][k];
      cvc.open_ends.push_back({!source_on_cb, !target_on_cb});
    }
  }
  for (const CutResult::Crossing& c : cut.crossings) {
    // Pieces of one ray are disjoint parts of one line: they never meet each other.
    if (owner[c.first] == owner[c.second]) continue;
    rays.crossings.push_back({owner[c.first], owner[c.second], c.point, c.overlap});
  }
  return rays;
}

}  // namespace visco::planning

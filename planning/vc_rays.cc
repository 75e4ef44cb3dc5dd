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
  if (FindOverlappingObstacles(scene.obstacles)) return FindUnoccludedVerticesReference(scene);
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
  std::sort(result.begin(), result.end(), [](const UnoccludedVertex& a, const UnoccludedVertex& b) {
    return std::tie(a.obstacle, a.vertex) < std::tie(b.obstacle, b.vertex);
  });
  return result;
}

std::vector<UnoccludedVertex> FindUnoccludedVerticesReference(const Scene& scene) {
  std::vector<UnoccludedVertex> result;
  if (!scene.camera) return result;
  const Point p = scene.camera->center;
  const std::vector<VertexRef> vertices = AllVertices(scene);
  const std::vector<int> hull = RobotHull(scene);
  for (const VertexRef& v : vertices) {
    if (!scene.camera->Sees(v.point)) continue;
    const Segment sight{p, v.point};
    bool occluded = false;
    for (const Obstacle& o : scene.obstacles) {
      const Polygon& poly = o.shape.polygon;
      for (std::size_t i = 0; i < poly.size() && !occluded; ++i) {
        const Segment e = poly.Edge(i);
        occluded = SegmentsCrossProperly(sight, e) ||
                   (InSegmentInterior(e, v.point) && Orientation(e.source, e.target, p) > 0) ||
                   (InSegmentInterior(e, p) && Orientation(e.source, e.target, v.point) > 0);
      }
    }
    for (const VertexRef& w : vertices) {
      if (occluded) break;
      if (InSegmentInterior(sight, w.point)) {
        occluded = InOpenSector(w.point, w.next, w.prev, p) || InOpenSector(w.point, w.next, w.prev, p, true);
      } else if (w.point == v.point) {
        occluded = InOpenSector(w.point, w.next, w.prev, p);
      } else if (w.point == p) {
        occluded = InOpenSector(p, w.next, w.prev, v.point);
      }
    }
    if (!occluded) {
      result.push_back(
          {v.obstacle, v.index, {ScanCm(scene, hull, p, v.point, +1), ScanCm(scene, hull, p, v.point, -1)}});
    }
  }
  return result;
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
  for (auto& [k, ray] : keyed) {
    const int index = static_cast<int>(rays.vc_rays.size());
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
      rays.cvc_rays.push_back(std::move(cvc));
      inputs.push_back({ray.from, ray.to, -a});
    }
    rays.vc_rays.push_back(std::move(ray));
  }
  CutResult cut = cspace.CutSegments(inputs, scene.bounds, /*crossings=*/true);
  for (std::size_t i = 0; i < rays.cvc_rays.size(); ++i) {
    rays.cvc_rays[i].segments = std::move(cut.parts[i]);
    for (const auto& [source_on_cb, target_on_cb] : cut.on_cb[i]) {
      rays.cvc_rays[i].open_ends.push_back({!source_on_cb, !target_on_cb});
    }
  }
  for (const CutResult::Crossing& c : cut.crossings) {
    rays.crossings.push_back({static_cast<int>(c.first), static_cast<int>(c.second), c.point, c.overlap});
  }
  return rays;
}

}  // namespace visco::planning

#include "planning/camera_placement.h"

#include <CGAL/Arr_segment_traits_2.h>
#include <CGAL/Arrangement_2.h>
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Polygon_2_algorithms.h>
#include <CGAL/convex_hull_2.h>
#include <CGAL/intersections.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <thread>

#include "common/error.h"
#include "planning/strategy.h"
#include "planning/vc_rays.h"

namespace visco::planning {
namespace {

using K = CGAL::Exact_predicates_exact_constructions_kernel;
using KPoint = K::Point_2;
using KSegment = K::Segment_2;
using Traits = CGAL::Arr_segment_traits_2<K>;
using Arrangement = CGAL::Arrangement_2<Traits>;

constexpr double kPi = 3.14159265358979323846;

KPoint ToK(const Point& p) { return {p.x(), p.y()}; }
Point ToPoint(const KPoint& p) { return {CGAL::to_double(p.x()), CGAL::to_double(p.y())}; }

// A point of the obstacles' boundary where a line of sight can graze them: a vertex with its two neighbours (the
// line through it is an event only if both of its edges lie on one side), or a crossing of two obstacles' edges
// (no neighbours: every line through it is kept, a superset).
struct GrazePoint {
  KPoint p;
  bool has_neighbours = false;
  KPoint prev, next;
};

// The part of `line` inside the closed rectangle, if it has positive length, with its ends in (x, y) order.
std::optional<KSegment> Clip(const K::Line_2& line, const K::Iso_rectangle_2& box) {
  const auto hit = CGAL::intersection(line, box);
  if (!hit) return std::nullopt;
  if (const KSegment* s = boost::get<KSegment>(&*hit)) {
    if (s->is_degenerate()) return std::nullopt;
    return CGAL::compare_xy(s->source(), s->target()) == CGAL::SMALLER ? *s : s->opposite();
  }
  return std::nullopt;
}

bool SegmentLess(const KSegment& a, const KSegment& b) {
  const auto c = CGAL::compare_xy(a.source(), b.source());
  if (c != CGAL::EQUAL) return c == CGAL::SMALLER;
  return CGAL::compare_xy(a.target(), b.target()) == CGAL::SMALLER;
}

bool SegmentEqual(const KSegment& a, const KSegment& b) { return a.source() == b.source() && a.target() == b.target(); }

}  // namespace

ViewingCells ComputeViewingCells(const Scene& scene, const Point& min, const Point& max,
                                 std::optional<double> camera_height) {
  if (!(min.x() < max.x() && min.y() < max.y())) {
    throw InputError(scene.source, "region", "the candidate region must have min < max in x and y");
  }
  const K::Iso_rectangle_2 box(ToK(min), ToK(max));
  ViewingCells out;

  // The vertices that can give VC rays, and the points where a line of sight can graze the obstacles.
  std::vector<KPoint> vertices;
  std::vector<GrazePoint> graze;
  for (const Obstacle& o : scene.obstacles) {
    const Polygon& poly = o.shape.polygon;
    for (std::size_t i = 0; i < poly.size(); ++i) {
      vertices.push_back(ToK(poly[i]));
      graze.push_back({ToK(poly[i]), true, ToK(poly.Vertex(i + poly.size() - 1)), ToK(poly.Vertex(i + 1))});
    }
  }
  out.obstacle_vertices = static_cast<int>(vertices.size());
  for (std::size_t a = 0; a < scene.obstacles.size(); ++a) {
    for (std::size_t b = a + 1; b < scene.obstacles.size(); ++b) {
      const Polygon& pa = scene.obstacles[a].shape.polygon;
      const Polygon& pb = scene.obstacles[b].shape.polygon;
      for (std::size_t i = 0; i < pa.size(); ++i) {
        const KSegment ea(ToK(pa.Vertex(i)), ToK(pa.Vertex(i + 1)));
        for (std::size_t j = 0; j < pb.size(); ++j) {
          const KSegment eb(ToK(pb.Vertex(j)), ToK(pb.Vertex(j + 1)));
          if (!CGAL::do_intersect(ea, eb)) continue;
          const auto hit = CGAL::intersection(ea, eb);
          if (!hit) continue;
          if (const KPoint* p = boost::get<KPoint>(&*hit)) graze.push_back({*p, false, {}, {}});
        }
      }
    }
  }

  // The robot's hull edge directions (the CM vertices change where P -> b is parallel to one).
  std::vector<KPoint> robot;
  for (const Point& p : scene.robot.polygon.vertices) robot.push_back(ToK(p));
  std::vector<KPoint> hull;
  CGAL::convex_hull_2(robot.begin(), robot.end(), std::back_inserter(hull));
  out.robot_vertices = static_cast<int>(hull.size());

  std::vector<KSegment> lines;
  auto add_line = [&](const KPoint& a, const KPoint& b) {
    if (a == b) return;
    if (auto s = Clip(K::Line_2(a, b), box)) lines.push_back(*s);
  };
  for (const KPoint& b : vertices) {
    for (const GrazePoint& w : graze) {
      if (w.p == b) continue;
      if (w.has_neighbours) {
        const auto o1 = CGAL::orientation(b, w.p, w.prev);
        const auto o2 = CGAL::orientation(b, w.p, w.next);
        if (o1 * o2 < 0) continue;  // the line crosses w's obstacle there: no line of sight grazes it at w
      }
      add_line(b, w.p);
    }
    for (std::size_t i = 0; i < hull.size(); ++i) {
      const KPoint& h0 = hull[i];
      const KPoint& h1 = hull[(i + 1) % hull.size()];
      add_line(b, b + (h1 - h0));
    }
    // 2.5D: where b's line of sight starts or stops passing over a prism lower than the camera.
    if (camera_height) {
      for (const Obstacle& o : scene.obstacles) {
        if (!o.height || !(*o.height < *camera_height)) continue;
        const K::FT ratio = K::FT(*camera_height) / K::FT(*o.height);
        const Polygon& poly = o.shape.polygon;
        for (std::size_t i = 0; i < poly.size(); ++i) {
          const KPoint e0 = b + ratio * (ToK(poly.Vertex(i)) - b);
          const KPoint e1 = b + ratio * (ToK(poly.Vertex(i + 1)) - b);
          add_line(e0, e1);
        }
      }
    }
  }
  std::sort(lines.begin(), lines.end(), SegmentLess);
  lines.erase(std::unique(lines.begin(), lines.end(), SegmentEqual), lines.end());
  out.event_lines = static_cast<int>(lines.size());
  // The rectangle closes the faces.
  const KPoint c0 = ToK(min), c1(max.x(), min.y()), c2 = ToK(max), c3(min.x(), max.y());
  lines.emplace_back(c0, c1);
  lines.emplace_back(c1, c2);
  lines.emplace_back(c2, c3);
  lines.emplace_back(c3, c0);

  Arrangement arrangement;
  std::vector<Traits::Curve_2> curves(lines.begin(), lines.end());
  CGAL::insert(arrangement, curves.begin(), curves.end());

  std::vector<std::vector<KPoint>> obstacles;
  for (const Obstacle& o : scene.obstacles) {
    std::vector<KPoint> ring;
    for (const Point& p : o.shape.polygon.vertices) ring.push_back(ToK(p));
    obstacles.push_back(std::move(ring));
  }
  for (auto f = arrangement.faces_begin(); f != arrangement.faces_end(); ++f) {
    if (f->is_unbounded() || !f->has_outer_ccb()) continue;
    ++out.faces;
    std::vector<KPoint> ring;
    auto e = f->outer_ccb();
    const auto first = e;
    do {
      ring.push_back(e->target()->point());
    } while (++e != first);
    K::FT sx = 0, sy = 0;
    for (const KPoint& p : ring) {
      sx += p.x();
      sy += p.y();
    }
    const KPoint centre(sx / static_cast<int>(ring.size()), sy / static_cast<int>(ring.size()));
    // The face lies inside or outside each obstacle as a whole (its edges lie on event lines): its centre decides.
    const bool blocked = std::any_of(obstacles.begin(), obstacles.end(), [&](const std::vector<KPoint>& o) {
      return CGAL::bounded_side_2(o.begin(), o.end(), centre, K()) != CGAL::ON_UNBOUNDED_SIDE;
    });
    if (blocked) continue;
    ViewingCell cell;
    cell.sample = ToPoint(centre);
    // A face too thin for its rounded centre to stay inside cannot hold a camera given in doubles: left out.
    const KPoint rounded = ToK(cell.sample);
    bool inside = true;
    for (std::size_t i = 0; i < ring.size() && inside; ++i) {
      const KPoint& a = ring[i];
      const KPoint& b = ring[(i + 1) % ring.size()];
      if (a == b) continue;
      inside = CGAL::orientation(a, b, rounded) == CGAL::LEFT_TURN;  // the outer boundary runs counter-clockwise
    }
    if (!inside) continue;
    K::FT area2 = 0;
    for (std::size_t i = 0; i < ring.size(); ++i) {
      const KPoint& a = ring[i];
      const KPoint& b = ring[(i + 1) % ring.size()];
      area2 += a.x() * b.y() - b.x() * a.y();
    }
    cell.area = CGAL::to_double(area2) / 2;
    for (const KPoint& p : ring) cell.polygon.vertices.push_back(ToPoint(p));
    out.cells.push_back(std::move(cell));
  }
  std::sort(out.cells.begin(), out.cells.end(), [](const ViewingCell& a, const ViewingCell& b) {
    if (a.area != b.area) return a.area > b.area;
    if (a.sample.x() != b.sample.x()) return a.sample.x() < b.sample.x();
    return a.sample.y() < b.sample.y();
  });
  std::map<std::vector<ViewVertex>, int> views;
  for (ViewingCell& cell : out.cells) {
    const auto [it, added] = views.emplace(ViewFrom(scene, cell.sample, camera_height), static_cast<int>(views.size()));
    cell.view = it->second;
  }
  out.views = static_cast<int>(views.size());
  return out;
}

std::vector<ViewVertex> ViewFrom(const Scene& scene, const Point& p, std::optional<double> camera_height) {
  // Three closed sectors of 125 degrees cover the circle (they overlap): the union of what each sees.
  Scene probe = scene;
  std::vector<ViewVertex> view;
  for (double first : {0.0, 120.0, 240.0}) {
    probe.camera = MakePlanarCamera(p, first, 125.0);
    probe.camera->height = camera_height;
    for (const UnoccludedVertex& u : FindUnoccludedVertices(probe)) {
      view.push_back({u.obstacle, u.vertex, u.cm[0], u.cm[1]});
    }
  }
  std::sort(view.begin(), view.end());
  view.erase(std::unique(view.begin(), view.end()), view.end());
  return view;
}

bool RanksBefore(const CameraEvaluation& a, const CameraEvaluation& b) {
  if (a.feasible != b.feasible) return a.feasible;
  if (a.feasible && a.steps != b.steps) return a.steps < b.steps;
  if (a.min_interval_deg != b.min_interval_deg) return a.min_interval_deg > b.min_interval_deg;
  if (a.preimage_area != b.preimage_area) return a.preimage_area > b.preimage_area;
  if (a.coverage != b.coverage) return a.coverage > b.coverage;
  if (a.center.x() != b.center.x()) return a.center.x() < b.center.x();
  return a.center.y() < b.center.y();
}

Camera AimedCamera(const Point& center, const Point& aim, double fov_deg, std::optional<double> height) {
  const Vector d = aim - center;
  const double middle = d.squaredNorm() > 0 ? std::atan2(d.y(), d.x()) * 180.0 / kPi : 0.0;
  Camera camera = MakePlanarCamera(center, middle - fov_deg / 2, fov_deg);
  camera.height = height;
  return camera;
}

Point DefaultAim(const Scene& scene) {
  if (!scene.start) throw InputError(scene.source, "start", "placing a camera needs a start region");
  auto average = [](const Polygon& p) {
    Point s(0, 0);
    for (const Point& v : p.vertices) s += v;
    return Point(s / static_cast<double>(p.size()));
  };
  return (average(scene.start->polygon) + average(scene.goal.polygon)) / 2;
}

std::vector<CameraEvaluation> EvaluateCameras(const Scene& scene, const std::vector<std::optional<Camera>>& cameras,
                                              const CameraSearchOptions& options) {
  std::vector<CameraEvaluation> out(cameras.size());
  auto evaluate = [&](std::size_t i) {
    CameraEvaluation& e = out[i];
    Scene s = scene;
    s.camera = cameras[i];
    if (cameras[i]) {
      e.center = cameras[i]->center;
      e.fov_first_deg = cameras[i]->fov_first_rad * 180.0 / kPi;
      e.fov_span_deg = (cameras[i]->fov_second_rad - cameras[i]->fov_first_rad) * 180.0 / kPi;
      for (std::size_t k = 0; k < scene.obstacles.size(); ++k) {
        if (Locate(scene.obstacles[k].shape.polygon, e.center) == Location::kInside) {
          e.reason = "the centre lies inside obstacle " + scene.obstacles[k].id;
          return;
        }
      }
    }
    PlanOptions plan;
    plan.max_steps = options.max_steps;
    plan.max_nondirectional = options.max_backprojections;
    plan.use_camera = cameras[i].has_value();
    plan.threads = 1;
    const auto t0 = std::chrono::steady_clock::now();
    const Strategy strategy = PlanStrategy(s, plan);
    e.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    e.feasible = strategy.feasible;
    e.reason = strategy.reason;
    if (strategy.feasible) {
      e.steps = static_cast<int>(strategy.steps.size());
      e.min_interval_deg = 360.0;
      for (const StrategyStep& step : strategy.steps) {
        e.min_interval_deg = std::min(e.min_interval_deg, (step.interval_hi - step.interval_lo) * 180.0 / kPi);
      }
      e.preimage_area = strategy.steps.front().preimage.area;
      e.coverage = 1.0;
    } else {
      e.coverage = strategy.best_coverage;
    }
  };
  const int threads = std::max(1, std::min<int>(options.threads, static_cast<int>(cameras.size())));
  std::atomic<std::size_t> next{0};
  std::atomic<int> done{0};
  std::mutex mutex;
  std::exception_ptr error;
  auto worker = [&] {
    for (std::size_t i = next++; i < cameras.size(); i = next++) {
      try {
        evaluate(i);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(mutex);
        if (!error) error = std::current_exception();
        next = cameras.size();
        return;
      }
      const int d = ++done;
      if (options.progress) {
        const std::lock_guard<std::mutex> lock(mutex);
        options.progress(d, static_cast<int>(cameras.size()));
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
  worker();
  for (std::thread& t : pool) t.join();
  if (error) std::rethrow_exception(error);
  return out;
}

std::vector<Point> GridCandidates(const Scene& scene, const Point& min, const Point& max, double h) {
  if (!(h > 0) || !std::isfinite(h)) throw InputError("command line", "--grid", "the spacing must be positive");
  const Vector size = max - min;
  const int nx = static_cast<int>(std::floor(size.x() / h)) + 1;
  const int ny = static_cast<int>(std::floor(size.y() / h)) + 1;
  if (static_cast<double>(nx) * ny > 1e6) throw InputError("command line", "--grid", "over a million grid points");
  const Point origin = min + Vector((size.x() - (nx - 1) * h) / 2, (size.y() - (ny - 1) * h) / 2);
  std::vector<Point> out;
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      const Point p = origin + Vector(i * h, j * h);
      const bool free = std::none_of(scene.obstacles.begin(), scene.obstacles.end(), [&](const Obstacle& o) {
        return Locate(o.shape.polygon, p) != Location::kOutside;
      });
      if (free) out.push_back(p);
    }
  }
  return out;
}

}  // namespace visco::planning

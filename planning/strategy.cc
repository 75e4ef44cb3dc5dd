#include "planning/strategy.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <set>
#include <thread>
#include <utility>

#include "common/error.h"
#include "common/motion_model.h"
#include "planning/cspace.h"
#include "planning/nondirectional.h"
#include "planning/scene_problem.h"
#include "planning/vc_rays.h"

namespace visco::planning {
namespace {

using Eigen::Vector2d;

double Deg(double rad) { return rad * 180.0 / M_PI; }

// The parameters t in [0, 1] of segment [a, b] that lie inside the region (closed, within `tolerance`), as maximal
// intervals.
std::vector<std::pair<double, double>> InsidePieces(const Region& region, const Vector2d& a, const Vector2d& b,
                                                    double tolerance) {
  std::vector<double> cuts = {0.0, 1.0};
  const Vector2d d = b - a;
  auto ring = [&](const RegionRing& r) {
    for (size_t i = 0; i < r.vertices.size(); ++i) {
      const Vector2d p = r.vertices[i], q = r.vertices[(i + 1) % r.vertices.size()];
      const Vector2d f = q - p;
      const double den = d.x() * f.y() - d.y() * f.x();
      if (std::abs(den) < 1e-300) continue;
      const Vector2d w = p - a;
      const double t = (w.x() * f.y() - w.y() * f.x()) / den, u = (w.x() * d.y() - w.y() * d.x()) / den;
      if (t > 0 && t < 1 && u >= 0 && u <= 1) cuts.push_back(t);
    }
  };
  for (const auto& poly : region.polygons) {
    ring(poly.outer);
    for (const auto& h : poly.holes) ring(h);
  }
  std::sort(cuts.begin(), cuts.end());
  std::vector<std::pair<double, double>> out;
  for (size_t k = 0; k + 1 < cuts.size(); ++k) {
    if (cuts[k + 1] - cuts[k] < 1e-12) continue;
    const Vector2d m = a + 0.5 * (cuts[k] + cuts[k + 1]) * d;
    if (!(region.Contains(m) || region.BoundaryDistance(m) <= tolerance)) continue;
    if (!out.empty() && std::abs(out.back().second - cuts[k]) < 1e-12) {
      out.back().second = cuts[k + 1];
    } else {
      out.push_back({cuts[k], cuts[k + 1]});
    }
  }
  return out;
}

// The best interval: largest margin, then widest, then smallest lo (deterministic).
const ThetaInterval* Best(const std::vector<ThetaInterval>& v) {
  const ThetaInterval* best = nullptr;
  for (const auto& i : v) {
    if (!best || i.margin > best->margin + 1e-12 ||
        (std::abs(i.margin - best->margin) <= 1e-12 && i.hi - i.lo > best->hi - best->lo + 1e-12)) {
      best = &i;
    }
  }
  return best;
}

// A target of the backchaining: what a step must end in, its backprojection problem and nondirectional
// backprojection, and the steps that follow it to the goal.
struct Node {
  Termination terminate = Termination::kGoal;
  std::string ref;                     // vc: the ray whose strip this is; contact: the face or corner
  std::vector<NamedPolygon> triggers;  // vc: strips around all of the ray's free segments (reaching one stops it)
  Vector2d end_a{0, 0}, end_b{0, 0};   // vc, contact: the piece where the step must end
  double end_radius = 0.0;             // ... within this distance of it
  // contact: the step into this target may only use θ in [range_lo, range_hi] (where the feature sticks).
  bool restricted = false;
  double range_lo = 0.0, range_hi = 0.0;
  BackprojectionProblem problem;
  NondirectionalBackprojection nd;
  bool vc = true;                  // the step into this target may comply to rays
  std::vector<StrategyStep> rest;  // the steps after the step into this target
};

StrategyStep MakeStep(const Node& node, const ThetaInterval& interval, const std::string& what_fits) {
  StrategyStep step;
  step.theta = WrapAngle(interval.best_theta);
  const Slice& slice = SliceAt(node.nd, step.theta);
  if (node.vc) step.active_rays = slice.vc.active_rays;
  BackprojectionProblem p = node.problem;
  p.theta = step.theta;
  step.preimage = node.vc ? BackprojectionWithActiveRays(p, step.active_rays) : ClassicBackprojection(p);
  step.terminate = node.terminate;
  step.terminate_ref = node.ref;
  step.target = node.problem.goal;
  step.triggers = node.triggers;
  step.end_a = node.end_a;
  step.end_b = node.end_b;
  step.end_radius = node.end_radius;
  step.sticks_lo = node.range_lo;
  step.sticks_hi = node.range_hi;
  step.interval_lo = interval.lo;
  step.interval_hi = interval.hi;
  step.margin = interval.margin;
  if (node.terminate == Termination::kGoal) {
    step.guarantee = fmt::format(
        "from anywhere in the preimage (it contains {} for every θ in [{:.2f}°, {:.2f}°]), every motion the "
        "uncertainty allows reaches the goal kernel: the sensed position is then inside the goal and the step ends",
        what_fits, Deg(interval.lo), Deg(interval.hi));
  } else if (node.terminate == Termination::kContact) {
    const std::string where =
        node.end_a == node.end_b
            ? fmt::format("in the corner at ({:.4f}, {:.4f}) or on its faces within {:.4f} m of it", node.end_a.x(),
                          node.end_a.y(), node.end_radius)
            : fmt::format("on the face between ({:.4f}, {:.4f}) and ({:.4f}, {:.4f})", node.end_a.x(), node.end_a.y(),
                          node.end_b.x(), node.end_b.y());
    step.guarantee = fmt::format(
        "from anywhere in the preimage (it contains {} for every θ in [{:.2f}°, {:.2f}°]), every motion the "
        "uncertainty allows reaches CB's {} and sticks there, {} (for θ in [{:.2f}°, {:.2f}°] the whole velocity cone "
        "lies in the friction cone there); the step ends when the robot stops in contact, and all of those places lie "
        "inside the next step's preimage",
        what_fits, Deg(interval.lo), Deg(interval.hi), node.end_a == node.end_b ? "corner" : "face", where,
        Deg(node.range_lo), Deg(node.range_hi));
  } else {
    step.guarantee = fmt::format(
        "from anywhere in the preimage (it contains {} for every θ in [{:.2f}°, {:.2f}°]), every motion reaches "
        "CVC ray {} first between ({:.4f}, {:.4f}) and ({:.4f}, {:.4f}) (the rest of the ray is never reached first); "
        "the step ends when the CM vertex crosses the VC line there, and that piece of the ray, widened by {} m, lies "
        "inside the next step's preimage",
        what_fits, Deg(interval.lo), Deg(interval.hi), node.ref, node.end_a.x(), node.end_a.y(), node.end_b.x(),
        node.end_b.y(), kVcStripHalfWidth);
  }
  return step;
}

// Share of R (sampled on a grid) inside the region.
double Coverage(const Region& region, const std::vector<Vector2d>& r) {
  Vector2d lo = r[0], hi = r[0];
  for (const auto& v : r) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
  Region poly;
  RegionPolygon rp;
  rp.outer.vertices = r;
  rp.outer.edges.resize(r.size());
  poly.polygons.push_back(rp);
  int in = 0, total = 0;
  for (int i = 0; i < 24; ++i) {
    for (int j = 0; j < 24; ++j) {
      const Vector2d q(lo.x() + (i + 0.5) / 24 * (hi.x() - lo.x()), lo.y() + (j + 0.5) / 24 * (hi.y() - lo.y()));
      if (!poly.Contains(q)) continue;
      ++total;
      in += region.Contains(q);
    }
  }
  return total ? static_cast<double>(in) / total : 0.0;
}

// θ unwrapped to [lo, lo + 2π): inside [lo, hi]?
bool InRange(double theta, double lo, double hi) {
  const double t = lo + std::fmod(std::fmod(theta - lo, 2 * M_PI) + 2 * M_PI, 2 * M_PI);
  return t <= hi;
}

// The parts of the intervals inside [lo, hi] (hi - lo < 2π), each with its margin at its midpoint (containment does
// not change inside an interval).
std::vector<ThetaInterval> Restrict(const std::vector<ThetaInterval>& in, double lo, double hi, const Node& node,
                                    const NamedPolygon& region) {
  std::vector<ThetaInterval> out;
  const double size = (node.problem.bounds_max - node.problem.bounds_min).norm();
  for (const auto& i : in) {
    for (int k = -2; k <= 2; ++k) {
      const double a = std::max(i.lo, lo + 2 * M_PI * k), b = std::min(i.hi, hi + 2 * M_PI * k);
      if (b - a <= 1e-9) continue;
      const double mid = WrapAngle(0.5 * (a + b));
      BackprojectionProblem p = node.problem;
      p.theta = mid;
      const Region reg =
          node.vc ? BackprojectionWithActiveRays(p, SliceAt(node.nd, mid).vc.active_rays) : ClassicBackprojection(p);
      double clear = 0;
      if (!RegionContainsPolygon(reg, region.vertices, 1e-9 * size, &clear)) continue;
      out.push_back({a, b, clear, mid});
    }
  }
  return out;
}

// The θ-intervals where `region` lies inside the node's preimage (only where the node's own step may run).
std::vector<ThetaInterval> Fits(const Node& node, const NamedPolygon& region) {
  const auto intervals = IntervalsContaining(node.nd, node.problem, region, node.vc);
  return node.restricted ? Restrict(intervals, node.range_lo, node.range_hi, node, region) : intervals;
}

// A place where a motion can stick: a face of CB (a maximal straight run of its boundary, CB on its left) or a
// concave corner of CB (two faces meeting with free space inside an angle below π), and the θ where it sticks for
// the whole velocity cone (the friction model of docs/semantics.md).
struct ContactFeature {
  bool corner = false;
  Vector2d a{0, 0}, b{0, 0};         // face: from a to b; corner: a = b = the corner
  Vector2d u_in{0, 0}, u_out{0, 0};  // corner: unit directions along its two faces, away from it
  double lo = 0.0, hi = 0.0;         // θ where it sticks, lo < hi
  std::string ref;
};

Vector2d LeftNormal(const Vector2d& d) { return Vector2d(-d.y(), d.x()).normalized(); }

// Turn at v (p -> v -> q): +1 left, -1 right, 0 straight (relative tolerance: the union's vertices are rounded, and a
// face split where its generator changes must stay one face).
int Turn(const Vector2d& p, const Vector2d& v, const Vector2d& q) {
  const Vector2d d1 = v - p, d2 = q - v;
  const double c = d1.x() * d2.y() - d1.y() * d2.x();
  if (std::abs(c) <= 1e-12 * d1.norm() * d2.norm()) return d1.dot(d2) > 0 ? 0 : (c >= 0 ? 1 : -1);
  return c > 0 ? 1 : -1;
}

std::vector<ContactFeature> ContactFeatures(const CSpace& cspace, double velocity_cone, double friction_cone) {
  std::vector<ContactFeature> out;
  const auto& polys = cspace.obstacle_union();
  const auto& sources = cspace.obstacle_union_sources();
  // Every boundary edge of CB, to tell a corner from a pinch: where two C-obstacles touch at a point, the boundary
  // passes there twice, and free space goes on through the point on the other side. A motion sliding into the
  // corner that one pass makes can leave through it (the motion model's contact rules see all four faces), so
  // it is no place where motions stop (random scene 11 at VISCO_SEED_OFFSET=56000: every start of a contact step
  // "sticking" in such a corner slid on through it and out of the bounds).
  std::vector<std::pair<Vector2d, Vector2d>> edges;
  double extent = 0.0;
  for (const auto& poly : polys) {
    std::vector<const Polygon*> rings = {&poly.outer};
    for (const auto& hole : poly.holes) rings.push_back(&hole);
    for (const Polygon* r : rings) {
      for (size_t i = 0; i < r->size(); ++i) {
        edges.emplace_back(r->Vertex(i), r->Vertex(i + 1));
        extent = std::max(extent, r->Vertex(i).cwiseAbs().maxCoeff());
      }
    }
  }
  const double touch = 1e-9 * std::max(extent, 1.0);
  // Whether a boundary edge other than (p, v) and (v, q) passes through v.
  auto pinch = [&](const Vector2d& p, const Vector2d& v, const Vector2d& q) {
    return std::any_of(edges.begin(), edges.end(), [&](const auto& e) {
      const bool own = (e.first == p && e.second == v) || (e.first == v && e.second == q);
      return !own && PointSegmentDistance(v, e.first, e.second) <= touch;
    });
  };
  auto ring = [&](const Polygon& r, const RingSources* src) {
    const size_t n = r.size();
    if (n < 3) return;
    size_t first = n;
    for (size_t i = 0; i < n && first == n; ++i) {
      if (Turn(r.Vertex(i + n - 1), r.Vertex(i), r.Vertex(i + 1)) != 0) first = i;
    }
    if (first == n) return;
    for (size_t k = 0; k < n; ++k) {
      const size_t i = (first + k) % n;
      const Vector2d p = r.Vertex(i + n - 1), v = r.Vertex(i), q = r.Vertex(i + 1);
      const int turn = Turn(p, v, q);
      if (turn == 0) continue;
      const std::string vref = src && i < src->vertex_refs.size() ? src->vertex_refs[i] : fmt::format("v({})", i);
      // The face that starts at v runs to the next vertex where the boundary turns.
      size_t j = i + 1;
      while (j < i + n && Turn(r.Vertex(j - 1), r.Vertex(j), r.Vertex(j + 1)) == 0) ++j;
      if (friction_cone > velocity_cone) {
        ContactFeature f;
        f.a = v;
        f.b = r.Vertex(j);
        const Vector2d m = LeftNormal(q - v);  // into CB
        const double at = std::atan2(m.y(), m.x());
        f.lo = at - (friction_cone - velocity_cone);
        f.hi = at + (friction_cone - velocity_cone);
        f.ref = "face:" + (src && i < src->edges.size() ? src->edges[i].ref : fmt::format("e({})", i));
        out.push_back(std::move(f));
      }
      if (turn < 0 && !pinch(p, v, q)) {
        // Free space turns left at v: the reaction can be anything in the hull of the two faces' friction cones.
        const Vector2d m1 = LeftNormal(v - p), m2 = LeftNormal(q - v);
        const double a2 = std::atan2(m2.y(), m2.x());
        double a1 = std::atan2(m1.y(), m1.x());
        while (a1 < a2) a1 += 2 * M_PI;
        ContactFeature f;
        f.corner = true;
        f.a = f.b = v;
        f.u_in = (p - v).normalized();
        f.u_out = (q - v).normalized();
        f.lo = a2 - friction_cone + velocity_cone;
        f.hi = a1 + friction_cone - velocity_cone;
        f.ref = "corner:" + vref;
        if (f.hi > f.lo && f.hi - f.lo < 2 * M_PI) out.push_back(std::move(f));
      }
    }
  };
  for (size_t k = 0; k < polys.size(); ++k) {
    const PolygonSources* src = k < sources.size() ? &sources[k] : nullptr;
    ring(polys[k].outer, src ? &src->outer : nullptr);
    for (size_t h = 0; h < polys[k].holes.size(); ++h)
      ring(polys[k].holes[h], src && h < src->holes.size() ? &src->holes[h] : nullptr);
  }
  return out;
}

// Drops from a child's nondirectional backprojection what the search never reads again (a child's step complies
// to no ray, so only its B_θ regions matter): the VC regions, the structures and ray lists, the orientations' refs,
// the regions' edge provenance strings. Kept: each slice's θ, interval and B_θ region with each edge's kind, line,
// source and sign (what carrying a region to another θ, containment and clearance read).
void KeepWhatTheSearchReads(NondirectionalBackprojection& nd) {
  nd.orientations.clear();
  nd.orientations.shrink_to_fit();
  nd.stats.unexplained_at.clear();
  nd.stats.unexplained_at.shrink_to_fit();
  for (Slice& slice : nd.slices) {
    slice.structure = SliceStructure{};
    Region classic = std::move(slice.vc.classic);
    slice.vc = VcBackprojection{};
    for (RegionPolygon& poly : classic.polygons) {
      auto lean = [](RegionRing& ring) {
        for (RegionEdge& e : ring.edges) std::string().swap(e.ref);
        ring.vertices.shrink_to_fit();
        ring.edges.shrink_to_fit();
      };
      lean(poly.outer);
      for (RegionRing& h : poly.holes) lean(h);
    }
    slice.vc.classic = std::move(classic);
  }
  nd.slices.shrink_to_fit();
}

NondirectionalOptions NdOptions(const PlanOptions& o) {
  NondirectionalOptions n;
  n.threads = o.threads;
  return n;
}

// The memory limit, watched while the search runs: with a limit, a thread of its own reads the resident memory every
// 20 ms, keeps the peak and, past the limit, sets the flag that ends the nondirectional backprojection in flight at its
// next sweep (NondirectionalOptions::stop). One sweep and one period are the most the search can overrun it by.
class MemoryWatch {
 public:
  MemoryWatch(double limit_mib, std::function<double()> read)
      : limit_mib_(limit_mib), read_(read ? std::move(read) : std::function<double()>(ResidentMemoryMiB)) {
    Sample();
    if (limit_mib_ > 0) thread_ = std::thread([this] { Run(); });
  }
  MemoryWatch(const MemoryWatch&) = delete;
  MemoryWatch& operator=(const MemoryWatch&) = delete;
  ~MemoryWatch() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      finished_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
  }
  // Reads the resident memory now; sets the flag past the limit.
  void Sample() {
    const double mib = read_();
    double peak = peak_mib_.load();
    while (mib > peak && !peak_mib_.compare_exchange_weak(peak, mib)) {
    }
    if (limit_mib_ > 0 && mib > limit_mib_) exceeded_.store(true);
  }
  bool Exceeded() const { return exceeded_.load(); }
  const std::atomic<bool>* Flag() const { return &exceeded_; }
  double PeakMiB() const { return peak_mib_.load(); }

 private:
  void Run() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!wake_.wait_for(lock, std::chrono::milliseconds(20), [&] { return finished_; })) Sample();
  }
  const double limit_mib_;
  const std::function<double()> read_;
  std::atomic<bool> exceeded_{false};
  std::atomic<double> peak_mib_{0.0};
  std::mutex mutex_;
  std::condition_variable wake_;
  bool finished_ = false;
  std::thread thread_;
};

}  // namespace

NamedPolygon Strip(const Vector2d& a, const Vector2d& b, double half_width, const std::string& ref) {
  return Strip(a, b, half_width, ref, b - a);
}

NamedPolygon Strip(const Vector2d& a, const Vector2d& b, double half_width, const std::string& ref,
                   const Vector2d& direction) {
  const Vector2d d = direction.normalized();
  const Vector2d n(-d.y() * half_width, d.x() * half_width);
  NamedPolygon p;
  p.vertices = {a - n, b - n, b + n, a + n};
  for (int k = 0; k < 4; ++k) {
    p.vertex_refs.push_back(ref + ".v[" + std::to_string(k) + "]");
    p.edge_refs.push_back(ref + ".e[" + std::to_string(k) + "]");
  }
  return p;
}

double ResidentMemoryMiB() {
  std::ifstream statm("/proc/self/statm");
  double pages_total = 0, pages_resident = 0;
  if (!(statm >> pages_total >> pages_resident)) return 0.0;
  return pages_resident * static_cast<double>(sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0);
}

const char* TerminationName(Termination t) {
  switch (t) {
    case Termination::kGoal:
      return "goal";
    case Termination::kVisualGuarded:
      return "vc";
    case Termination::kContact:
      return "contact";
  }
  return "?";
}

Strategy PlanStrategy(const Scene& scene, const PlanOptions& options) {
  if (!scene.start) throw InputError(scene.source, "start", "planning needs a start region");
  if (options.max_steps < 1) throw InputError("command line", "--max-steps", "must be at least 1");
  const CSpace cspace(scene);
  const bool camera = options.use_camera && scene.camera.has_value();
  VcRays rays;
  if (camera) rays = ComputeVcRays(scene, cspace);
  const BackprojectionProblem base = ProblemFromScene(scene, cspace, camera ? &rays : nullptr, 0.0, /*kernel=*/true);
  if (base.goal.empty()) {  // infeasible like any scene without a strategy: `visco plan` writes why
    Strategy none;
    none.reason = kEmptyGoalKernel;
    return none;
  }
  NamedPolygon start;
  start.vertices = scene.start->polygon.vertices;
  Strategy out;
  auto progress = [&](double f) {
    if (options.progress) options.progress(std::clamp(f, 0.0, 1.0));
  };

  const auto search_start = std::chrono::steady_clock::now();
  auto seconds = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - search_start).count(); };
  if (options.search_progress) {
    PlanProgress p;
    p.max_steps = options.max_steps;
    options.search_progress(p);
  }
  // The last step: goal termination, preimage B_vcθ(kernel).
  Node goal;
  goal.terminate = Termination::kGoal;
  goal.problem = base;
  goal.vc = camera;
  MemoryWatch memory(options.max_memory_mib, options.resident_memory_mib);
  NondirectionalOptions goal_options = NdOptions(options);
  goal_options.stop = memory.Flag();
  try {
    goal.nd = ComputeNondirectional(base, nullptr, goal_options);
  } catch (const NondirectionalStopped&) {
    out.memory_limit_reached = true;
    out.peak_memory_mib = memory.PeakMiB();
    out.reason = fmt::format(
        "the search stopped at the memory limit ({:.0f} MiB in use, --max-memory {:.0f} MiB) while computing the "
        "goal's preimage over all θ (the one-step strategies): no strategy",
        out.peak_memory_mib, options.max_memory_mib);
    return out;
  }
  ++out.nondirectional;
  out.goal_seconds = seconds();
  out.goal_sweeps = goal.nd.stats.backprojections;
  progress(0.2);
  {
    const auto intervals = IntervalsContaining(goal.nd, base, start, goal.vc);
    if (const ThetaInterval* best = Best(intervals)) {
      out.feasible = true;
      out.steps.push_back(MakeStep(goal, *best, "the start region"));
      memory.Sample();
      out.peak_memory_mib = memory.PeakMiB();
      progress(1.0);
      return out;
    }
  }
  // Diagnostics: the largest share of R that one step covers.
  for (const Slice& s : goal.nd.slices) {
    const double c = Coverage(goal.vc ? s.vc.region : s.vc.classic, start.vertices);
    if (c > out.best_coverage) out.best_coverage = c, out.best_theta = s.theta;
  }

  // Earlier steps: visual guarded termination on a ray whose free segments all fit the next preimage, or contact
  // termination on a face or corner of CB whose sticking places all fit it.
  const std::vector<ContactFeature> features = ContactFeatures(cspace, base.velocity_cone, base.friction_cone);
  std::vector<Node> frontier = {std::move(goal)};
  std::set<std::string> used;
  bool budget_reached = false;
  struct Candidate {
    std::vector<StrategyStep> steps;
    double margin;
  };
  const double size = (base.bounds_max - base.bounds_min).norm();
  // f(region) for the preimage of each of the node's slices where its step may run (its θ-range).
  auto for_each_preimage = [](const Node& node, const auto& f) {
    for (const Slice& sl : node.nd.slices) {
      if (node.restricted && !InRange(sl.theta, node.range_lo, node.range_hi)) continue;
      f(node.vc ? sl.vc.region : sl.vc.classic);
    }
  };
  // The longest piece of segment [a, b] inside one of the node's slices.
  auto longest_piece = [&](const Node& node, const Vector2d& a, const Vector2d& b, Vector2d& pa, Vector2d& pb) {
    double best_len = 0;
    for_each_preimage(node, [&](const Region& region) {
      for (const auto& [t0, t1] : InsidePieces(region, a, b, 1e-9 * size)) {
        const Vector2d x = a + t0 * (b - a), y = a + t1 * (b - a);
        if ((y - x).norm() > best_len) best_len = (y - x).norm(), pa = x, pb = y;
      }
    });
    return best_len;
  };
  const bool lean = options.search == SearchMode::kLean;
  memory.Sample();
  bool memory_reached = false;
  int stopped_level = 0;
  std::int64_t stopped_done = 0, stopped_total = 0;
  // The candidates the C-obstacles and bounds make among themselves, the same for every child (listed at the first
  // level with children; the search before lists them per child, kept to compare).
  std::shared_ptr<const StaticCandidates> static_candidates;
  for (int level = 2; level <= options.max_steps && !options.kernel_only && !budget_reached; ++level) {
    out.levels = level;
    std::vector<Node> next;
    std::vector<Candidate> found;
    // The level's child targets, in the order the search meets them: a child of `node` (its target `child.ref` used
    // up) with the step into `node` that follows it. False, and nothing added, when the budget of backprojections is
    // spent. Their nondirectional backprojections are computed below, after the whole level is known (which children
    // there are depends only on the frontier and on what is used up, not on the children's own backprojections).
    std::vector<Node> pending;
    auto expand = [&](Node child, const Node& node, const ThetaInterval& fit, const std::string& what) {
      if (out.nondirectional + static_cast<std::int64_t>(pending.size()) >= options.max_nondirectional) {
        budget_reached = true;
        return false;
      }
      used.insert(child.ref);
      child.rest = node.rest;
      child.rest.insert(child.rest.begin(), MakeStep(node, fit, what));
      pending.push_back(std::move(child));
      return true;
    };
    for (size_t f = 0; f < frontier.size() && !budget_reached; ++f) {
      const Node& node = frontier[f];
      for (const CvcRayInput& ray : base.rays) {
        if (!camera || used.count(ray.id) || ray.id == node.ref) continue;
        // The longest piece of the ray inside one of the node's slices, shrunk at its ends so that its strip fits;
        // then the θ-interval where that strip lies inside the node's preimage.
        double best_len = 0;
        Vector2d pa{0, 0}, pb{0, 0};
        size_t best_seg = 0;
        for (size_t k = 0; k < ray.segments.size(); ++k) {
          Vector2d x, y;
          const double len = longest_piece(node, ray.segments[k][0], ray.segments[k][1], x, y);
          if (len > best_len) best_len = len, pa = x, pb = y, best_seg = k;
        }
        const double shrink = 3 * kVcStripHalfWidth;
        if (best_len < 4 * shrink) continue;
        const Vector2d dir = (pb - pa) / best_len;
        const Vector2d ea = pa + shrink * dir, eb = pb - shrink * dir;
        // Every strip on the piece's segment is squared to the segment's direction, so that the goal strip and the
        // forbidden rest beside it share their corners exactly.
        const Vector2d seg_dir = ray.segments[best_seg][1] - ray.segments[best_seg][0];
        const NamedPolygon end_strip = Strip(ea, eb, kVcStripHalfWidth, ray.id + ".end", seg_dir);
        const std::vector<ThetaInterval> fits = Fits(node, end_strip);
        const ThetaInterval* best = Best(fits);
        if (!best) continue;
        Node child;
        child.terminate = Termination::kVisualGuarded;
        child.ref = ray.id;
        child.problem = base;
        child.problem.goal = {end_strip};
        child.end_a = ea;
        child.end_b = eb;
        child.end_radius = kVcStripHalfWidth;
        // The rest of the ray (every free segment, outside the piece): reaching it first ends the step outside the
        // piece, so it is forbidden, right up to the piece's strip. (It used to start 1.5 cm away, and the executor's
        // event fires in that gap as anywhere on the ray: a motion the planner let pass through it stopped there,
        // 1 cm beside the line and outside the target, VISCO_SEED_OFFSET=168000, random scene 5.)
        for (size_t k = 0; k < ray.segments.size(); ++k) {
          const auto& seg = ray.segments[k];
          child.triggers.push_back(Strip(seg[0], seg[1], kVcStripHalfWidth, ray.id + ".strip"));
          const Vector2d d = seg[1] - seg[0];
          const double len = d.norm();
          // The piece's parameters on this segment (if it lies on it).
          const double ta = (ea - seg[0]).dot(d) / (len * len), tb = (eb - seg[0]).dot(d) / (len * len);
          const bool on = std::abs((ea - seg[0]).x() * d.y() - (ea - seg[0]).y() * d.x()) <= 1e-9 * size * len &&
                          ta >= -1e-9 && tb <= 1 + 1e-9;
          // The rest pieces end exactly at the piece's ends (ea, eb), on the segment's direction like the piece.
          std::vector<std::pair<Vector2d, Vector2d>> rest;
          if (on) {
            const bool forward = ta <= tb;
            rest = {{seg[0], forward ? ea : eb}, {forward ? eb : ea, seg[1]}};
          } else {
            rest = {{seg[0], seg[1]}};
          }
          for (const auto& [r0, r1] : rest) {
            if ((r1 - r0).dot(d) <= 1e-9 * size * len) continue;
            child.problem.forbidden.push_back(
                Strip(r0, r1, kVcStripHalfWidth, ray.id + ".rest" + std::to_string(child.problem.forbidden.size()), d));
          }
        }
        // The guarded motion towards the ray complies to no ray (its own would carry it along, others could carry it
        // past the strip).
        child.problem.rays.clear();
        child.vc = false;
        if (!expand(std::move(child), node, *best, "the piece of ray " + ray.id + " where the step before ends")) break;
      }
      // Contact: corners first (they end the motion in the least room), then faces, longest piece first.
      struct ContactCandidate {
        const ContactFeature* feature;
        Vector2d pa, pb;
        double len;
      };
      std::vector<ContactCandidate> contacts;
      const double w = kContactDepth, tan_phi = std::tan(base.friction_cone);
      const double face_shrink = w * (2 + tan_phi);
      for (const ContactFeature& feature : features) {
        if (budget_reached || used.count(feature.ref)) continue;
        Vector2d pa = feature.a, pb = feature.b;
        if (feature.corner) {
          bool inside = false;
          for_each_preimage(node, [&](const Region& region) {
            inside = inside || region.Contains(feature.a) || region.BoundaryDistance(feature.a) <= 1e-9 * size;
          });
          if (inside) contacts.push_back({&feature, pa, pb, 0.0});
        } else {
          const double len = longest_piece(node, feature.a, feature.b, pa, pb);
          if (len >= 2 * face_shrink + w) contacts.push_back({&feature, pa, pb, len});
        }
      }
      std::stable_sort(contacts.begin(), contacts.end(), [](const ContactCandidate& x, const ContactCandidate& y) {
        if (x.feature->corner != y.feature->corner) return x.feature->corner;
        return x.len > y.len + 1e-12;
      });
      if (contacts.size() > static_cast<size_t>(std::max(0, options.max_contact_features)))
        contacts.resize(static_cast<size_t>(std::max(0, options.max_contact_features)));
      for (const ContactCandidate& cc : contacts) {
        const ContactFeature& feature = *cc.feature;
        NamedPolygon ends, target;
        Node child;
        if (feature.corner) {
          // Entering the target square (half-width w), the motion sticks on a face within w√2 (1 + tan φ) of the
          // corner: the parallelogram the two faces span to that length must fit.
          const double reach = w * std::sqrt(2.0) * (1 + tan_phi) * 1.01;
          const Vector2d c = feature.a;
          ends.vertices = {c, c + reach * feature.u_out, c + reach * (feature.u_out + feature.u_in),
                           c + reach * feature.u_in};
          target.vertices = {c + Vector2d(-w, -w), c + Vector2d(w, -w), c + Vector2d(w, w), c + Vector2d(-w, w)};
          child.end_a = child.end_b = c;
          child.end_radius = reach;
        } else {
          // Entering the target strip (depth w), the motion sticks on the face within w tan φ of where it entered:
          // the piece it can stick on, shrunk by that and more, stands for the target; the whole piece must fit.
          const Vector2d dir = (cc.pb - cc.pa) / cc.len, free_side(dir.y(), -dir.x());
          ends.vertices = {cc.pa, cc.pb, cc.pb + w * free_side, cc.pa + w * free_side};
          target = Strip(cc.pa + face_shrink * dir, cc.pb - face_shrink * dir, w, feature.ref + ".target");
          child.end_a = cc.pa;
          child.end_b = cc.pb;
          child.end_radius = 0.0;
        }
        const std::vector<ThetaInterval> fits = Fits(node, ends);
        const ThetaInterval* best = Best(fits);
        if (!best) continue;
        child.terminate = Termination::kContact;
        child.ref = feature.ref;
        child.problem = base;
        child.problem.goal = {target};
        child.problem.rays.clear();
        child.vc = false;
        child.restricted = true;
        child.range_lo = feature.lo;
        child.range_hi = feature.hi;
        if (!expand(std::move(child), node, *best,
                    std::string("the places where the step before sticks (") + feature.ref + ")"))
          break;
      }
    }
    // The children's nondirectional backprojections, and whether the start region fits each one's preimage.
    const bool last = level == options.max_steps;
    std::vector<std::optional<Candidate>> fits(pending.size());
    std::vector<char> computed(pending.size(), 0);
    std::atomic<std::size_t> next_child{0};
    std::atomic<bool> stop{false};  // a worker failed
    std::mutex mutex;
    std::condition_variable changed;
    std::size_t done = 0;
    const double level_start = seconds();
    auto report = [&] {
      progress(0.2 + 0.8 * (level - 2 + (pending.empty() ? 1.0 : static_cast<double>(done) / pending.size())) /
                         (options.max_steps - 1));
      if (!options.search_progress) return;
      PlanProgress p;
      p.level = level;
      p.max_steps = options.max_steps;
      p.done = static_cast<std::int64_t>(done);
      p.total = static_cast<std::int64_t>(pending.size());
      p.elapsed_s = seconds();
      if (done > 0) p.level_left_s = (p.elapsed_s - level_start) / done * (pending.size() - done);
      options.search_progress(p);
    };
    report();
    memory.Sample();
    const int workers =
        lean ? std::clamp(options.threads, 1, static_cast<int>(std::max<std::size_t>(pending.size(), 1))) : 1;
    NondirectionalOptions nd_options = NdOptions(options);
    if (lean) nd_options.threads = std::max(1, options.threads / workers);
    nd_options.stop = memory.Flag();
    if (lean && !pending.empty() && !static_candidates && !memory.Exceeded()) {
      try {
        static_candidates = ListStaticCandidates(base, options.threads, memory.Flag());
      } catch (const NondirectionalStopped&) {
        // the memory limit: the children stop at it below
      }
    }
    nd_options.static_candidates = static_candidates;
    auto work = [&] {
      for (;;) {
        if (stop.load() || memory.Exceeded()) return;
        const std::size_t i = next_child.fetch_add(1);
        if (i >= pending.size()) return;
        Node& child = pending[i];
        const double t0 = seconds();
        try {
          child.nd = ComputeNondirectional(child.problem, nullptr, nd_options);
        } catch (const NondirectionalStopped&) {
          return;  // the memory limit: this child is not computed
        }
        const double child_s = seconds() - t0;
        const std::int64_t child_sweeps = child.nd.stats.backprojections;
        const std::vector<ThetaInterval> start_fits = Fits(child, start);
        if (const ThetaInterval* st = Best(start_fits)) {
          Candidate c;
          c.steps = child.rest;
          c.steps.insert(c.steps.begin(), MakeStep(child, *st, "the start region"));
          c.margin = st->margin;
          fits[i] = std::move(c);
        }
        if (lean) {
          // What the next level reads of a child; the last level's children are never read again.
          if (last) {
            child.nd = NondirectionalBackprojection{};
          } else {
            KeepWhatTheSearchReads(child.nd);
          }
        }
        memory.Sample();
        std::lock_guard<std::mutex> lock(mutex);
        computed[i] = 1;
        ++done;
        out.children_seconds += child_s;
        out.slowest_child_seconds = std::max(out.slowest_child_seconds, child_s);
        out.children_sweeps += child_sweeps;
        changed.notify_all();
      }
    };
    {
      // `workers` threads compute; this one reports progress (from the calling thread, as the callback promises).
      std::exception_ptr error;
      int exited = 0;  // workers that have returned (all children taken, a failure or the memory limit)
      auto guarded = [&] {
        try {
          work();
        } catch (...) {
          std::lock_guard<std::mutex> lock(mutex);
          if (!error) error = std::current_exception();
          stop.store(true);
        }
        std::lock_guard<std::mutex> lock(mutex);
        ++exited;
        changed.notify_all();
      };
      std::vector<std::thread> threads;
      for (int t = 0; t < workers; ++t) threads.emplace_back(guarded);
      std::unique_lock<std::mutex> lock(mutex);
      std::size_t seen = 0;
      while (exited < workers) {
        changed.wait(lock, [&] { return done != seen || exited == workers; });
        seen = done;
        lock.unlock();
        report();
        lock.lock();
      }
      lock.unlock();
      for (auto& th : threads) th.join();
      if (error) std::rethrow_exception(error);
    }
    // In the order the children were met (the answer does not depend on the threads): the first found wins ties.
    for (std::size_t i = 0; i < pending.size(); ++i) {
      if (!computed[i]) break;
      ++out.nondirectional;
      ++out.children;
      if (fits[i]) found.push_back(std::move(*fits[i]));
      if (!lean || !last) next.push_back(std::move(pending[i]));
    }
    memory.Sample();
    if (memory.Exceeded()) {
      memory_reached = true;
      stopped_level = level;
      stopped_done = static_cast<std::int64_t>(done);
      stopped_total = static_cast<std::int64_t>(pending.size());
      break;
    }
    if (!found.empty()) {
      // Fewest steps (this level), then the largest margin; the first found wins ties (rays in id order, then
      // contact features in the order above).
      const Candidate* best = &found[0];
      for (const auto& c : found) {
        if (c.margin > best->margin + 1e-12) best = &c;
      }
      out.feasible = true;
      out.steps = best->steps;
      out.peak_memory_mib = memory.PeakMiB();
      progress(1.0);
      return out;
    }
    frontier = std::move(next);
    if (frontier.empty()) break;
  }
  out.reason = fmt::format(
      "no strategy within {} step(s): one step covers at most {:.0f}% of the start region (at θ = {:.1f}°){}",
      options.max_steps, 100 * out.best_coverage, Deg(out.best_theta),
      !scene.camera
          ? "; the scene has no camera: visual constraints (visco camera) or more steps (--max-steps) may help"
      : !camera             ? "; planned without the camera"
      : options.kernel_only ? "; only goal-terminated steps were allowed (--kernel-only)"
                            : "; more steps (--max-steps) or another camera position (visco camera) may help");
  if (budget_reached) {
    out.reason += fmt::format("; the search stopped after {} nondirectional backprojections (--max-backprojections)",
                              out.nondirectional);
  }
  out.peak_memory_mib = memory.PeakMiB();
  if (memory_reached) {
    out.memory_limit_reached = true;
    out.reason =
        fmt::format(
            "the search stopped at the memory limit ({:.0f} MiB in use, --max-memory {:.0f} MiB) while trying {} steps "
            "({} of that level's {} child targets done, {} nondirectional backprojections in all): no strategy within "
            "{} "
            "step(s); ",
            out.peak_memory_mib, options.max_memory_mib, stopped_level, stopped_done, stopped_total, out.nondirectional,
            stopped_level - 1) +
        out.reason;
  }
  progress(1.0);
  return out;
}

double StepTimeout(const Scene& scene, double speed) {
  return std::round(3.0 * (scene.bounds.max - scene.bounds.min).norm() / speed + 10.0);
}

}  // namespace visco::planning

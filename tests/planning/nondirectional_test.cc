// The critical orientations and the nondirectional backprojection (planning/critical.h, planning/nondirectional.h)
// on seeded random whole scenes that nobody designed (cameras anywhere and on the bounds, θ all around, ε_v 2-20°,
// non-convex and overlapping obstacles) and on every example scene:
//   * between two consecutive reported orientations the structure (classic and VC, holes included) does not change,
//     sampled at ¼, ½, ¾ of every interval, and no change is found where no candidate explains it;
//   * every reported orientation (R-critical aside) really changes the structure;
//   * each kind occurs and changes the structure somewhere;
//   * the kinetic method agrees with Donald's critical-slice baseline;
//   * points inside every slice's VC region survive the adversarial simulator;
//   * the intervals where a random region R fits are right at sampled θ.

#include "planning/nondirectional.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "common/motion_model.h"
#include "planning/area_profile.h"
#include "planning/critical.h"
#include "planning/cspace.h"
#include "planning/scene_file.h"
#include "planning/scene_problem.h"
#include "planning/strategy.h"
#include "planning/vc_rays.h"
#include "tests/bench/planning/pentagon_grid.h"
#include "tests/planning/random_scenes.h"
#include "tests/planning/random_vc_scenes.h"

namespace visco::planning {
namespace {

using Eigen::Vector2d;

struct Tally {
  int scenes = 0, intervals = 0, broken = 0, orientations = 0, changes = 0, not_changing = 0, unexplained = 0,
      found_by_probes = 0, rule_missed = 0, rule_missed_sliding = 0;
  // Regions carried from the open slice to ¼ and ¾ of its interval (RegionAt) against the sweep there: how many, the
  // worst distance of a swept vertex to the carried ones and back (relative to the scene's size) and of the areas.
  int carried = 0;
  double carried_vertex = 0, carried_area = 0;
  std::int64_t candidates = 0;
  std::set<std::string> kinds_changing;
  // How much the structure changes across each orientation that changes it (EditSize): the papers' Conjecture 1
  // expects a bounded local change (a vertex or an edge comes or goes). Size -> orientations.
  std::map<int, int> edit_sizes;
  std::map<std::string, std::map<int, int>> edit_sizes_by_kind;
};

// The size of the change between two structures: the edges (kind:ref) in one and not the other, counted as multisets
// over all rings of a region, plus the rings that come or go (a reordering that keeps every edge counts 2), the larger
// of the classic and the VC region's, plus the active rays that change. One edge coming or going is 1, one replaced by
// another 2.
std::string EditSizes(const Tally& t) {
  std::string s = "edges that come or go across a change (size: orientations):";
  for (const auto& [size, n] : t.edit_sizes) s += " " + std::to_string(size) + ": " + std::to_string(n);
  for (const auto& [kind, sizes] : t.edit_sizes_by_kind) {
    s += "\n  " + kind + ":";
    for (const auto& [size, n] : sizes) s += " " + std::to_string(size) + ": " + std::to_string(n);
  }
  return s;
}

int EditSize(const SliceStructure& a, const SliceStructure& b) {
  auto tokens = [](const std::vector<std::string>& rings, std::map<std::string, int>& count, int sign, int& nrings) {
    for (const auto& ring : rings) {
      std::istringstream in(ring);
      std::string token;
      while (in >> token) {
        if (token == "|") {
          nrings += sign;
        } else if (token.find(':') != std::string::npos) {
          count[token] += sign;
        }
      }
      nrings += sign;
    }
  };
  int size = 0;
  for (const bool vc : {false, true}) {
    std::map<std::string, int> count;
    int rings = 0;
    tokens(vc ? a.vc : a.classic, count, 1, rings);
    tokens(vc ? b.vc : b.classic, count, -1, rings);
    int diff = std::abs(rings);
    for (const auto& [token, n] : count) diff += std::abs(n);
    if (diff == 0 && (vc ? a.vc != b.vc : a.classic != b.classic)) diff = 2;
    size = std::max(size, diff);
  }
  std::vector<std::string> rays;
  std::set_symmetric_difference(a.active_rays.begin(), a.active_rays.end(), b.active_rays.begin(), b.active_rays.end(),
                                std::back_inserter(rays));
  return size + static_cast<int>(rays.size());
}

SliceStructure StructureOf(const VcBackprojection& vc) {
  return {RegionStructure(vc.classic), RegionStructure(vc.region), vc.active_rays};
}

SliceStructure StructureAt(const BackprojectionProblem& pr, double theta) {
  BackprojectionProblem p = pr;
  p.theta = theta;
  return StructureOf(VcEnlargedBackprojection(p));
}

std::vector<Vector2d> AllVertices(const Region& r) {
  std::vector<Vector2d> out;
  for (const auto& poly : r.polygons) {
    out.insert(out.end(), poly.outer.vertices.begin(), poly.outer.vertices.end());
    for (const auto& h : poly.holes) out.insert(out.end(), h.vertices.begin(), h.vertices.end());
  }
  return out;
}

// The larger of the two directed distances between the regions' vertex sets (the Hausdorff distance of the sets).
double VertexDistance(const Region& a, const Region& b) {
  const auto va = AllVertices(a), vb = AllVertices(b);
  if (va.size() != vb.size()) return std::numeric_limits<double>::infinity();
  auto directed = [](const std::vector<Vector2d>& x, const std::vector<Vector2d>& y) {
    double worst = 0;
    for (const auto& p : x) {
      double best = std::numeric_limits<double>::infinity();
      for (const auto& q : y) best = std::min(best, (p - q).norm());
      worst = std::max(worst, best);
    }
    return worst;
  };
  return std::max(directed(va, vb), directed(vb, va));
}

// The swept backprojections at θ, their structure, and the open slice's regions carried to θ compared with them.
SliceStructure SweptAndCarried(const BackprojectionProblem& pr, const NondirectionalBackprojection& nd, double theta,
                               Tally& t) {
  BackprojectionProblem p = pr;
  p.theta = theta;
  const VcBackprojection swept = VcEnlargedBackprojection(p);
  const double size = (pr.bounds_max - pr.bounds_min).norm();
  for (const bool vc : {false, true}) {
    const Region& truth = vc ? swept.region : swept.classic;
    const Region carried = RegionAt(nd, theta, vc);
    const double dv = VertexDistance(carried, truth) / size;
    const double da = std::abs(carried.area - truth.area) / (size * size);
    ++t.carried;
    t.carried_vertex = std::max(t.carried_vertex, dv);
    t.carried_area = std::max(t.carried_area, da);
    EXPECT_LE(dv, 1e-9) << "θ " << theta << (vc ? " VC" : " classic") << ": the carried region's vertices are off";
    EXPECT_LE(da, 1e-9) << "θ " << theta << (vc ? " VC" : " classic") << ": the carried region's area is off";
  }
  return StructureOf(swept);
}

// How far (radians) the nearest other candidate is from candidates[i]; with `other_features`, the nearest one with
// other refs (an along-a-segment event gives one candidate per end of the segment, at the same θ).
double NearestOtherCandidate(const std::vector<CriticalOrientation>& candidates, size_t i,
                             bool other_features = false) {
  double nearest = M_PI;
  for (size_t j = 0; j < candidates.size(); ++j) {
    if (j == i || (other_features && candidates[j].refs == candidates[i].refs)) continue;
    nearest = std::min(nearest, std::abs(WrapAngle(candidates[j].theta - candidates[i].theta)));
  }
  return nearest;
}

// The classic regions at θ − d and θ + d.
std::pair<Region, Region> ClassicRegionsAround(const BackprojectionProblem& pr, double theta, double d) {
  BackprojectionProblem before = pr, after = pr;
  before.theta = WrapAngle(theta - d);
  after.theta = WrapAngle(theta + d);
  return {ClassicBackprojection(before), ClassicBackprojection(after)};
}

// The property of docs/formats.md `visco critical`: sampled at ¼, ½, ¾ of every interval between consecutive
// orientations, the structure is the same; and across every non-R orientation it changes.
void CheckStructure(const std::string& name, const BackprojectionProblem& pr, const NondirectionalBackprojection& nd,
                    Tally& t) {
  ++t.scenes;
  t.candidates += nd.stats.candidates;
  t.unexplained += static_cast<int>(nd.stats.unexplained);
  EXPECT_EQ(nd.stats.unexplained, 0) << name << ": a change no candidate explains";
  t.found_by_probes += static_cast<int>(nd.stats.found_by_probes);
  EXPECT_EQ(nd.stats.found_by_probes, 0) << name << ": a change the kinetic walk skipped";
  // The walk's rule is exact on whole scenes but at sliding events, whose rule has a known gap (docs: a motion leaving
  // the edge into free space at an interior point; VISCO_SEED_OFFSET=20000060 seed 7 at 1.49°: a part of the VC
  // region appears at an edge that met no region). The strip problems too, since their pieces share their corners
  // exactly (before, edges shorter than 1e-15 at those corners came or went at events elsewhere: strip seed 46).
  t.rule_missed += static_cast<int>(nd.stats.rule_missed);
  t.rule_missed_sliding += static_cast<int>(nd.stats.rule_missed_sliding);
  EXPECT_EQ(nd.stats.rule_missed - nd.stats.rule_missed_sliding, 0)
      << name << ": a change at an event the walk's rule skips (a later sweep found it)";
  const auto& o = nd.orientations;
  const int not_changing_before = t.not_changing;
  t.orientations += static_cast<int>(o.size());
  std::vector<SliceStructure> mid(o.size());
  for (size_t k = 0; k < o.size(); ++k) {
    const double lo = o[k].theta, hi = k + 1 < o.size() ? o[k + 1].theta : o[0].theta + 2 * M_PI;
    if (hi - lo < 1e-9) continue;
    ++t.intervals;
    const SliceStructure a = SweptAndCarried(pr, nd, WrapAngle(lo + 0.25 * (hi - lo)), t);
    mid[k] = StructureAt(pr, WrapAngle(lo + 0.5 * (hi - lo)));
    const SliceStructure c = SweptAndCarried(pr, nd, WrapAngle(lo + 0.75 * (hi - lo)), t);
    if (!(a == mid[k] && mid[k] == c)) {
      ++t.broken;
      ADD_FAILURE() << name << ": the structure changes inside (" << lo * 180 / M_PI << "°, " << hi * 180 / M_PI
                    << "°)";
    }
  }
  // Every structural orientation changes the structure: the intervals on its two sides differ (R-critical ones need
  // not).
  for (size_t k = 0; k < o.size() && o.size() > 1; ++k) {
    const size_t prev = (k + o.size() - 1) % o.size();
    if (o[k].kind == CriticalKind::kR || mid[prev].classic.empty() || mid[k].classic.empty()) continue;
    ++t.changes;
    if (mid[prev] == mid[k]) {
      ++t.not_changing;
      std::string refs;
      for (const auto& r : o[k].refs) refs += " " + r;
      ADD_FAILURE() << name << ": nothing changes across the " << CriticalKindName(o[k].kind) << " orientation "
                    << o[k].theta * 180 / M_PI << "°" << refs;
    } else {
      t.kinds_changing.insert(CriticalKindName(o[k].kind));
      const int size = EditSize(mid[prev], mid[k]);
      ++t.edit_sizes[size];
      ++t.edit_sizes_by_kind[CriticalKindName(o[k].kind)][size];
    }
  }
  EXPECT_EQ(t.not_changing, not_changing_before) << name << ": an orientation where nothing changes";
}

BackprojectionProblem SceneProblem(const Scene& s, const CSpace& cspace, const VcRays& rays) {
  return ProblemFromScene(s, cspace, &rays, 0.0, /*kernel=*/false);
}

// A whole random scene of 2 x 1 cells through the real pipeline (scene -> C-space -> VC rays -> problem).
struct RandomCase {
  Scene scene;
  std::unique_ptr<CSpace> cspace;
  BackprojectionProblem problem;
};

std::optional<RandomCase> MakeRandomCase(std::uint64_t seed) {
  RandomCase c;
  double theta = 0;
  if (!testing::RandomWholeScene(seed, c.scene, theta, 2, 1)) return std::nullopt;
  c.cspace = std::make_unique<CSpace>(c.scene);
  const VcRays rays = ComputeVcRays(c.scene, *c.cspace);
  c.problem = SceneProblem(c.scene, *c.cspace, rays);
  return c;
}

NondirectionalOptions Options(int threads = 2) {
  NondirectionalOptions o;
  o.threads = threads;
  return o;
}

// Seeds of the structure property: 100 whole random scenes of 2 x 1 cells in four parts (run side by side); a
// sanitizer build runs every fifth.
#if defined(__SANITIZE_ADDRESS__)
constexpr std::uint64_t kSeedStride = 5;
constexpr int kSanitizerDivisor = 3;  // the other tests run a third of their scenes
#else
constexpr std::uint64_t kSeedStride = 1;
constexpr int kSanitizerDivisor = 1;
#endif

// CI runs the first 10 seeds of each part (40 scenes); VISCO_FULL_PROPERTY=1 runs all 100 (the figures in
// docs/planning_nondirectional.md come from the full run).
bool FullProperty() { return std::getenv("VISCO_FULL_PROPERTY") != nullptr; }

void StructureOnSeeds(std::uint64_t first, std::uint64_t last, Tally& t) {
  if (!FullProperty()) last = std::min(last, first + 9);
  // Every seed of the part is generated (cheap); a sanitizer build checks every kSeedStride-th accepted scene, so a
  // rejected seed does not leave it with nothing to check.
  int tried = 0, accepted = 0;
  for (std::uint64_t seed = first; seed <= last; ++seed) {
    ++tried;
    Scene scene;
    double theta = 0;
    if (!testing::RandomWholeScene(seed, scene, theta, 2, 1)) continue;
    if (accepted++ % static_cast<int>(kSeedStride) != 0) continue;
    const auto random = MakeRandomCase(seed);
    if (!random) continue;
    const BackprojectionProblem& pr = random->problem;
    const auto nd = ComputeNondirectional(pr, nullptr, Options());
    CheckStructure("seed " + std::to_string(seed), pr, nd, t);
  }
  std::string kinds;
  for (const auto& k : t.kinds_changing) kinds += k + " ";
  std::printf(
      "scenes %d, candidates %lld, orientations %d (%d checked across, %d change nothing), intervals %d "
      "(broken %d), unexplained %d, skipped by the walk %d, missed by its rule %d (at sliding events %d); kinds that "
      "change the structure: %s\n"
      "regions carried to 1/4 and 3/4 of their interval: %d, worst vertex %.2e, worst area %.2e (of the scene's "
      "size)\n%s\n",
      t.scenes, static_cast<long long>(t.candidates), t.orientations, t.changes, t.not_changing, t.intervals, t.broken,
      t.unexplained, t.found_by_probes, t.rule_missed, t.rule_missed_sliding, kinds.c_str(), t.carried,
      t.carried_vertex, t.carried_area, EditSizes(t).c_str());
  if (testing::DesignedSeeds()) {
    EXPECT_GE(accepted * 10, tried * 9) << "the generator rejects too many seeds";
  }
  EXPECT_GE(t.scenes, 1);
  EXPECT_EQ(t.broken, 0);
}

TEST(NondirectionalProperty, StructureIsConstantBetweenOrientationsSeeds1To25) {
  Tally t;
  StructureOnSeeds(1, 25, t);
}
TEST(NondirectionalProperty, StructureIsConstantBetweenOrientationsSeeds26To50) {
  Tally t;
  StructureOnSeeds(26, 50, t);
}
TEST(NondirectionalProperty, StructureIsConstantBetweenOrientationsSeeds51To75) {
  Tally t;
  StructureOnSeeds(51, 75, t);
}
TEST(NondirectionalProperty, StructureIsConstantBetweenOrientationsSeeds76To100) {
  Tally t;
  StructureOnSeeds(76, 100, t);
}

// The problems of a strategy's visual guarded steps (planning/strategy.cc): the goal a thin strip around a piece of
// a CVC ray (or of a random segment where the scene has none), the rest of the ray forbidden right up to it, no
// active rays. Their free edges start at the strip's corners, partly inside the forbidden strips, and their free
// vertices lie a few centimetres from the goal: shapes the whole-scene generator never makes (the kinetic walk
// missed a free vertex crossing the bounds and back on such a problem: VISCO_SEED_OFFSET=19507001, strategy seed 11).
std::optional<BackprojectionProblem> StripProblem(std::uint64_t seed) {
  auto random = MakeRandomCase(seed);
  if (!random) return std::nullopt;
  BackprojectionProblem pr = random->problem;
  std::mt19937_64 rng(seed * 7919 + 3);
  std::uniform_real_distribution<double> unit(0, 1);
  const Vector2d lo = pr.bounds_min, hi = pr.bounds_max;
  Vector2d a, b;
  if (!pr.rays.empty()) {
    const auto& ray = pr.rays[rng() % pr.rays.size()];
    const auto& seg = ray.segments[rng() % ray.segments.size()];
    a = seg[0];
    b = seg[1];
  } else {
    a = lo + Vector2d(unit(rng), unit(rng)).cwiseProduct(hi - lo);
    b = lo + Vector2d(unit(rng), unit(rng)).cwiseProduct(hi - lo);
  }
  const double len = (b - a).norm();
  if (len < 0.2) return std::nullopt;
  const double t0 = 0.6 * unit(rng), t1 = t0 + (0.1 + 0.3 * unit(rng)) * (1 - t0);
  const Vector2d pa = a + t0 * (b - a), pb = a + t1 * (b - a);
  // Squared to the segment, as the planner makes them: the pieces share their corners exactly.
  pr.goal = {Strip(pa, pb, kVcStripHalfWidth, "piece.end", b - a)};
  pr.forbidden.clear();
  if (t0 > 1e-3) pr.forbidden.push_back(Strip(a, pa, kVcStripHalfWidth, "piece.rest0", b - a));
  if (t1 < 1 - 1e-3) pr.forbidden.push_back(Strip(pb, b, kVcStripHalfWidth, "piece.rest1", b - a));
  pr.rays.clear();
  return pr;
}

TEST(NondirectionalProperty, StructureIsConstantWithStripGoalsAndForbiddenStrips) {
  Tally t;
  int kinetic_vs_baseline = 0;
  const std::uint64_t last = FullProperty() ? 60 : 15;
  for (std::uint64_t seed = 1; seed <= last; seed += kSeedStride) {
    const auto pr = StripProblem(seed);
    if (!pr) continue;
    const auto nd = ComputeNondirectional(*pr, nullptr, Options());
    CheckStructure("strip seed " + std::to_string(seed), *pr, nd, t);
    // Every fifth against the critical-slice baseline (not under a sanitizer: the baseline sweeps every event).
    if (kSanitizerDivisor == 1 && seed % 5 == 1 && CriticalCandidates(*pr, nullptr).size() < 2500) {
      NondirectionalOptions base = Options();
      base.method = SliceMethod::kBaseline;
      const auto baseline = ComputeNondirectional(*pr, nullptr, base);
      ASSERT_EQ(nd.orientations.size(), baseline.orientations.size()) << "strip seed " << seed;
      for (size_t k = 0; k < nd.slices.size(); ++k) {
        EXPECT_EQ(nd.slices[k].structure, baseline.slices[k].structure) << "strip seed " << seed << " slice " << k;
      }
      ++kinetic_vs_baseline;
    }
  }
  std::printf(
      "strip problems %d, orientations %d, intervals %d (broken %d), unexplained %d, skipped by the walk %d, missed by "
      "its rule %d (at sliding events %d), against the baseline %d\n",
      t.scenes, t.orientations, t.intervals, t.broken, t.unexplained, t.found_by_probes, t.rule_missed,
      t.rule_missed_sliding, kinetic_vs_baseline);
  EXPECT_GE(t.scenes, (FullProperty() ? 30 : 8) / static_cast<int>(kSeedStride));
  EXPECT_EQ(t.broken, 0);
}

// True if two regions are the same bit for bit: rings, vertices, edges with their provenance, area.
bool IdenticalRegions(const Region& a, const Region& b) {
  auto same_ring = [](const RegionRing& x, const RegionRing& y) {
    if (x.vertices != y.vertices || x.edges.size() != y.edges.size()) return false;
    for (size_t i = 0; i < x.edges.size(); ++i) {
      const RegionEdge &e = x.edges[i], &f = y.edges[i];
      if (e.kind != f.kind || e.ref != f.ref || e.source != f.source || e.line != f.line || e.sign != f.sign) {
        return false;
      }
    }
    return true;
  };
  if (a.area != b.area || a.polygons.size() != b.polygons.size()) return false;
  for (size_t i = 0; i < a.polygons.size(); ++i) {
    const RegionPolygon &p = a.polygons[i], &q = b.polygons[i];
    if (!same_ring(p.outer, q.outer) || p.holes.size() != q.holes.size()) return false;
    for (size_t h = 0; h < p.holes.size(); ++h) {
      if (!same_ring(p.holes[h], q.holes[h])) return false;
    }
  }
  return true;
}

// The overlay of the statics prepared once (PrepareStaticOverlay, which every nondirectional backprojection uses)
// gives each sweep the regions and the ray choice it gets overlaying the statics itself, bit for bit: whole random
// scenes with the goal resting on CB (the goal's edges cross CB's: crossings that are no input point) and the strip
// problems of guarded steps (forbidden strips abutting the goal, crossing CB), at θ all around. A problem whose
// statics changed after it was prepared is swept as if it had not been.
TEST(NondirectionalProperty, APreparedOverlayGivesTheSameRegions) {
  int problems = 0, compared = 0;
  const std::uint64_t last = FullProperty() ? 100 : 20;
  for (std::uint64_t seed = 1; seed <= last; ++seed) {
    std::vector<BackprojectionProblem> cases;
    {
      Scene scene;
      double theta = 0;
      if (testing::RandomWholeScene(seed, scene, theta, 2, 1, /*goal_on_cb=*/true)) {
        const CSpace cspace(scene);
        cases.push_back(SceneProblem(scene, cspace, ComputeVcRays(scene, cspace)));
      }
    }
    if (auto strip = StripProblem(seed)) cases.push_back(*strip);
    for (const BackprojectionProblem& plain : cases) {
      ++problems;
      BackprojectionProblem prepared = plain;
      PrepareStaticOverlay(prepared);
      ASSERT_NE(prepared.static_overlay, nullptr);
      for (int k = 0; k < 6; ++k) {
        BackprojectionProblem p = plain, q = prepared;
        p.theta = q.theta = WrapAngle(-M_PI + (k + 0.37) * M_PI / 3);
        const VcBackprojection a = VcEnlargedBackprojection(p), b = VcEnlargedBackprojection(q);
        EXPECT_TRUE(IdenticalRegions(a.classic, b.classic)) << "seed " << seed << " θ " << p.theta;
        EXPECT_TRUE(IdenticalRegions(a.region, b.region)) << "seed " << seed << " θ " << p.theta;
        EXPECT_EQ(a.active_rays, b.active_rays) << "seed " << seed << " θ " << p.theta;
        ++compared;
      }
      // The goal moved after the overlay was prepared: the sweep must not use it.
      BackprojectionProblem moved = plain, stale = prepared;
      for (auto* pr : {&moved, &stale}) {
        for (Vector2d& v : pr->goal.front().vertices) v += Vector2d(0.05, 0.03);
        pr->theta = -M_PI / 2 + 0.2;
      }
      EXPECT_TRUE(IdenticalRegions(ClassicBackprojection(moved), ClassicBackprojection(stale))) << "seed " << seed;
    }
  }
  std::printf("prepared overlays: %d problems, %d orientations compared\n", problems, compared);
  EXPECT_GE(problems, 8);
}

// Every example scene, with its start region's R-critical orientations.
TEST(NondirectionalExamples, StructureIsConstantBetweenConsecutiveOrientations) {
  Tally t;
#if defined(__SANITIZE_ADDRESS__)
  std::vector<const char*> files = {"fig13"};  // the sanitizer build is several times slower
#else
  std::vector<const char*> files = {"fig13", "ledge"};  // VISCO_FULL_PROPERTY=1: every example scene
#endif
  if (FullProperty()) files = {"slot", "fig5", "fig13", "ledge", "slot_pinhole"};
  for (const char* file : files) {
    const Scene s = LoadScene(std::string("data/scenes/") + file + ".json");
    const CSpace cspace(s);
    const VcRays rays = ComputeVcRays(s, cspace);
    const BackprojectionProblem pr = SceneProblem(s, cspace, rays);
    // fig13 with its start region's R-critical orientations; the others without (the structure is the same).
    NamedPolygon start;
    const bool with_start = s.start && std::string(file) == "fig13";
    if (with_start) start.vertices = s.start->polygon.vertices;
    const auto nd = ComputeNondirectional(pr, with_start ? &start : nullptr, Options());
    CheckStructure(file, pr, nd, t);
  }
  std::printf(
      "example scenes %d, orientations %d, intervals %d (broken %d); regions carried %d, worst vertex %.2e, "
      "worst area %.2e (of the scene's size)\n%s\n",
      t.scenes, t.orientations, t.intervals, t.broken, t.carried, t.carried_vertex, t.carried_area,
      EditSizes(t).c_str());
  EXPECT_EQ(t.broken, 0);
}

// The R-critical kind changes what the planner asks about: on fig13 the interval of orientations where the start
// region fits inside B_vcθ(G) begins at an R-critical orientation, where the region's structure stays the same but
// the start region goes from sticking out to fitting.
TEST(NondirectionalExamples, AnRCriticalOrientationIsWhereTheStartRegionStartsToFit) {
  const Scene s = LoadScene("data/scenes/fig13.json");
  ASSERT_TRUE(s.start.has_value());
  const CSpace cspace(s);
  const VcRays rays = ComputeVcRays(s, cspace);
  const BackprojectionProblem pr = SceneProblem(s, cspace, rays);
  NamedPolygon start;
  start.vertices = s.start->polygon.vertices;
  const auto nd = ComputeNondirectional(pr, &start, Options());
  const auto intervals = IntervalsContaining(nd, pr, start, /*vc=*/true);
  ASSERT_FALSE(intervals.empty());
  const double size = (pr.bounds_max - pr.bounds_min).norm();
  auto fits = [&](double theta) {
    BackprojectionProblem p = pr;
    p.theta = WrapAngle(theta);
    return RegionContainsPolygon(VcEnlargedBackprojection(p).region, start.vertices, 1e-9 * size, nullptr);
  };
  int r_ends = 0;
  for (const auto& in : intervals) {
    for (double end : {in.lo, in.hi}) {
      const bool is_r = std::any_of(nd.orientations.begin(), nd.orientations.end(), [&](const CriticalOrientation& o) {
        return o.kind == CriticalKind::kR && std::abs(WrapAngle(o.theta - end)) < 1e-9;
      });
      if (!is_r) continue;
      ++r_ends;
      const double inward = end == in.lo ? 1.0 : -1.0, step = 1e-4;
      EXPECT_TRUE(fits(end + inward * step)) << end * 180 / M_PI;
      EXPECT_FALSE(fits(end - inward * step)) << end * 180 / M_PI;
      EXPECT_EQ(StructureAt(pr, WrapAngle(end - step)), StructureAt(pr, WrapAngle(end + step)))
          << "at " << end * 180 / M_PI << "° the region itself changes: not an R-only event";
    }
  }
  EXPECT_GE(r_ends, 1) << "no interval where the start region fits ends at an R-critical orientation";
}

// The free-edge kind (Fox & Hutchinson, Prop. 2) changes the structure: in tests/planning/data/scenes/
// free_edge_crossing.json the goal is a U whose right arm's backprojection ends in a free vertex (the +ε_v free edge
// of the arm's corner and the −ε_v one of the roof between the arms) just below an active CVC ray that leads into the
// left arm; turning θ pushes that free vertex across the ray, and the region below the ray joins the band above it
// around a new hole. The scene also made the ray choice's exact region comparison meet a ring that touches itself at
// a vertex (a CGAL precondition, planning/backprojection/ray_choice.h SimpleLoops): the sanitizer build checks it.
BackprojectionProblem FreeEdgeCrossingProblem() {
  const Scene s = LoadScene("tests/planning/data/scenes/free_edge_crossing.json");
  const CSpace cspace(s);
  const VcRays rays = ComputeVcRays(s, cspace);
  return SceneProblem(s, cspace, rays);
}

TEST(NondirectionalExamples, AFreeVertexCrossingAnActiveRayChangesTheStructure) {
  const BackprojectionProblem pr = FreeEdgeCrossingProblem();
  auto check_change = [&](double theta, double step) {
    const SliceStructure before = StructureAt(pr, WrapAngle(theta - step));
    const SliceStructure after = StructureAt(pr, WrapAngle(theta + step));
    EXPECT_EQ(before.classic, after.classic) << "only the VC region changes at " << theta * 180 / M_PI;
    EXPECT_NE(before.vc, after.vc) << "the VC structure is the same across " << theta * 180 / M_PI;
    EXPECT_NE(before.vc.size(), 0u);
  };
#if defined(__SANITIZE_ADDRESS__)
  // The whole computation takes 80 s under the sanitizers: there only the change at the orientation it reports.
  check_change(-86.5417 * M_PI / 180, 1e-4);
#else
  const auto nd = ComputeNondirectional(pr, nullptr, Options());
  Tally t;
  CheckStructure("free_edge_crossing", pr, nd, t);
  EXPECT_EQ(t.broken, 0);
  int free_edge = 0;
  for (const auto& o : nd.orientations) {
    if (o.kind != CriticalKind::kFreeEdge) continue;
    ++free_edge;
    ASSERT_EQ(o.refs.size(), 3u);
    EXPECT_EQ(o.refs[2], "vc0.cm2") << "the ray the free vertex crosses";
    EXPECT_NEAR(o.theta * 180 / M_PI, -86.5417, 1e-3);
    check_change(o.theta, 1e-6);
    std::printf("free-edge orientation %.4f deg (%s, %s, %s): the VC structure changes\n", o.theta * 180 / M_PI,
                o.refs[0].c_str(), o.refs[1].c_str(), o.refs[2].c_str());
  }
  EXPECT_EQ(free_edge, 1);
#endif
}

// At θ ≈ 4° in the same scene, regions the ray choice compares have a ring that touches itself at a vertex. CGAL's
// polygon sets take such a ring only as a precondition (the debug build stopped there with an internal error); the
// ring is cut into simple loops first (planning/backprojection/ray_choice.h SimpleLoops). The region found is the same
// for every way of choosing the rays that this ring passes through.
TEST(NondirectionalExamples, ARingTouchingItselfIsComparedExactly) {
  const BackprojectionProblem pr = FreeEdgeCrossingProblem();
  for (double theta : {0.0619, 0.0702679, 0.0943}) {
    BackprojectionProblem p = pr;
    p.theta = theta;
    VcSelectionOptions exact;
    exact.method = RaySelection::kExact;
    const VcBackprojection track = VcEnlargedBackprojection(p);
    const VcBackprojection searched = VcEnlargedBackprojection(p, exact);
    EXPECT_GE(track.region.area, track.classic.area - 1e-9) << theta;
    EXPECT_NEAR(track.region.area, searched.region.area, 1e-9) << theta;
    EXPECT_EQ(track.active_rays, searched.active_rays) << theta;
  }
}

// Donald's critical-slice baseline and the kinetic method report the same orientations and slices.
TEST(NondirectionalProperty, KineticAgreesWithTheCriticalSliceBaseline) {
  int compared = 0;
  const int to_compare = kSanitizerDivisor > 1 ? 1 : 4;  // the baseline sweeps every candidate: slow under ASan
  for (std::uint64_t seed = 1; compared < to_compare && seed <= 40; ++seed) {
    const auto random = MakeRandomCase(seed);
    if (!random) continue;
    const BackprojectionProblem& pr = random->problem;
    if (CriticalCandidates(pr, nullptr).size() > 1500) continue;
    NondirectionalOptions base = Options();
    base.method = SliceMethod::kBaseline;
    const auto kinetic = ComputeNondirectional(pr, nullptr, Options());
    const auto baseline = ComputeNondirectional(pr, nullptr, base);
    ASSERT_EQ(kinetic.orientations.size(), baseline.orientations.size()) << "seed " << seed;
    for (size_t k = 0; k < kinetic.orientations.size(); ++k) {
      EXPECT_NEAR(kinetic.orientations[k].theta, baseline.orientations[k].theta, 1e-9) << "seed " << seed;
    }
    ASSERT_EQ(kinetic.slices.size(), baseline.slices.size());
    for (size_t k = 0; k < kinetic.slices.size(); ++k) {
      EXPECT_EQ(kinetic.slices[k].structure, baseline.slices[k].structure) << "seed " << seed << " slice " << k;
    }
    EXPECT_LT(kinetic.stats.backprojections, baseline.stats.backprojections) << "seed " << seed;
    ++compared;
  }
  EXPECT_EQ(compared, to_compare);
}

// The kinetic walk's two economies change nothing but the sweeps: an event whose point is off the regions' boundary
// is skipped (`boundary_events`), and a change that is the local edit of the event just swept is put there without a
// sweep before it (`local_edits`). With either off, the same orientations (kind, refs, θ) and slice structures.
// The same orientations (θ, kind, refs) and slice structures: what an option that only saves sweeps must keep.
void ExpectSameResult(const NondirectionalBackprojection& a, const NondirectionalBackprojection& b,
                      const std::string& name) {
  ASSERT_EQ(a.orientations.size(), b.orientations.size()) << name;
  for (size_t k = 0; k < a.orientations.size(); ++k) {
    EXPECT_NEAR(a.orientations[k].theta, b.orientations[k].theta, 1e-9) << name;
    EXPECT_EQ(a.orientations[k].kind, b.orientations[k].kind) << name;
    EXPECT_EQ(a.orientations[k].refs, b.orientations[k].refs) << name;
  }
  ASSERT_EQ(a.slices.size(), b.slices.size()) << name;
  for (size_t k = 0; k < a.slices.size(); ++k) {
    EXPECT_EQ(a.slices[k].structure, b.slices[k].structure) << name << " slice " << k;
  }
}

TEST(NondirectionalProperty, TheWalksEconomiesChangeOnlyTheSweeps) {
  int compared = 0;
  std::int64_t explained = 0, sweeps = 0, sweeps_without[2] = {0, 0};
  const int to_compare = kSanitizerDivisor > 1 ? 2 : 6;
  for (std::uint64_t seed = 1; compared < to_compare && seed <= 60; ++seed) {
    const auto random = MakeRandomCase(seed);
    if (!random) continue;
    const BackprojectionProblem& pr = random->problem;
    const auto nd = ComputeNondirectional(pr, nullptr, Options());
    explained += nd.stats.explained;
    sweeps += nd.stats.backprojections;
    for (int without = 0; without < 2; ++without) {
      NondirectionalOptions o = Options();
      (without == 0 ? o.boundary_events : o.local_edits) = false;
      const auto other = ComputeNondirectional(pr, nullptr, o);
      const std::string name = "seed " + std::to_string(seed) + (without == 0 ? " (boundary)" : " (local edits)");
      sweeps_without[without] += other.stats.backprojections;
      if (without == 1) {
        EXPECT_EQ(other.stats.explained, 0) << name;
      }
      ExpectSameResult(nd, other, name);
    }
    ++compared;
  }
  std::printf(
      "scenes %d: %lld sweeps, %lld without the boundary rule, %lld without local edits (%lld changes put at "
      "their event by its local edit)\n",
      compared, static_cast<long long>(sweeps), static_cast<long long>(sweeps_without[0]),
      static_cast<long long>(sweeps_without[1]), static_cast<long long>(explained));
  EXPECT_EQ(compared, to_compare);
  EXPECT_GT(explained, 0) << "no change was a local edit: the rule is not exercised";
  EXPECT_LT(sweeps, sweeps_without[1]);
  EXPECT_LE(sweeps, sweeps_without[0]);
}

// Ray points' events on demand (docs/planning_nondirectional.md, "Ray points' events on demand"): the walk over the
// candidates it lists (the events of the ray points its slices have, walked again when a slice has more) gives what
// the walk over the full listing gives: the same orientations (kind, refs, θ within 1e-9 rad: an event's θ is that of
// its first candidate, and a ray point's candidate not listed can be one within 1e-10 rad before it) and open slices'
// structures, and the same critical slices where the orientation is the same bit for bit, on random whole scenes with
// cameras (2 x 1 cells; VISCO_FULL_PROPERTY=1: 100 scenes, a third of them of 3 x 2 cells).
TEST(NondirectionalProperty, RayEventsOnDemandGiveWhatTheFullListingGives) {
  int compared = 0, walked_again = 0, moved = 0;
  std::int64_t listed = 0, full = 0, ray_points = 0, reused = 0;
  const int to_compare = FullProperty() ? 100 : (kSanitizerDivisor > 1 ? 2 : 6);
  for (std::uint64_t seed = 1; compared < to_compare && seed <= 400; ++seed) {
    Scene scene;
    double theta = 0;
    const bool large = FullProperty() && seed % 3 == 0;
    if (!testing::RandomWholeScene(seed, scene, theta, large ? 3 : 2, large ? 2 : 1)) continue;
    const CSpace cspace(scene);
    const VcRays rays = ComputeVcRays(scene, cspace);
    const BackprojectionProblem pr = SceneProblem(scene, cspace, rays);
    if (pr.rays.empty()) continue;
    NondirectionalOptions on_demand = Options();
    on_demand.ray_events_min_pairs = 0;  // these scenes are small
    const auto nd = ComputeNondirectional(pr, nullptr, on_demand);
    NondirectionalOptions o = Options();
    o.ray_events_on_demand = false;
    const auto reference = ComputeNondirectional(pr, nullptr, o);
    // The same orientations and open slices; a critical slice (swept at exactly its orientation, a degenerate
    // configuration) wherever the orientation is the same bit for bit.
    const std::string name = "seed " + std::to_string(seed);
    ASSERT_EQ(nd.orientations.size(), reference.orientations.size()) << name;
    for (size_t k = 0; k < nd.orientations.size(); ++k) {
      EXPECT_NEAR(nd.orientations[k].theta, reference.orientations[k].theta, 1e-9) << name;
      EXPECT_EQ(nd.orientations[k].kind, reference.orientations[k].kind) << name;
      EXPECT_EQ(nd.orientations[k].refs, reference.orientations[k].refs) << name;
      moved += nd.orientations[k].theta != reference.orientations[k].theta;
    }
    ASSERT_EQ(nd.slices.size(), reference.slices.size()) << name;
    for (size_t k = 0; k < nd.slices.size(); ++k) {
      if (nd.slices[k].critical && nd.slices[k].theta != reference.slices[k].theta) continue;
      EXPECT_EQ(nd.slices[k].structure, reference.slices[k].structure) << name << " slice " << k;
    }
    EXPECT_EQ(reference.stats.walks, 1);
    EXPECT_LE(nd.stats.candidates, reference.stats.candidates) << "seed " << seed;
    listed += nd.stats.candidates;
    full += reference.stats.candidates;
    ray_points += nd.stats.ray_points_listed;
    reused += nd.stats.reused;
    walked_again += nd.stats.walks > 1;
    ++compared;
  }
  std::printf(
      "scenes %d: %lld candidates listed against %lld in full; %lld ray points listed, %d scenes walked again "
      "(%lld backprojections reused); %d orientations moved by under 1e-9 rad\n",
      compared, static_cast<long long>(listed), static_cast<long long>(full), static_cast<long long>(ray_points),
      walked_again, static_cast<long long>(reused), moved);
  EXPECT_EQ(compared, to_compare);
  EXPECT_LT(listed, full);
  if (kSanitizerDivisor == 1) {
    EXPECT_GT(walked_again, 0) << "no slice had a ray point: walking again is not exercised";
  }
}

// The kinetic walk's computed updates (docs/planning_nondirectional.md, "Computing the slice after a change"): every
// slice it computes from the last one instead of sweeping has the swept slice's structure and areas (check_updates
// sweeps as well and counts the differences), on random whole scenes; and with the updates the result is the one
// without them.
TEST(NondirectionalProperty, ComputedUpdatesAreTheSweptSlices) {
  std::int64_t updated = 0, mismatches = 0, sweeps = 0, sweeps_without = 0;
  int scenes = 0, grids = 0, compared = 0;
  // Checked against sweeps; on some problems also the result with the updates against the one without them.
  auto check = [&](const BackprojectionProblem& pr, const std::string& name, bool compare) {
    NondirectionalOptions o = Options();
    o.check_updates = true;
    const auto checked = ComputeNondirectional(pr, nullptr, o);
    updated += checked.stats.updated;
    mismatches += checked.stats.update_mismatches;
    EXPECT_EQ(checked.stats.update_mismatches, 0) << name;
    if (!compare) return;
    ++compared;
    const auto nd = ComputeNondirectional(pr, nullptr, Options());
    NondirectionalOptions off = Options();
    off.computed_updates = false;
    const auto without = ComputeNondirectional(pr, nullptr, off);
    EXPECT_EQ(without.stats.updated, 0) << name;
    EXPECT_EQ(nd.stats.updated, checked.stats.updated) << name;
    sweeps += nd.stats.backprojections;
    sweeps_without += without.stats.backprojections;
    ExpectSameResult(nd, without, name);
  };
  const std::uint64_t last = FullProperty() ? 100 : (kSanitizerDivisor > 1 ? 4 : 16);
  for (std::uint64_t seed = 1; seed <= last; ++seed) {
    const auto random = MakeRandomCase(seed);
    if (!random) continue;
    check(random->problem, "seed " + std::to_string(seed), scenes < (kSanitizerDivisor > 1 ? 1 : 4));
    ++scenes;
  }
  // The problems of a strategy's visual guarded steps (a goal strip on a ray, the rest of it forbidden), where the
  // strips' edges meet (and so are never edited) but free edges pass their corners.
  int strips = 0;
  for (std::uint64_t seed = 1; seed <= (FullProperty() ? 60 : (kSanitizerDivisor > 1 ? 2 : 6)); ++seed) {
    const auto pr = StripProblem(seed);
    if (!pr) continue;
    check(*pr, "strip seed " + std::to_string(seed), false);
    ++strips;
  }
  // And the benchmark's grids of pentagons (8 and 16: 44 and 84 C-obstacle vertices), where many obstacles stand
  // side by side and a free edge passes from one to the next (the random scenes have one or two obstacles).
  for (const int m : {8, 16}) {
    if (kSanitizerDivisor > 1 && m > 8) break;
    check(bench::PentagonGrid(m), "pentagon grid " + std::to_string(m), m == 8);
    ++grids;
  }
  std::printf(
      "scenes %d, %d strip problems and %d grids: %lld slices computed instead of swept, %lld differ from the sweep; "
      "%lld sweeps against %lld without the updates on %d of them\n",
      scenes, strips, grids, static_cast<long long>(updated), static_cast<long long>(mismatches),
      static_cast<long long>(sweeps), static_cast<long long>(sweeps_without), compared);
  EXPECT_GT(updated, 0) << "no slice was computed: the updates are not exercised";
  EXPECT_LT(sweeps, sweeps_without);
}

// The kinetic walk's local rule for sliding events (docs/planning_nondirectional.md, "Sliding events that matter"):
// a sliding event whose edge or vertex meets neither region just before it changes nothing. Each sampled sliding
// candidate with no other candidate within 2·gap is checked on both sides: where its feature is away from the
// classic and VC regions at θ − gap, the structure at θ + gap is the same (a change of the chosen rays alone is a
// selection orientation, which no geometric event bounds: counted apart).
TEST(NondirectionalProperty, ASlidingEventAwayFromTheRegionsChangesNothing) {
  int away = 0, near = 0, changed_away = 0, selection_only = 0, near_changing = 0;
  const int per_scene = kSanitizerDivisor > 1 ? 8 : 40;
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(kSanitizerDivisor > 1 ? 3 : 12); ++seed) {
    const auto random = MakeRandomCase(seed);
    if (!random) continue;
    const BackprojectionProblem& pr = random->problem;
    const auto candidates = CriticalCandidates(pr, nullptr);
    const double size = (pr.bounds_max - pr.bounds_min).norm();
    std::vector<size_t> sliding;
    for (size_t i = 0; i < candidates.size(); ++i) {
      if (candidates[i].kind != CriticalKind::kSliding) continue;
      ASSERT_FALSE(candidates[i].feature.empty()) << "seed " << seed << ": a sliding candidate without its feature";
      sliding.push_back(i);
    }
    std::mt19937_64 rng(seed * 131);
    std::shuffle(sliding.begin(), sliding.end(), rng);
    int tried = 0;
    for (size_t i : sliding) {
      if (tried >= per_scene) break;
      const double theta = candidates[i].theta;
      const double gap = std::min(1e-6, 0.4 * NearestOtherCandidate(candidates, i));
      if (gap < 1e-11) continue;  // another candidate at the same θ: its own change would be counted here
      ++tried;
      BackprojectionProblem before = pr, after = pr;
      before.theta = WrapAngle(theta - gap);
      after.theta = WrapAngle(theta + gap);
      const VcBackprojection b = VcEnlargedBackprojection(before), a = VcEnlargedBackprojection(after);
      const bool meets = FeatureMeetsRegion(candidates[i].feature, b.classic, 1e-9 * size) ||
                         FeatureMeetsRegion(candidates[i].feature, b.region, 1e-9 * size);
      const SliceStructure sb = StructureOf(b), sa = StructureOf(a);
      if (meets) {
        ++near;
        near_changing += sb == sa ? 0 : 1;
        continue;
      }
      ++away;
      if (sb.active_rays != sa.active_rays) {
        ++selection_only;
        continue;
      }
      if (!(sb == sa)) {
        ++changed_away;
        ADD_FAILURE() << "seed " << seed << ": the sliding event of " << candidates[i].refs[0] << " at "
                      << theta * 180 / M_PI << "° changes the structure although its feature meets no region";
      }
    }
  }
  std::printf(
      "sliding events sampled: %d away from the regions (%d changed; %d changed the chosen rays only), %d "
      "meeting them (%d of those change the structure)\n",
      away, changed_away, selection_only, near, near_changing);
  EXPECT_GT(away, 20 / kSanitizerDivisor);
  EXPECT_EQ(changed_away, 0);
}

// The sliding causes the kinetic walk never sweeps at, even where their edge meets a region
// (SlidingCauseChangesNothing): a cone edge reaching n ± φ (the cone points away from the obstacle, so no velocity
// touches the edge), θ itself along the edge (the contact model depends on the cone of velocities, not on the
// commanded one), a vertex rule's bisector pointing out of CB, and a cone edge reaching the friction cone's near edge
// (the edge sticks on both sides). Sampled like the test above, but only where the feature meets a region: the
// structure is the same on both sides.
TEST(NondirectionalProperty, SlidingEventsThatTouchNoVelocityChangeNothing) {
  std::map<SlidingCause, int> sampled, changed;
  int selection_only = 0;
  // Per scene: at most `per_cause` sampled events of each cause, and `evaluations` pairs of sweeps in all.
  const int per_cause = kSanitizerDivisor > 1 ? 2 : 5, evaluations = kSanitizerDivisor > 1 ? 24 : 100;
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(kSanitizerDivisor > 1 ? 14 : 40); ++seed) {
    const auto random = MakeRandomCase(seed);
    if (!random) continue;
    const BackprojectionProblem& pr = random->problem;
    const auto candidates = CriticalCandidates(pr, nullptr);
    const double size = (pr.bounds_max - pr.bounds_min).norm();
    std::vector<size_t> picked;
    for (size_t i = 0; i < candidates.size(); ++i) {
      if (SlidingCauseChangesNothing(candidates[i].sliding)) picked.push_back(i);
    }
    std::mt19937_64 rng(seed * 257);
    std::shuffle(picked.begin(), picked.end(), rng);
    std::map<SlidingCause, int> tried;
    int evaluated = 0;
    for (size_t i : picked) {
      if (evaluated >= evaluations) break;
      if (tried[candidates[i].sliding] >= per_cause) continue;
      const double theta = candidates[i].theta;
      // Isolated from every candidate of another cause (others of these causes at the same θ, on collinear pieces
      // of one edge, say, are covered by the same claim).
      double nearest = M_PI;
      for (size_t j = 0; j < candidates.size(); ++j) {
        if (j == i || SlidingCauseChangesNothing(candidates[j].sliding)) continue;
        nearest = std::min(nearest, std::abs(WrapAngle(candidates[j].theta - theta)));
      }
      const double gap = std::min(1e-6, 0.4 * nearest);
      if (gap < 1e-11) continue;
      BackprojectionProblem before = pr, after = pr;
      before.theta = WrapAngle(theta - gap);
      after.theta = WrapAngle(theta + gap);
      ++evaluated;
      const VcBackprojection b = VcEnlargedBackprojection(before), a = VcEnlargedBackprojection(after);
      const bool meets = FeatureMeetsRegion(candidates[i].feature, b.classic, 1e-9 * size) ||
                         FeatureMeetsRegion(candidates[i].feature, b.region, 1e-9 * size);
      if (!meets) continue;  // the rule of the test above skips those anyway
      ++tried[candidates[i].sliding];
      ++sampled[candidates[i].sliding];
      const SliceStructure sb = StructureOf(b), sa = StructureOf(a);
      if (sb.active_rays != sa.active_rays) {
        ++selection_only;
        continue;
      }
      if (!(sb == sa)) {
        ++changed[candidates[i].sliding];
        ADD_FAILURE() << "seed " << seed << ": the sliding event of " << candidates[i].refs[0] << " at "
                      << theta * 180 / M_PI << "° (cause " << static_cast<int>(candidates[i].sliding)
                      << ") changes the structure";
      }
    }
  }
  std::printf(
      "sliding events meeting a region: %d with the cone pointing away (%d changed), %d with θ along the edge (%d "
      "changed), %d at a vertex rule's bisector pointing out of CB (%d changed), %d where the edge sticks on both "
      "sides (%d changed), %d changed the chosen rays only\n",
      sampled[SlidingCause::kAway], changed[SlidingCause::kAway], sampled[SlidingCause::kAlong],
      changed[SlidingCause::kAlong], sampled[SlidingCause::kVertexAway], changed[SlidingCause::kVertexAway],
      sampled[SlidingCause::kStickingHeld], changed[SlidingCause::kStickingHeld], selection_only);
  // A sanitizer build samples a few (it checks the code, the release build the claim).
  if (kSanitizerDivisor > 1) {
    EXPECT_GT(sampled[SlidingCause::kAway] + sampled[SlidingCause::kAlong] + sampled[SlidingCause::kVertexAway] +
                  sampled[SlidingCause::kStickingHeld],
              0);
  } else {
    EXPECT_GT(sampled[SlidingCause::kAway], 10);
    EXPECT_GT(sampled[SlidingCause::kAlong], 5);
    EXPECT_GT(sampled[SlidingCause::kVertexAway], 5);
    EXPECT_GT(sampled[SlidingCause::kStickingHeld], 5);
  }
}

// A sliding event alone at its θ changes the structure: a ramp whose lower end touches the goal, the robot pushed
// down into it. Where some velocity of the cone sticks on the ramp, the ramp is not in B_θ(G); where every velocity
// slides down it, the ramp and the points above it that fall onto it are. The kinetic walk, with its local rule,
// reports the change as a sliding orientation of the ramp's edge, and the ramp meets the regions on both sides.
TEST(NondirectionalExamples, ASlidingEventOnARampChangesTheStructure) {
  BackprojectionProblem pr;
  pr.bounds_min = {0, 0};
  pr.bounds_max = {10, 8};
  NamedPolygon ramp;
  ramp.vertices = {{0, 0}, {8, 0}, {0, 4}};  // the hypotenuse from (8, 0) up to (0, 4) is the ramp
  ramp.edge_refs = {"floor", "ramp", "wall"};
  pr.obstacles = {ramp};
  NamedPolygon goal;
  goal.vertices = {{8, 0}, {9.5, 0}, {9.5, 1}, {8, 1}};
  pr.goal = {goal};
  pr.velocity_cone = 10 * M_PI / 180;
  pr.friction_cone = 20 * M_PI / 180;
  const auto candidates = CriticalCandidates(pr, nullptr);
  const auto nd = ComputeNondirectional(pr, nullptr, Options());
  const double size = (pr.bounds_max - pr.bounds_min).norm();
  int alone_changing = 0;
  for (size_t i = 0; i < candidates.size(); ++i) {
    const CriticalOrientation& c = candidates[i];
    if (c.kind != CriticalKind::kSliding || c.refs[0] != "ramp") continue;
    const double nearest = NearestOtherCandidate(candidates, i);
    if (nearest < 1e-6) continue;
    const auto [b, a] = ClassicRegionsAround(pr, c.theta, 0.4 * nearest);
    if (RegionStructure(b) == RegionStructure(a)) continue;
    ++alone_changing;
    EXPECT_TRUE(FeatureMeetsRegion(c.feature, b, 1e-9 * size)) << c.theta * 180 / M_PI;
    EXPECT_TRUE(FeatureMeetsRegion(c.feature, a, 1e-9 * size)) << c.theta * 180 / M_PI;
    // The kinetic walk reports it, as a sliding orientation of the ramp.
    bool reported = false;
    for (const auto& o : nd.orientations) {
      reported = reported || (std::abs(o.theta - c.theta) <= 1e-12 && o.kind == CriticalKind::kSliding &&
                              o.refs == std::vector<std::string>{"ramp"});
    }
    EXPECT_TRUE(reported) << "the ramp's sliding change at " << c.theta * 180 / M_PI << "° is not reported";
  }
  EXPECT_GT(alone_changing, 0);
}

// A free edge turning across the line of a goal edge: a part of the region appears between that edge and the free
// edge from its upper end, attached at a corner where no free edge started before (here the region was the goal
// alone). No free edge of the region involves the event before it, so the walk's free-edge rule skips it; its rule
// for events along a static segment (the segment meets the region) sweeps there. Where such a part stays, a later
// sweep would find it anyway; where it goes again before the next sweep (the strip property:
// StructureIsConstantWithStripGoalsAndForbiddenStrips fails without the rule, seed 1) only that rule sees it.
TEST(NondirectionalExamples, AFreeEdgeTurningAcrossAGoalEdgeChangesTheStructure) {
  BackprojectionProblem pr;
  pr.bounds_min = {0, 0};
  pr.bounds_max = {10, 8};
  NamedPolygon floor;
  floor.vertices = {{-1, -1}, {11, -1}, {11, 1}, {-1, 1}};
  pr.obstacles = {floor};
  NamedPolygon goal;
  goal.vertices = {{3, 1}, {6, 1}, {5.6, 1.5}, {3.3, 1.5}};  // slanted sides: parallel to nothing else
  pr.goal = {goal};
  pr.velocity_cone = 5 * M_PI / 180;
  pr.friction_cone = 20 * M_PI / 180;
  const auto candidates = CriticalCandidates(pr, nullptr);
  const auto nd = ComputeNondirectional(pr, nullptr, Options());
  EXPECT_EQ(nd.stats.found_by_probes, 0);
  EXPECT_EQ(nd.stats.unexplained, 0);
  const double size = (pr.bounds_max - pr.bounds_min).norm();
  int alone_changing = 0;
  for (size_t i = 0; i < candidates.size(); ++i) {
    const CriticalOrientation& c = candidates[i];
    if (c.kind != CriticalKind::kVgraph || c.feature.empty()) continue;  // along a static segment
    const double nearest = NearestOtherCandidate(candidates, i, /*other_features=*/true);
    if (nearest < 1e-6) continue;
    const auto [b, a] = ClassicRegionsAround(pr, c.theta, 0.4 * nearest);
    if (RegionStructure(b) == RegionStructure(a)) continue;
    // Before the event the source starts no free edge of the region: the free-edge rule alone would skip it.
    auto starts_free_edge = [&](const Region& r) {
      bool starts = false;
      for (const auto& poly : r.polygons) {
        for (const auto& e : poly.outer.edges) {
          starts = starts || (e.kind == EdgeKind::kFree && (e.source - c.sources[0]).norm() <= 1e-9 * size);
        }
      }
      return starts;
    };
    if (starts_free_edge(b)) continue;
    ++alone_changing;
    EXPECT_TRUE(FeatureMeetsRegion(c.feature, b, 1e-9 * size)) << c.theta * 180 / M_PI;
    bool reported = false;
    for (const auto& o : nd.orientations) reported = reported || std::abs(o.theta - c.theta) <= 1e-12;
    EXPECT_TRUE(reported) << "the change along " << c.refs[0] << "-" << c.refs[1] << " at " << c.theta * 180 / M_PI
                          << "° is not reported";
  }
  EXPECT_GT(alone_changing, 0);
}

// Soundness of every slice: points inside each slice's VC region reach the goal in the adversarial simulator with
// the slice's rays active.
TEST(NondirectionalProperty, EverySliceIsSound) {
  int samples = 0, failures = 0, slices = 0;
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(12 / kSanitizerDivisor); ++seed) {
    const auto random = MakeRandomCase(seed);
    if (!random) continue;
    const BackprojectionProblem& pr = random->problem;
    const auto nd = ComputeNondirectional(pr, nullptr, Options());
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    for (const Slice& sl : nd.slices) {
      ++slices;
      BackprojectionProblem p = pr;
      p.theta = sl.theta;
      const MotionModel model(ToMotionWorld(*random->cspace, p, sl.vc.active_rays));
      Vector2d lo(1e300, 1e300), hi = -lo;
      for (const auto& poly : sl.vc.region.polygons) {
        for (const auto& v : poly.outer.vertices) {
          lo = lo.cwiseMin(v);
          hi = hi.cwiseMax(v);
        }
      }
      for (int i = 0; i < 12; ++i) {
        const Vector2d q(lo.x() + u(rng) * (hi.x() - lo.x()), lo.y() + u(rng) * (hi.y() - lo.y()));
        if (!sl.vc.region.Contains(q) || sl.vc.region.BoundaryDistance(q) < 1e-6 || model.InObstacleInterior(q)) {
          continue;
        }
        ++samples;
        const auto r = SimulateAdversarially(model, q, sl.theta, pr.velocity_cone, seed * 977 + i, i % 3 == 0);
        if (r.outcome != Outcome::kReachedGoal) {
          ++failures;
          ADD_FAILURE() << "seed " << seed << " slice θ = " << sl.theta * 180 / M_PI << ": (" << q.x() << ", " << q.y()
                        << ") fails: " << OutcomeName(r.outcome);
        }
      }
    }
  }
  std::printf("slices %d, samples %d, failures %d\n", slices, samples, failures);
  EXPECT_GT(samples, 200 / kSanitizerDivisor);
  EXPECT_EQ(failures, 0);
}

// Query correctness: for random rectangles R, R lies inside B_vcθ(G) (B_θ(G)) at sampled θ inside the returned
// intervals, and at no sampled θ outside them (away from the endpoints).
TEST(NondirectionalProperty, IntervalsContainingARegionAreRight) {
  int checked = 0, inside = 0, wrong = 0, pieces = 0, carried = 0;
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(kSanitizerDivisor > 1 ? 2 : 10); ++seed) {
    const auto random = MakeRandomCase(seed);
    if (!random) continue;
    const BackprojectionProblem& pr = random->problem;
    const auto nd = ComputeNondirectional(pr, nullptr, Options());
    std::mt19937_64 rng(seed * 31);
    std::uniform_real_distribution<double> u(0, 1);
    const Vector2d g = pr.goal[0].vertices[0];
    for (int k = 0; k < 3; ++k) {
      // A rectangle near the goal (so that it fits somewhere), 0.2-1 m wide.
      const double w = 0.2 + 0.8 * u(rng), h = 0.2 + 0.8 * u(rng);
      const Vector2d c = g + Vector2d(-2 + 4 * u(rng), -2 + 4 * u(rng));
      NamedPolygon r;
      r.vertices = {c, c + Vector2d(w, 0), c + Vector2d(w, h), c + Vector2d(0, h)};
      for (bool vc : {false, true}) {
        IntervalQueryStats qs;
        const auto intervals = IntervalsContaining(nd, pr, r, vc, &qs);
        pieces += qs.pieces;
        carried += qs.carried;
        for (int i = 0; i < 72; ++i) {
          const double t = -M_PI + (i + 0.37) * 2 * M_PI / 72;
          bool in_interval = false, near_end = false;
          for (const auto& iv : intervals) {
            for (double x : {t, t + 2 * M_PI, t - 2 * M_PI}) {
              in_interval = in_interval || (x > iv.lo && x < iv.hi);
              near_end = near_end || std::abs(x - iv.lo) < 1e-6 || std::abs(x - iv.hi) < 1e-6;
            }
          }
          if (near_end) continue;
          BackprojectionProblem p = pr;
          p.theta = t;
          const Region reg =
              vc ? BackprojectionWithActiveRays(p, SliceAt(nd, t).vc.active_rays) : ClassicBackprojection(p);
          const bool contains = RegionContainsPolygon(reg, r.vertices, 1e-9);
          ++checked;
          inside += contains;
          if (contains != in_interval) {
            ++wrong;
            ADD_FAILURE() << "seed " << seed << " R " << k << (vc ? " vc" : " classic") << " θ = " << t * 180 / M_PI
                          << ": contained " << contains << ", in an interval " << in_interval;
          }
        }
      }
    }
  }
  std::printf("checked %d orientations, R inside at %d, wrong %d; pieces %d, decided by carried regions %d\n", checked,
              inside, wrong, pieces, carried);
  if (testing::DesignedSeeds()) {  // not vacuous
    EXPECT_GT(inside, 20 / kSanitizerDivisor);
  }
  EXPECT_EQ(wrong, 0);
  // The carried regions decide most pieces (the sweep only where R is within 1e-6 of the scene of a moving edge), so
  // the check above is mostly a check of them.
  EXPECT_GT(carried * 10, pieces * 9);
}

// The area-against-θ curves of `visco critical --svg` come from carried regions, not sweeps: every sample agrees with
// the sweep at its θ (the classic region, and the region with the active rays of the slice standing for θ), on an
// example scene with visual constraints and on random scenes.
TEST(NondirectionalProperty, SampledAreasAreTheSweptOnes) {
  int compared = 0;
  double worst = 0;
  auto check = [&](const std::string& name, const BackprojectionProblem& pr) {
    const auto nd = ComputeNondirectional(pr, nullptr, Options());
    const auto samples = SampleAreas(nd, 48);
    const double size = (pr.bounds_max - pr.bounds_min).norm();
    // Every samples.size()/24-th sample: the evenly spaced ones and those just inside the intervals' ends.
    for (size_t i = 0; i < samples.size(); i += std::max<size_t>(1, samples.size() / 24)) {
      BackprojectionProblem p = pr;
      p.theta = samples[i].theta;
      const double classic = ClassicBackprojection(p).area;
      const double vc = BackprojectionWithActiveRays(p, SliceAt(nd, p.theta).vc.active_rays).area;
      const double err = std::max(std::abs(classic - samples[i].classic), std::abs(vc - samples[i].vc)) / (size * size);
      worst = std::max(worst, err);
      ++compared;
      EXPECT_LE(err, 1e-9) << name << " θ = " << p.theta * 180 / M_PI << "°: classic " << samples[i].classic
                           << " swept " << classic << ", vc " << samples[i].vc << " swept " << vc;
    }
  };
  const Scene s = LoadScene("data/scenes/fig13.json");
  const CSpace cspace(s);
  const VcRays rays = ComputeVcRays(s, cspace);
  check("fig13", SceneProblem(s, cspace, rays));
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(kSanitizerDivisor > 1 ? 1 : 4); ++seed) {
    if (const auto random = MakeRandomCase(seed)) check("seed " + std::to_string(seed), random->problem);
  }
  std::printf("area samples compared with sweeps: %d, worst difference %.2e of the scene's size squared\n", compared,
              worst);
  EXPECT_GE(compared, 24);
}

}  // namespace
}  // namespace visco::planning

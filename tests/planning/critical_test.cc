// The candidate critical orientations (planning/critical.h): the grid-indexed generator (the default) against the
// obvious scan over every segment, on seeded random whole scenes nobody designed (cameras anywhere and on the bounds,
// rays to the bounds, non-convex and overlapping obstacles, ε_v 2-20°, start regions anywhere), the benchmark's
// pentagon grids and every example scene: the same candidates (θ bit for bit, kind, refs, sources) and the same
// counts. The grid only skips segments that cannot meet the query, so any difference is a bug in it. And the compact
// list (CandidateList, what the nondirectional backprojection reads) against the listing before it, which kept every
// candidate as a CriticalOrientation (CriticalCandidatesReference): the same candidates in the same order, every
// field, on the same scenes. And the listing of a CandidateScope against the full one filtered by its rule. And the
// listing that takes the static candidates (ListStaticCandidates, listed once per scene) against the full one, on the
// problems of a multi-step search's children (a goal strip, forbidden strips, no rays) and on others.

#include "planning/critical.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>
#include <vector>

#include "planning/cspace.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "planning/scene_problem.h"
#include "planning/vc_rays.h"
#include "tests/bench/planning/pentagon_grid.h"
#include "tests/planning/random_vc_scenes.h"

namespace visco::planning {
namespace {

void ExpectSameCandidates(const std::string& name, const BackprojectionProblem& pr, const NamedPolygon* start) {
  CriticalCounts indexed_counts, scan_counts;
  const auto indexed = CriticalCandidates(pr, start, &indexed_counts, CandidateSearch::kIndexed);
  const auto scan = CriticalCandidates(pr, start, &scan_counts, CandidateSearch::kScan);
  ASSERT_EQ(indexed.size(), scan.size()) << name;
  for (size_t k = 0; k < scan.size(); ++k) {
    ASSERT_EQ(indexed[k].theta, scan[k].theta) << name << " candidate " << k;
    ASSERT_EQ(indexed[k].kind, scan[k].kind) << name << " candidate " << k;
    ASSERT_EQ(indexed[k].refs, scan[k].refs) << name << " candidate " << k;
    ASSERT_EQ(indexed[k].sources.size(), scan[k].sources.size()) << name << " candidate " << k;
    ASSERT_EQ(indexed[k].source_signs, scan[k].source_signs) << name << " candidate " << k;
    if (!scan[k].sources.empty()) {
      ASSERT_EQ(scan[k].source_signs.size(), scan[k].sources.size()) << name;
    }
    for (size_t s = 0; s < scan[k].sources.size(); ++s) {
      ASSERT_EQ(indexed[k].sources[s], scan[k].sources[s]) << name << " candidate " << k;
    }
  }
  for (int kind = 0; kind < 7; ++kind) EXPECT_EQ(indexed_counts.by_kind[kind], scan_counts.by_kind[kind]) << name;
  EXPECT_EQ(indexed_counts.visible_pairs, scan_counts.visible_pairs) << name;
  EXPECT_EQ(indexed_counts.points, scan_counts.points) << name;
  if (start) {
    const auto r_indexed = RCriticalCandidates(pr, *start, CandidateSearch::kIndexed);
    const auto r_scan = RCriticalCandidates(pr, *start, CandidateSearch::kScan);
    ASSERT_EQ(r_indexed.size(), r_scan.size()) << name;
    for (size_t k = 0; k < r_scan.size(); ++k) {
      EXPECT_EQ(r_indexed[k].theta, r_scan[k].theta) << name;
      EXPECT_EQ(r_indexed[k].refs, r_scan[k].refs) << name;
    }
  }
}

// Every field of candidate c against r's; the first that differs is named with both values.
::testing::AssertionResult SameCandidate(const CriticalOrientation& c, const CriticalOrientation& r) {
  // (A double streamed into the result prints all its digits; PrintToString rounds it.)
  if (c.theta != r.theta) return ::testing::AssertionFailure() << "theta: " << c.theta << " vs " << r.theta;
  ::testing::AssertionResult result = ::testing::AssertionSuccess();
  auto field = [&](const char* name, const auto& a, const auto& b) {
    if (result && !(a == b)) {
      result = ::testing::AssertionFailure()
               << name << ": " << ::testing::PrintToString(a) << " vs " << ::testing::PrintToString(b);
    }
  };
  field("kind", c.kind, r.kind);
  field("refs", c.refs, r.refs);
  field("sources", c.sources, r.sources);
  field("source_signs", c.source_signs, r.source_signs);
  field("feature", c.feature, r.feature);
  field("point", c.point, r.point);
  field("sliding", c.sliding, r.sliding);
  return result;
}

// The compact list against the reference listing: every field of every candidate, in order, and the counts.
void ExpectListIsTheReference(const std::string& name, const BackprojectionProblem& pr, const NamedPolygon* start,
                              const std::vector<CriticalOrientation>& reference, const CriticalCounts& reference_counts,
                              int threads) {
  CriticalCounts list_counts;
  const CandidateList list =
      CriticalCandidateList(pr, start, &list_counts, CandidateSearch::kIndexed, nullptr, threads);
  ASSERT_EQ(list.size(), reference.size()) << name;
  CriticalOrientation c;
  for (size_t k = 0; k < reference.size(); ++k) {
    const CriticalOrientation& r = reference[k];
    list.Get(k, c);
    ASSERT_TRUE(SameCandidate(c, r)) << name << " candidate " << k;
    ASSERT_EQ(list.theta(k), r.theta) << name << " candidate " << k;
    ASSERT_EQ(list.kind(k), r.kind) << name << " candidate " << k;
    ASSERT_EQ(list.Refs(k), r.refs) << name << " candidate " << k;
    ASSERT_EQ(list.sliding(k), r.sliding) << name << " candidate " << k;
    list.Get(k, c, /*with_refs=*/false);
    ASSERT_TRUE(c.refs.empty()) << name;
    ASSERT_EQ(c.sources, r.sources) << name << " candidate " << k;
  }
  for (int kind = 0; kind < 7; ++kind) EXPECT_EQ(list_counts.by_kind[kind], reference_counts.by_kind[kind]) << name;
  EXPECT_EQ(list_counts.visible_pairs, reference_counts.visible_pairs) << name;
  EXPECT_EQ(list_counts.points, reference_counts.points) << name;
  EXPECT_EQ(list_counts.segments, reference_counts.segments) << name;
  // TakeKind: the R-critical ones out, the rest in order.
  CandidateList rest = CriticalCandidateList(pr, start);
  const auto taken = rest.TakeKind(CriticalKind::kR);
  size_t t = 0, o = 0;
  for (const auto& r : reference) {
    if (r.kind == CriticalKind::kR) {
      ASSERT_LT(t, taken.size()) << name;
      EXPECT_EQ(taken[t].theta, r.theta) << name;
      EXPECT_EQ(taken[t++].refs, r.refs) << name;
    } else {
      ASSERT_LT(o, rest.size()) << name;
      EXPECT_EQ(rest.theta(o), r.theta) << name;
      EXPECT_EQ(rest.Refs(o++), r.refs) << name;
    }
  }
  EXPECT_EQ(t, taken.size()) << name;
  EXPECT_EQ(o, rest.size()) << name;
}

// The list is made on one thread and on three (the pairs' events listed side by side).
void ExpectSameAsReference(const std::string& name, const BackprojectionProblem& pr, const NamedPolygon* start) {
  const auto reference_counts_and_list = [&] {
    CriticalCounts counts;
    auto list = CriticalCandidatesReference(pr, start, &counts);
    return std::make_pair(counts, std::move(list));
  }();
  for (const int threads : {1, 3}) {
    ExpectListIsTheReference(name + (threads > 1 ? " (3 threads)" : ""), pr, start, reference_counts_and_list.second,
                             reference_counts_and_list.first, threads);
  }
}

// The listing with a CandidateScope against the full listing filtered by the scope's rule (critical.h): a candidate is
// kept where it has no sources (sliding, vc), is of the start region (R), runs along a static segment (a vgraph event
// with a feature), or each of its sources that is a ray point is one the scope names. Every field, in order, on one
// thread and on three; the scope names none of the ray points, then every third one. Adds the candidates left out to
// `left_out`.
void ExpectScopedListIsTheFilteredFullListing(const std::string& name, const BackprojectionProblem& pr,
                                              const NamedPolygon* start, std::int64_t& left_out) {
  const CandidateList full = CriticalCandidateList(pr, start);
  const std::vector<Eigen::Vector2d>& ray_points = full.ray_points();
  for (const int every : {0, 3}) {
    CandidateScope scope;
    scope.all = false;
    for (size_t k = 0; every > 0 && k < ray_points.size(); k += static_cast<size_t>(every)) {
      scope.ray_points.push_back(ray_points[k]);
    }
    const auto is = [](const std::vector<Eigen::Vector2d>& v, const Eigen::Vector2d& p) {
      return std::find(v.begin(), v.end(), p) != v.end();
    };
    std::vector<CriticalOrientation> expected;
    CriticalOrientation c;
    for (size_t i = 0; i < full.size(); ++i) {
      full.Get(i, c);
      bool keep =
          c.sources.empty() || c.kind == CriticalKind::kR || (c.kind == CriticalKind::kVgraph && !c.feature.empty());
      if (!keep) {
        keep = std::all_of(c.sources.begin(), c.sources.end(), [&](const Eigen::Vector2d& source) {
          return !is(ray_points, source) || is(scope.ray_points, source);
        });
      }
      if (keep) expected.push_back(c);
    }
    left_out += static_cast<std::int64_t>(full.size() - expected.size());
    for (const int threads : {1, 3}) {
      const std::string what =
          name + " (every " + std::to_string(every) + "th ray point, " + std::to_string(threads) + " threads)";
      const CandidateList scoped =
          CriticalCandidateList(pr, start, nullptr, CandidateSearch::kIndexed, nullptr, threads, &scope);
      EXPECT_EQ(scoped.ray_points(), ray_points) << what;
      ASSERT_EQ(scoped.size(), expected.size()) << what;
      for (size_t k = 0; k < expected.size(); ++k) {
        const CriticalOrientation& r = expected[k];
        scoped.Get(k, c);
        ASSERT_TRUE(SameCandidate(c, r)) << what << " candidate " << k;
      }
    }
  }
}

// The list of `pr` with the static candidates of `statics_of` taken against the list made without them: every field,
// in order, and the counts, on one thread and on three.
void ExpectStaticsChangeNothing(const std::string& name, const BackprojectionProblem& pr, const NamedPolygon* start,
                                const BackprojectionProblem& statics_of) {
  CriticalCounts full_counts;
  const CandidateList full = CriticalCandidateList(pr, start, &full_counts);
  const auto statics = ListStaticCandidates(statics_of, 2);
  CriticalOrientation c, r;
  for (const int threads : {1, 3}) {
    const std::string what = name + " (" + std::to_string(threads) + " threads)";
    CriticalCounts counts;
    const CandidateList list =
        CriticalCandidateList(pr, start, &counts, CandidateSearch::kIndexed, nullptr, threads, nullptr, statics.get());
    ASSERT_EQ(list.size(), full.size()) << what;
    for (size_t k = 0; k < full.size(); ++k) {
      full.Get(k, r);
      list.Get(k, c);
      ASSERT_TRUE(SameCandidate(c, r)) << what << " candidate " << k;
    }
    for (int kind = 0; kind < 7; ++kind) EXPECT_EQ(counts.by_kind[kind], full_counts.by_kind[kind]) << what;
    EXPECT_EQ(counts.visible_pairs, full_counts.visible_pairs) << what;
    EXPECT_EQ(counts.points, full_counts.points) << what;
  }
}

// A square strip of half-width w around the segment ab (like a child's goal and forbidden strips).
NamedPolygon StripAround(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double w) {
  const Eigen::Vector2d d = (b - a).normalized(), n(-d.y(), d.x());
  NamedPolygon p;
  p.vertices = {a - w * n, b - w * n, b + w * n, a + w * n};
  return p;
}

#if defined(__SANITIZE_ADDRESS__)
constexpr std::uint64_t kSeeds = 12;  // the scan is O(n³): slow under a sanitizer
#else
constexpr std::uint64_t kSeeds = 60;
#endif

TEST(CriticalCandidates, IndexedSearchEqualsTheScanOnRandomWholeScenes) {
  int compared = 0, with_start = 0;
  std::int64_t candidates = 0, left_out = 0;
  for (std::uint64_t seed = 1; seed <= kSeeds; ++seed) {
    Scene scene;
    double theta = 0;
    // Sizes 2 x 1 and 3 x 2 cells; every other scene with a start region (R-critical orientations).
    if (!testing::RandomWholeScene(seed, scene, theta, seed % 2 ? 2 : 3, seed % 2 ? 1 : 2)) continue;
    const bool start = seed % 2 == 0 && testing::PlaceStartRegion(seed, scene);
    const CSpace cspace(scene);
    const VcRays rays = ComputeVcRays(scene, cspace);
    const BackprojectionProblem pr = ProblemFromScene(scene, cspace, &rays, theta, /*kernel=*/false);
    NamedPolygon r;
    if (start) r.vertices = scene.start->polygon.vertices;
    ExpectSameCandidates("seed " + std::to_string(seed), pr, start ? &r : nullptr);
    ExpectSameAsReference("seed " + std::to_string(seed), pr, start ? &r : nullptr);
    ExpectScopedListIsTheFilteredFullListing("seed " + std::to_string(seed), pr, start ? &r : nullptr, left_out);
    candidates += static_cast<std::int64_t>(CriticalCandidates(pr, start ? &r : nullptr).size());
    ++compared;
    with_start += start;
  }
  std::printf("compared %d scenes (%d with a start region), %lld candidates, %lld left out by the scopes\n", compared,
              with_start, static_cast<long long>(candidates), static_cast<long long>(left_out));
  EXPECT_GT(left_out, 0) << "no scope left anything out: the filter is not exercised";
  EXPECT_GE(compared, static_cast<int>(kSeeds) * 9 / 10);
  EXPECT_GE(with_start, 1);
}

// The children of a multi-step search: the scene's C-obstacles and bounds with a goal strip on a ray, the rest of the
// ray forbidden, no rays; a goal on a C-obstacle's face; a goal whose edge runs through two C-obstacle vertices (their
// free edges' events along it are listed again); a start region; and statics of another scene (not taken).
TEST(CriticalCandidates, StaticCandidatesGiveTheSameListOnRandomWholeScenes) {
  int compared = 0;
  for (std::uint64_t seed = 1; seed <= kSeeds / 2; ++seed) {
    Scene scene;
    double theta = 0;
    if (!testing::RandomWholeScene(seed, scene, theta, seed % 2 ? 2 : 3, seed % 2 ? 1 : 2)) continue;
    const bool start = seed % 2 == 0 && testing::PlaceStartRegion(seed, scene);
    const CSpace cspace(scene);
    const VcRays rays = ComputeVcRays(scene, cspace);
    const BackprojectionProblem pr = ProblemFromScene(scene, cspace, &rays, theta, /*kernel=*/false);
    if (pr.obstacles.empty()) continue;
    NamedPolygon r;
    if (start) r.vertices = scene.start->polygon.vertices;
    const std::string name = "seed " + std::to_string(seed);
    ExpectStaticsChangeNothing(name + ", the scene", pr, start ? &r : nullptr, pr);
    const double w = 0.01;
    if (!pr.rays.empty() && !pr.rays[0].segments.empty()) {
      const auto& seg = pr.rays[0].segments[0];
      const Eigen::Vector2d m = 0.5 * (seg[0] + seg[1]);
      BackprojectionProblem child = pr;
      child.goal = {StripAround(m, seg[1], w)};
      child.forbidden.push_back(StripAround(seg[0], m, w));
      child.rays.clear();
      ExpectStaticsChangeNothing(name + ", a ray's child", child, start ? &r : nullptr, pr);
    }
    const auto& obstacle = pr.obstacles[0].vertices;
    BackprojectionProblem face = pr;
    face.goal = {StripAround(obstacle[0], obstacle[1], w)};
    face.rays.clear();
    ExpectStaticsChangeNothing(name + ", a face's child", face, start ? &r : nullptr, pr);
    if (obstacle.size() >= 3) {
      BackprojectionProblem through = face;
      NamedPolygon triangle;
      triangle.vertices = {obstacle[0], obstacle[2], obstacle[0] + 2 * (obstacle[1] - obstacle[0])};
      through.goal = {triangle};
      ExpectStaticsChangeNothing(name + ", a goal through two vertices", through, start ? &r : nullptr, pr);
    }
    BackprojectionProblem other = pr;
    other.obstacles[0].vertices[0] += Eigen::Vector2d(1e-3, 0);
    ExpectStaticsChangeNothing(name + ", another scene's statics", pr, start ? &r : nullptr, other);
    ++compared;
  }
  EXPECT_GE(compared, static_cast<int>(kSeeds) / 3);
}

TEST(CriticalCandidates, IndexedSearchEqualsTheScanOnPentagonGrids) {
  for (int m : {1, 4, 9, 16}) {
    ExpectSameCandidates("pentagons " + std::to_string(m), bench::PentagonGrid(m), nullptr);
    ExpectSameAsReference("pentagons " + std::to_string(m), bench::PentagonGrid(m), nullptr);
  }
}

TEST(CriticalCandidates, IndexedSearchEqualsTheScanOnTheExampleScenes) {
  for (const char* file : {"slot", "fig5", "fig13", "ledge", "corner", "slot_pinhole"}) {
    const Scene s = LoadScene(std::string("data/scenes/") + file + ".json");
    const CSpace cspace(s);
    const VcRays rays = ComputeVcRays(s, cspace);
    const BackprojectionProblem pr = ProblemFromScene(s, cspace, &rays, 0.0, /*kernel=*/false);
    NamedPolygon r;
    if (s.start) r.vertices = s.start->polygon.vertices;
    ExpectSameCandidates(file, pr, s.start ? &r : nullptr);
    ExpectSameAsReference(file, pr, s.start ? &r : nullptr);
    std::int64_t left_out = 0;
    ExpectScopedListIsTheFilteredFullListing(file, pr, s.start ? &r : nullptr, left_out);
    ExpectStaticsChangeNothing(file, pr, s.start ? &r : nullptr, pr);
  }
}

}  // namespace
}  // namespace visco::planning

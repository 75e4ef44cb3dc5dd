// The internals of the directional and nondirectional backprojections that need no exact arithmetic, tested
// directly (their headers are internal to planning/, namespace internal): the tracking-error geometry, region
// structure and its smallest edit, and the parallel loop.

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <vector>

#include "planning/backprojection/tracking_error.h"
#include "planning/nondirectional/region_structure.h"
#include "planning/threads.h"

namespace visco::planning::internal {
namespace {

using Eigen::Vector2d;

// A ring of unit-square-like vertices whose edges carry the given refs (all obstacle edges).
RegionRing Ring(const std::vector<std::string>& refs) {
  RegionRing r;
  for (size_t i = 0; i < refs.size(); ++i) {
    r.vertices.emplace_back(static_cast<double>(i), 0.0);
    r.edges.push_back({EdgeKind::kObstacle, refs[i], Vector2d::Zero(), {}, 0});
  }
  return r;
}

TEST(TrackingError, ParallelSegmentWithinDeltaIsOnePieceAlongTheRay) {
  // The ray runs from (0, 0) down to (0, -1); the segment is 5 mm beside it, δ = 1 cm.
  double t0 = -1, t1 = -1;
  ASSERT_TRUE(PieceWithinTrackingError({0.005, -0.2}, {0.005, -0.6}, {0, 0}, {0, -1}, 0.01, t0, t1));
  EXPECT_NEAR(std::min(t0, t1), 0.2, 1e-12);
  EXPECT_NEAR(std::max(t0, t1), 0.6, 1e-12);
}

TEST(TrackingError, ParallelSegmentFartherThanDeltaIsNoPiece) {
  double t0 = -1, t1 = -1;
  EXPECT_FALSE(PieceWithinTrackingError({0.05, -0.2}, {0.05, -0.6}, {0, 0}, {0, -1}, 0.01, t0, t1));
}

TEST(TrackingError, CrossingSegmentIsThePartWithinDelta) {
  // A horizontal segment crossing the ray at y = -0.5: its part within δ of the line is x in [-δ, δ], which projects
  // onto the one ray parameter 0.5.
  double t0 = -1, t1 = -1;
  ASSERT_TRUE(PieceWithinTrackingError({-0.02, -0.5}, {0.02, -0.5}, {0, 0}, {0, -1}, 0.01, t0, t1));
  EXPECT_NEAR(t0, 0.5, 1e-12);
  EXPECT_NEAR(t1, 0.5, 1e-12);
}

TEST(RegionStructure, RingSequenceDoesNotDependOnWhereTheRingStarts) {
  const RegionRing a = Ring({"c", "a", "b"}), b = Ring({"a", "b", "c"});
  EXPECT_EQ(RingSequence(a, "outer"), RingSequence(b, "outer"));
  EXPECT_EQ(Join(RingSequence(b, "outer")), "outer obstacle:a obstacle:b obstacle:c");
}

TEST(RegionStructure, SmallestEditOfOneInsertedEdge) {
  const RegionRing before = Ring({"A", "B", "C", "D"}), after = Ring({"A", "B", "X", "C", "D"});
  const auto edit = SmallestEdit(before, after);
  ASSERT_TRUE(edit.has_value());
  EXPECT_EQ(edit->b_count, 0u);
  EXPECT_EQ(edit->a_count, 1u);
  EXPECT_EQ(after.edges[edit->a_begin].ref, "X");
}

TEST(RegionStructure, SmallestEditOfOneReplacedEdge) {
  const RegionRing before = Ring({"A", "B", "C", "D", "E", "F"}), after = Ring({"A", "B", "C", "Y", "E", "F"});
  const auto edit = SmallestEdit(before, after);
  ASSERT_TRUE(edit.has_value());
  EXPECT_EQ(edit->b_count, 1u);
  EXPECT_EQ(edit->a_count, 1u);
  EXPECT_EQ(before.edges[edit->b_begin].ref, "D");
  EXPECT_EQ(after.edges[edit->a_begin].ref, "Y");
}

TEST(Threads, ParallelForRunsEveryIndexOnce) {
  for (const int threads : {1, 3}) {
    std::vector<std::atomic<int>> runs(257);
    ParallelFor(runs.size(), threads, nullptr, 0.0, 1.0, [&](size_t i) { runs[i].fetch_add(1); });
    for (size_t i = 0; i < runs.size(); ++i) EXPECT_EQ(runs[i].load(), 1) << "index " << i << ", " << threads;
  }
}

TEST(Threads, ParallelForPassesOnAWorkersException) {
  EXPECT_THROW(ParallelFor(50, 3, nullptr, 0.0, 1.0,
                           [](size_t i) {
                             if (i == 17) throw std::runtime_error("task 17");
                           }),
               std::runtime_error);
}

}  // namespace
}  // namespace visco::planning::internal

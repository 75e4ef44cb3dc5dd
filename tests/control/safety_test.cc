// Command limits, compared on seeded random commands with a direct reading of each limit.

#include "control/safety.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace visco::control {
namespace {

TEST(Safety, ClipsSpeedKeepingDirection) {
  SafetyFilter filter({0.1, 100.0, 0.0}, std::nullopt);
  Vec2 out;
  EXPECT_EQ(filter.Apply({0.3, 0.4}, {0.06, 0.08}, 0.002, nullptr, out), SafetyVerdict::kClipped);
  EXPECT_NEAR(out.x, 0.06, 1e-12);
  EXPECT_NEAR(out.y, 0.08, 1e-12);
}

TEST(Safety, DecelerationIsAccelerationLimitedToo) {
  // A zero nominal command (not a stop: stops bypass the filter in the executor) ramps down.
  SafetyFilter filter({1.0, 0.1, 0.0}, std::nullopt);
  Vec2 out{1, 1};
  EXPECT_EQ(filter.Apply({0, 0}, {0.5, 0.0}, 0.002, nullptr, out), SafetyVerdict::kClipped);
  EXPECT_NEAR(out.x, 0.5 - 0.1 * 0.002, 1e-15);
  EXPECT_EQ(out.y, 0.0);
}

TEST(Safety, NonFiniteCommandIsRejected) {
  SafetyFilter filter({1.0, 1.0, 0.0}, std::nullopt);
  Vec2 out{1, 1};
  EXPECT_EQ(filter.Apply({std::nan(""), 0}, {}, 0.002, nullptr, out), SafetyVerdict::kNonFinite);
  EXPECT_EQ(Norm(out), 0.0);
}

TEST(Safety, BoundsRemoveOutwardMotionAndRejectOutside) {
  SafetyFilter filter({1.0, 1000.0, 0.01}, Bounds{{0, 0}, {1, 1}});
  Vec2 out;
  const Vec2 near_right{0.995, 0.5};
  EXPECT_EQ(filter.Apply({0.1, 0.1}, {0.1, 0.1}, 0.002, &near_right, out), SafetyVerdict::kClipped);
  EXPECT_EQ(out.x, 0.0);
  EXPECT_NEAR(out.y, 0.1, 1e-12);
  const Vec2 outside{1.01, 0.5};
  EXPECT_EQ(filter.Apply({-0.1, 0.0}, {}, 0.002, &outside, out), SafetyVerdict::kOutsideBounds);
  EXPECT_EQ(Norm(out), 0.0);
}

TEST(SafetyProperty, EveryOutputRespectsEveryLimit) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> v(-1.0, 1.0);
  std::uniform_real_distribution<double> p(-0.1, 1.1);
  const SafetyLimits limits{0.2, 1.5, 0.02};
  const Bounds bounds{{0, 0}, {1, 1}};
  SafetyFilter filter(limits, bounds);
  Vec2 previous{};
  for (int i = 0; i < 100000; ++i) {
    const Vec2 nominal{v(rng), v(rng)};
    const Vec2 position{p(rng), p(rng)};
    Vec2 out;
    const SafetyVerdict verdict = filter.Apply(nominal, previous, 0.002, &position, out);
    const bool inside = position.x >= 0 && position.x <= 1 && position.y >= 0 && position.y <= 1;
    if (!inside) {
      EXPECT_EQ(verdict, SafetyVerdict::kOutsideBounds);
      EXPECT_EQ(Norm(out), 0.0);
      continue;
    }
    EXPECT_LE(Norm(out), limits.max_speed + 1e-12);
    EXPECT_LE(Norm(out - previous), limits.max_accel * 0.002 + 1e-12);
    // Outward components never grow near a bound.
    if (position.x <= limits.bounds_margin) {
      EXPECT_GE(out.x, std::min(0.0, previous.x) - 1e-12);
    }
    if (position.x >= 1 - limits.bounds_margin) {
      EXPECT_LE(out.x, std::max(0.0, previous.x) + 1e-12);
    }
    if (position.y <= limits.bounds_margin) {
      EXPECT_GE(out.y, std::min(0.0, previous.y) - 1e-12);
    }
    previous = out;
  }
}

}  // namespace
}  // namespace visco::control

// Command limits, compared on seeded random commands with a direct reading of each limit.

#include "control/safety.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

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

// With the default limits (0.2 m/s, 2 m/s^2, 5 mm: the stopping distance 10 mm is twice the margin) a
// robot driven straight at a bound brakes at the acceleration limit and comes to rest inside the margin, without
// leaving the bounds and without the hard outside-bounds stop, also when the position it is given is 6 ms old.
TEST(Safety, ApproachingABoundAtTheDefaultLimitsBrakesSmoothlyAndStopsInside) {
  const SafetyLimits limits;  // the defaults
  const Bounds bounds{{0, 0}, {1, 1}};
  const SafetyFilter filter(limits, bounds);
  for (int latency_steps : {0, 3}) {
    const double dt = 0.002;
    Vec2 p{0.5, 0.5};
    Vec2 previous{};
    std::vector<Vec2> history(8, p);
    double max_dv = 0.0;
    double max_x = 0.0;
    for (int k = 0; k < 3000; ++k) {
      const Vec2 measured = history[history.size() - 1 - latency_steps];
      Vec2 out;
      const SafetyVerdict verdict = filter.Apply({0.2, 0.0}, previous, dt, &measured, out);
      ASSERT_NE(verdict, SafetyVerdict::kOutsideBounds) << "step " << k << " latency " << latency_steps;
      max_dv = std::max(max_dv, Norm(out - previous));
      p = p + dt * out;  // a robot that follows its command
      max_x = std::max(max_x, p.x);
      previous = out;
      history.erase(history.begin());
      history.push_back(p);
    }
    EXPECT_LE(max_x, 1.0) << "latency " << latency_steps;
    EXPECT_EQ(previous.x, 0.0);  // at rest against the margin line
    if (latency_steps == 0) {
      EXPECT_LE(max_x, 1.0 - limits.bounds_margin + 1e-5);  // the discrete curve: within 10 µm of the line
      EXPECT_GE(p.x, 1.0 - limits.bounds_margin - 0.001);
    }
    // Braking at the acceleration limit with an exact position; with a stale one the curve, followed late, asks
    // for up to a few a dt in its last steps (measured 3.04: still inside the margin).
    EXPECT_LE(max_dv, (latency_steps == 0 ? 1.0 + 1e-9 : 4.0) * limits.max_accel * dt) << "latency " << latency_steps;
    RecordProperty(latency_steps == 0 ? "max_dv_over_a_dt" : "max_dv_over_a_dt_latency",
                   std::to_string(max_dv / (limits.max_accel * dt)));
    std::printf("approach at default limits, position %d ms old: closest %.2f mm from the bound, max |dv| %.2f a dt\n",
                latency_steps * 2, (1.0 - max_x) * 1e3, max_dv / (limits.max_accel * dt));
  }
}

TEST(SafetyProperty, EveryOutputRespectsEveryLimit) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> v(-1.0, 1.0);
  std::uniform_real_distribution<double> p(-0.1, 1.1);
  const SafetyLimits limits{0.2, 1.5, 0.02};
  const Bounds bounds{{0, 0}, {1, 1}};
  SafetyFilter filter(limits, bounds);
  const SafetyFilter unbounded(limits, std::nullopt);
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
    // The acceleration limit holds unless the braking curve towards a bound cut an outward component: then the
    // output is the unbounded one with outward components reduced towards zero (the bounds win), each at most the
    // braking speed for the distance to the margin line.
    Vec2 free;
    unbounded.Apply(nominal, previous, 0.002, nullptr, free);
    if (out.x == free.x && out.y == free.y) {
      EXPECT_LE(Norm(out - previous), limits.max_accel * 0.002 + 1e-12);
    } else {
      EXPECT_TRUE(std::abs(out.x) <= std::abs(free.x) && out.x * free.x >= 0);
      EXPECT_TRUE(std::abs(out.y) <= std::abs(free.y) && out.y * free.y >= 0);
    }
    const double a = limits.max_accel, h = 0.5 * a * 0.002, m = limits.bounds_margin;
    const auto braking = [&](double d) { return d > 0 ? std::sqrt(h * h + 2 * a * d) - h : 0.0; };
    EXPECT_LE(out.x, braking(1 - m - position.x) + 1e-12);
    EXPECT_GE(out.x, -braking(position.x - m) - 1e-12);
    EXPECT_LE(out.y, braking(1 - m - position.y) + 1e-12);
    EXPECT_GE(out.y, -braking(position.y - m) - 1e-12);
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

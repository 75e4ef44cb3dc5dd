// The visual compliance law: its parts, its sign, its saturation, and closed-loop convergence on seeded random
// rays against the exact planar camera (synthetic_camera.h).

#include "control/servo_law.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "control/synthetic_camera.h"
#include "tests/control/harness.h"

namespace visco::control {
namespace {

TEST(ServoLaw, TangentialPartIsTheProjectionOfTheCommand) {
  ServoConfig config;
  const Vec2 t = FromAngle(0.3);
  const Vec2 u = FromAngle(0.3 + 0.5);
  const ServoOutput out = VisualComplianceLaw(config, t, u, 0.1, 0.0, 1.0);
  EXPECT_NEAR(Dot(out.tangential, t), 0.1 * std::cos(0.5), 1e-12);
  EXPECT_NEAR(Cross(t, out.tangential), 0.0, 1e-12);
  EXPECT_NEAR(Norm(out.normal), 0.0, 1e-12);  // on the line: no correction
}

TEST(ServoLaw, CorrectionOpposesTheErrorThroughTheInteractionMatrix) {
  ServoConfig config;
  config.gain = 3.0;
  config.focal_px = 600;
  config.max_normal_speed = 10.0;
  const Vec2 t = FromAngle(-1.0);
  for (double d : {-20.0, -1.0, 2.5, 40.0}) {
    const double range = 1.7;
    const ServoOutput out = VisualComplianceLaw(config, t, t, 0.05, d, range);
    const Vec2 L = InteractionRow(config, t, range);
    // The predicted image velocity is exactly -gain * error (tangential motion does not move the line distance).
    EXPECT_NEAR(Dot(L, out.velocity), -config.gain * d, 1e-9);
    EXPECT_FALSE(out.saturated);
  }
}

TEST(ServoLaw, CorrectionSaturates) {
  ServoConfig config;
  config.max_normal_speed = 0.01;
  const ServoOutput out = VisualComplianceLaw(config, {1, 0}, {1, 0}, 0.05, -1e4, 1.0);
  EXPECT_TRUE(out.saturated);
  EXPECT_NEAR(Norm(out.normal), 0.01, 1e-15);
  EXPECT_GT(out.normal.y, 0);  // d < 0: push towards the left normal (+y for a ray along +x)
}

TEST(ServoLaw, NominalRangeWhenUnknown) {
  ServoConfig config;
  config.nominal_range_m = 2.0;
  const Vec2 a = InteractionRow(config, {0, 1}, 0.0);
  EXPECT_NEAR(a.x, -config.focal_px / 2.0, 1e-12);
}

TEST(ServoLaw, WithAnInteractionRowTheImageVelocityIsMinusGainTimesTheError) {
  ServoConfig config;
  config.gain = 2.5;
  config.max_normal_speed = 10.0;
  const Vec2 t = FromAngle(0.7), n = LeftNormal(t);
  const Vec2 J = 55.0 * n + 7.0 * t;  // off the line: moving along the ray changes d too
  const Vec2 u = FromAngle(0.7 - 0.4);
  for (double d : {-30.0, -0.5, 0.0, 3.0, 25.0}) {
    const ServoOutput out = VisualComplianceLaw(config, t, u, 0.08, d, J);
    EXPECT_NEAR(Dot(J, out.velocity), -config.gain * d, 1e-12);
    EXPECT_NEAR(Dot(out.tangential, t), 0.08 * std::cos(0.4), 1e-15);  // the commanded motion along the ray
    EXPECT_NEAR(Dot(out.normal, t), 0.0, 1e-15);                       // the correction is along n
    EXPECT_FALSE(out.saturated || out.degenerate);
  }
  // A row that does not see motion along n (behind the camera, the horizon): no correction, said so.
  const ServoOutput behind = VisualComplianceLaw(config, t, u, 0.08, 5.0, Vec2{} - J);
  EXPECT_TRUE(behind.degenerate);
  EXPECT_EQ(Norm(behind.normal), 0.0);
  // Saturation as in the planar law.
  config.max_normal_speed = 0.01;
  const ServoOutput big = VisualComplianceLaw(config, t, u, 0.08, 500.0, J);
  EXPECT_TRUE(big.saturated);
  EXPECT_NEAR(Norm(big.normal), 0.01, 1e-15);
  EXPECT_LT(Dot(big.normal, n), 0.0);
}

// Property: on seeded random rays, start offsets and commanded directions within 60 degrees of the ray, the law
// closed through the exact camera model (sampled at 30 Hz, zero-order hold, 500 Hz control) brings the error below
// 0.5 px within 2 s and keeps it there, while the vertex advances along the ray.
TEST(ServoLawProperty, ConvergesOnRandomRays) {
  std::mt19937_64 rng(20261122);
  std::uniform_real_distribution<double> angle(-std::numbers::pi, std::numbers::pi);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const Vec2 camera{0.0, 0.0};
    const double ray_angle = angle(rng);
    const double length = 1.0 + 2.0 * unit(rng);
    const Vec2 from = camera - length * FromAngle(ray_angle);  // obstacle vertex
    Task task;
    task.rays.push_back(testing::MakeRay("r", from, camera, 0, {0.0, 0.0}));
    ServoConfig config;
    config.focal_px = 400 + 800 * unit(rng);
    SyntheticCamera cam(task, {config.focal_px, 0.5, 0.0}, 1);
    const Vec2 t = task.rays[0].direction;
    // Start 60%..90% of the way from the camera towards the vertex, offset sideways by up to 2 cm.
    Vec2 q = from + (0.1 + 0.3 * unit(rng)) * (camera - from) + (0.04 * unit(rng) - 0.02) * LeftNormal(t);
    const double sign = unit(rng) < 0.5 ? 1.0 : -1.0;  // move towards or away from the camera
    const Vec2 u = FromAngle(std::atan2(sign * t.y, sign * t.x) + (unit(rng) - 0.5) * 2.0 * std::numbers::pi / 3);
    double held_d = cam.SignedDistance(0, q);
    double range = 0;
    const Vec2 start = q;
    double worst_late = 0;
    for (int k = 0; k < 1500; ++k) {  // 3 s at 500 Hz
      if (k % 17 == 0) held_d = cam.SignedDistance(0, q, &range);
      const ServoOutput out = VisualComplianceLaw(config, t, u, 0.02, held_d, range);
      q = q + 0.002 * out.velocity;
      if (k > 1000) worst_late = std::max(worst_late, std::abs(cam.SignedDistance(0, q)));
    }
    EXPECT_LT(worst_late, 0.5) << "trial " << trial;
    EXPECT_GT(sign * Dot(q - start, t), 0.0) << "trial " << trial;  // it moved along the ray, the commanded way
  }
}

}  // namespace
}  // namespace visco::control

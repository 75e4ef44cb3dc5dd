// The robot's command frame fitted to the world (`visco robot-frame`): against synthetic truth with noise (the
// estimate within its stated uncertainty), exact without noise, and refused when the points do not determine it.

#include "common/robot_frame.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "common/error.h"

namespace visco {
namespace {

Eigen::Matrix2d Rot(double a) {
  Eigen::Matrix2d r;
  r << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
  return r;
}

std::string ErrorOf(const std::vector<FramePoint>& points, bool with_scale) {
  try {
    FitRobotFrame(points, with_scale, "pts.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no InputError";
}

double AngleDiff(double a, double b) { return std::remainder(a - b, 2 * M_PI); }

TEST(RobotFrame, ExactWithoutNoise) {
  for (bool with_scale : {false, true}) {
    const double theta = 2.1, scale = with_scale ? 0.98 : 1.0;
    const Eigen::Vector2d t(0.4, -1.2);
    std::vector<FramePoint> pts;
    for (const Eigen::Vector2d& c : {Eigen::Vector2d(0, 0), Eigen::Vector2d(0.3, 0), Eigen::Vector2d(0.1, 0.25)}) {
      pts.push_back({c, scale * Rot(theta) * c + t});
    }
    const RobotFrame f = FitRobotFrame(pts, with_scale);
    EXPECT_NEAR(AngleDiff(f.theta, theta), 0, 1e-12);
    EXPECT_NEAR(f.scale, scale, 1e-12);
    EXPECT_NEAR((f.t - t).norm(), 0, 1e-12);
    EXPECT_LT(f.rms_residual_m, 1e-12);
    EXPECT_EQ(f.dof, with_scale ? 2 : 3);
  }
}

// Seeded random frames and K = 6 random positions with 1 mm of observation noise: each parameter within 3 stated
// sigmas of the truth in at least 95 % of 400 fits (rigid and with scale), and the stated noise near the true one.
TEST(RobotFrame, NoisyFitWithinStatedUncertainty) {
  std::mt19937 rng(4041);
  std::uniform_real_distribution<double> u(-1, 1);
  const double noise = 0.001;
  std::normal_distribution<double> n(0, noise);
  for (bool with_scale : {false, true}) {
    const int fits = 400;
    int within_theta = 0, within_t = 0, within_scale = 0;
    double sigma_sum = 0;
    for (int i = 0; i < fits; ++i) {
      const double theta = M_PI * u(rng), scale = with_scale ? 1 + 0.05 * u(rng) : 1.0;
      const Eigen::Vector2d t(u(rng), u(rng));
      std::vector<FramePoint> pts;
      for (int k = 0; k < 6; ++k) {
        const Eigen::Vector2d c(0.3 * u(rng), 0.3 * u(rng));
        pts.push_back({c, scale * Rot(theta) * c + t + Eigen::Vector2d(n(rng), n(rng))});
      }
      const RobotFrame f = FitRobotFrame(pts, with_scale);
      within_theta += std::abs(AngleDiff(f.theta, theta)) <= 3 * f.theta_stddev ? 1 : 0;
      within_t += std::abs(f.t.x() - t.x()) <= 3 * f.t_stddev.x() && std::abs(f.t.y() - t.y()) <= 3 * f.t_stddev.y();
      within_scale += !with_scale || std::abs(f.scale - scale) <= 3 * f.scale_stddev ? 1 : 0;
      sigma_sum += f.sigma_m;
    }
    std::printf("%s: within 3 sigma: theta %d, t %d, scale %d of %d; mean sigma %.3f mm (true 1 mm)\n",
                with_scale ? "with scale" : "rigid", within_theta, within_t, within_scale, fits,
                sigma_sum / fits * 1e3);
    EXPECT_GE(within_theta, 0.95 * fits);
    EXPECT_GE(within_t, 0.95 * fits);
    EXPECT_GE(within_scale, 0.95 * fits);
    EXPECT_NEAR(sigma_sum / fits, noise, 0.15 * noise);
  }
}

TEST(RobotFrame, RefusedWhenUndetermined) {
  const Eigen::Vector2d a(0.1, 0.2), b(0.4, 0.2);
  EXPECT_NE(ErrorOf({}, false).find("pts.json: points: the commanded positions do not determine"), std::string::npos);
  EXPECT_NE(ErrorOf({{a, a}}, false).find("at least 2 distinct positions"), std::string::npos);
  EXPECT_NE(ErrorOf({{a, a}, {a, b}, {a, a}}, true).find("that all coincide"), std::string::npos);
  EXPECT_NE(ErrorOf({{a, a}, {b, a}}, false).find("the observed positions all coincide"), std::string::npos);
  // A command frame with a mirrored axis: refused, not fitted with a rotation.
  std::vector<FramePoint> mirrored;
  for (const Eigen::Vector2d& c :
       {Eigen::Vector2d(0, 0), Eigen::Vector2d(0.3, 0), Eigen::Vector2d(0.1, 0.25), Eigen::Vector2d(0.2, -0.2)}) {
    mirrored.push_back({c, Rot(0.3) * Eigen::Vector2d(c.x(), -c.y())});
  }
  EXPECT_NE(ErrorOf(mirrored, false).find("mirrored"), std::string::npos);
  EXPECT_NE(ErrorOf(mirrored, true).find("mirrored"), std::string::npos);
  // Collinear positions determine a 2-D rotation (no refusal), and two points fit exactly (dof 0 with scale).
  const RobotFrame two = FitRobotFrame({{a, Rot(1) * a}, {b, Rot(1) * b}}, true);
  EXPECT_NEAR(two.theta, 1, 1e-12);
  EXPECT_EQ(two.dof, 0);
  EXPECT_EQ(two.theta_stddev, 0);
}

TEST(RobotFrame, FilesRoundTripAndBadInputNamesTheEntry) {
  const auto dir = std::filesystem::temp_directory_path() / ("visco_robot_frame_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string pts = (dir / "pts.json").string(), out = (dir / "frame.json").string();
  std::ofstream(pts) << R"({"points": [{"commanded": [0, 0], "observed": [1, 1]},
                                       {"commanded": [0.5, 0], "observed": [1, 1.5]},
                                       {"commanded": [0, 0.5], "observed": [0.5, 1]}]})";
  const RobotFrame f = FitRobotFrame(LoadFramePoints(pts), false, pts);
  EXPECT_NEAR(f.theta, M_PI / 2, 1e-12);
  SaveRobotFrame(f, out);
  const RobotFrame g = LoadRobotFrame(out);
  EXPECT_NEAR(g.theta, f.theta, 1e-12);
  EXPECT_NEAR((g.t - Eigen::Vector2d(1, 1)).norm(), 0, 1e-12);
  auto error = [&](const std::string& text) {
    std::ofstream(pts) << text;
    try {
      LoadFramePoints(pts);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no InputError");
  };
  EXPECT_NE(error(R"({"points": [{"commanded": [0, 0]}]})").find("points[0].observed: missing"), std::string::npos);
  EXPECT_NE(
      error(R"({"points": [{"commanded": [0], "observed": [1, 1]}]})").find("points[0].commanded: must be [x, y]"),
      std::string::npos);
  EXPECT_NE(error(R"({"points": [], "extra": 1})").find("extra: unknown field"), std::string::npos);
  EXPECT_NE(error(R"({"pts": []})").find("points: missing"), std::string::npos);
  EXPECT_NE(error("{").find("not valid JSON"), std::string::npos);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace visco

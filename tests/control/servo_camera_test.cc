// The servo law's calibrated camera (control/servo_law.h, control/servo_camera.h) against ViSP and vision:
// - its interaction row J (the derivative of the signed pixel distance of the tracked point to the VC line with
//   respect to the robot's planar motion) equals the one built from ViSP's own features (vpFeaturePoint's interaction
//   matrix, the VC line projected by vpLine / vpFeatureLine, vpMeterPixelConversion) on random tilted cameras;
// - it equals finite differences of vision's own measurement (vision::SignedImageDistance) when the robot moves;
// - the files `visco run --camera --extrinsics --objects` reads give the camera vision's loaders give;
// - in closed loop the law brings d to 0 at the gain's rate with a tilted camera, where the planar f/range law does
//   not (the figures are printed).
// This test links ViSP and vision; visco::control does not.

#include "control/servo_camera.h"

#include <gtest/gtest.h>
#include <unistd.h>
#include <visp3/core/vpCameraParameters.h>
#include <visp3/core/vpHomogeneousMatrix.h>
#include <visp3/core/vpImagePoint.h>
#include <visp3/core/vpLine.h>
#include <visp3/core/vpMeterPixelConversion.h>
#include <visp3/core/vpPoint.h>
#include <visp3/visual_features/vpFeatureBuilder.h>
#include <visp3/visual_features/vpFeatureLine.h>
#include <visp3/visual_features/vpFeaturePoint.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <vector>

#include "common/error.h"
#include "control/servo_law.h"
#include "vision/camera.h"
#include "vision/features.h"
#include "vision/object_model.h"

namespace visco::control {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A camera at `eye` looking at `target` on the plane, turned by `roll` about its optical axis (ViSP's camera frame:
// z forward, x right, y down).
Eigen::Isometry3d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, double roll) {
  const Eigen::Vector3d z = (target - eye).normalized();
  Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ());
  if (x.norm() < 1e-6) x = Eigen::Vector3d::UnitX();
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d r;
  r.col(0) = x, r.col(1) = y, r.col(2) = z;
  Eigen::Isometry3d wMc = Eigen::Isometry3d::Identity();
  wMc.linear() = r * Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  wMc.translation() = eye;
  return wMc;
}

ServoCamera FromPose(double px, double py, double u0, double v0, const Eigen::Isometry3d& wMc, double height) {
  double r[3][3], t[3];
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 3; ++k) r[i][k] = wMc.linear()(i, k);
    t[i] = wMc.translation()[i];
  }
  return MakeServoCamera(px, py, u0, v0, r, t, height);
}

vpHomogeneousMatrix ToViSP(const Eigen::Isometry3d& cMw) {
  vpHomogeneousMatrix m;
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 3; ++k) m[i][k] = cMw.linear()(i, k);
    m[i][3] = cMw.translation()[i];
  }
  return m;
}

// One random scene: a camera anywhere above the plane looking down at a random tilt, a VC ray through its foot point,
// and a tracked point in front of it, within the image.
struct RandomCase {
  double px, py, u0, v0;
  Eigen::Isometry3d wMc;
  double height;   // of the tracked point
  Vec2 direction;  // of the ray, towards the camera's foot point
  Vec2 point;      // the tracked point's plane position
  Vec2 from;       // the obstacle vertex (on the ray, behind the point)
};

RandomCase Draw(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  RandomCase c;
  c.px = 300 + 1200 * unit(rng);
  c.py = c.px * (0.9 + 0.2 * unit(rng));
  c.u0 = 200 + 400 * unit(rng);
  c.v0 = 150 + 300 * unit(rng);
  const double H = 1 + 9 * unit(rng);
  const Eigen::Vector3d eye(-10 + 20 * unit(rng), -10 + 20 * unit(rng), H);
  const double tilt = 50 * kPi / 180 * unit(rng);  // optical axis from straight down
  const double azimuth = 2 * kPi * unit(rng);
  const Eigen::Vector3d target =
      eye + Eigen::Vector3d(H * std::tan(tilt) * std::cos(azimuth), H * std::tan(tilt) * std::sin(azimuth), -H);
  c.wMc = LookAt(eye, target, 2 * kPi * unit(rng));
  c.height = 0.9 * H * unit(rng);
  // The tracked point: a random pixel, cast onto the plane z = height.
  Eigen::Vector3d ray_w;
  do {  // a pixel within the central 60% of a 640x480 image, whose line of sight goes down steeply enough
    const Eigen::Vector3d ray_c((-0.3 + 0.6 * unit(rng)) * 640 / c.px, (-0.3 + 0.6 * unit(rng)) * 480 / c.py, 1.0);
    ray_w = c.wMc.linear() * ray_c.normalized();
  } while (ray_w.z() > -0.3);
  const double s = (c.height - eye.z()) / ray_w.z();
  const Eigen::Vector3d p = eye + s * ray_w;
  c.point = {p.x(), p.y()};
  // The ray: from an obstacle vertex up to 4 m behind the point's neighbourhood, towards the foot point.
  const Vec2 foot{eye.x(), eye.y()};
  const Vec2 near = c.point + (0.3 * unit(rng) - 0.15) * FromAngle(2 * kPi * unit(rng));
  const Vec2 away = near - foot;
  c.from = foot + (1 + 0.3 * unit(rng)) * away;
  c.direction = (1 / Norm(foot - c.from)) * (foot - c.from);
  return c;
}

// ViSP's numbers for one case: the signed distance (pixels) and its interaction row with respect to the point's
// planar motion, built from vpFeaturePoint's interaction matrix and the VC line projected by vpLine / vpFeatureLine.
struct ViSPResult {
  double d;
  Vec2 row;
  double line_normal[2];  // (a, b) of the pixel line, oriented
};

ViSPResult ViSPRow(const RandomCase& c) {
  const vpCameraParameters cam(c.px, c.py, c.u0, c.v0);
  const Eigen::Isometry3d cMw_e = c.wMc.inverse();
  const vpHomogeneousMatrix cMw = ToViSP(cMw_e);
  // The point and its feature (x, y) with its depth, through the pixel (vpFeatureBuilder from an image point).
  vpPoint P(c.point.x, c.point.y, c.height);
  P.track(cMw);
  double u, v;
  vpMeterPixelConversion::convertPoint(cam, P.get_x(), P.get_y(), u, v);
  vpFeaturePoint s;
  vpFeatureBuilder::create(s, cam, vpImagePoint(v, u));
  s.set_Z(P.get_Z());
  const vpMatrix L = s.interaction();  // 2x6, (dx, dy) = L v_camera
  // The VC line: the intersection of the VC surface (the vertical plane through the camera centre containing the ray)
  // with the plane z = height, projected.
  const Vec2 n = LeftNormal(c.direction);
  const Eigen::Vector3d C = c.wMc.translation();
  vpLine line;
  line.setWorldCoordinates(n.x, n.y, 0, -(n.x * C.x() + n.y * C.y()), 0, 0, 1, -c.height);
  line.track(cMw);
  vpFeatureLine fl;
  vpFeatureBuilder::create(fl, line);
  const double rho = fl.getRho(), theta = fl.getTheta();
  // x cos(theta) + y sin(theta) - rho = 0 in normalized coordinates; in pixels, normalized to a unit normal.
  const double a = std::cos(theta) / c.px, b = std::sin(theta) / c.py;
  const double k = std::hypot(a, b);
  double sigma = 1.0;
  {  // orient: a point just left of the ray (in the world) is positive
    vpPoint Q(c.from.x + 0.01 * n.x, c.from.y + 0.01 * n.y, c.height);
    Q.track(cMw);
    if (std::cos(theta) * Q.get_x() + std::sin(theta) * Q.get_y() - rho < 0) sigma = -1.0;
  }
  ViSPResult r;
  r.d = sigma * (std::cos(theta) * s.get_x() + std::sin(theta) * s.get_y() - rho) / k;
  r.line_normal[0] = sigma * a / k, r.line_normal[1] = sigma * b / k;
  // dd/d(x, y) = sigma / k (cos theta, sin theta); a point moving at w (world) in front of a still camera is the
  // camera moving at -cRw w in front of a still point.
  const double gx = sigma * std::cos(theta) / k, gy = sigma * std::sin(theta) / k;
  const Eigen::Matrix3d cRw = cMw_e.linear();
  double row[2] = {0, 0};
  for (int j = 0; j < 2; ++j) {
    for (int m = 0; m < 3; ++m) row[j] += (gx * L[0][m] + gy * L[1][m]) * -cRw(m, j);
  }
  r.row = {row[0], row[1]};
  return r;
}

TEST(ServoJacobian, EqualsViSPsInteractionOnRandomTiltedCameras) {
  std::mt19937_64 rng(20261204);
  double worst = 0, worst_d = 0, worst_line = 0;
  for (int trial = 0; trial < 500; ++trial) {
    const RandomCase c = Draw(rng);
    const ServoCamera cam = FromPose(c.px, c.py, c.u0, c.v0, c.wMc, c.height);
    const ViSPResult visp = ViSPRow(c);
    bool in_front = false;
    const double d = ModelSignedDistance(cam, c.direction, c.point, &in_front);
    ASSERT_TRUE(in_front) << "trial " << trial;
    const Vec2 row = CameraInteractionRow(cam, c.direction, c.point, 1e-9);
    const ImageLine line = VcImageLine(cam, c.direction);
    const double scale = Norm(visp.row);
    ASSERT_GT(scale, 0);
    const double err = Norm(row - visp.row) / scale;
    const double err_d = std::abs(d - visp.d) / (std::abs(visp.d) + 1.0);
    const double err_line = std::hypot(line.a - visp.line_normal[0], line.b - visp.line_normal[1]);
    worst = std::max(worst, err), worst_d = std::max(worst_d, err_d), worst_line = std::max(worst_line, err_line);
    EXPECT_LT(err, 1e-9) << "trial " << trial << ": J (" << row.x << ", " << row.y << ") vs ViSP (" << visp.row.x
                         << ", " << visp.row.y << ")";
    EXPECT_LT(err_d, 1e-9) << "trial " << trial << ": d " << d << " vs ViSP " << visp.d;
    EXPECT_LT(err_line, 1e-9) << "trial " << trial;
    // On the VC surface J is along the ray's normal; off it, moving along the ray changes d (perspective).
    EXPECT_GT(Dot(row, LeftNormal(c.direction)), 0) << "trial " << trial;
  }
  std::printf("500 random tilted cameras: worst relative difference to ViSP: J %.2e, d %.2e, line normal %.2e\n", worst,
              worst_d, worst_line);
}

// vision's own measurement (vision::SignedImageDistance: the VC line through the images of the obstacle edge's ends,
// the robot's top vertex) moved by finite steps of the robot in the plane.
TEST(ServoJacobian, EqualsFiniteDifferencesOfVisionsMeasurement) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  double worst = 0, worst_d = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const RandomCase c = Draw(rng);
    const vision::CameraModel camera = vision::CameraModel::Pinhole(c.px, c.py, c.u0, c.v0, 640, 480);
    const Eigen::Isometry3d cMw = c.wMc.inverse();
    vision::ObjectModel robot;
    const Eigen::Vector2d cm(0.3 * unit(rng), 0.3 * unit(rng));  // the CM vertex in the robot frame
    robot.polygon = {{0, 0}, cm, {-0.1, 0.2}};
    robot.height = c.height > 0 ? c.height : 0.01;
    vision::ObjectModel obstacle;
    obstacle.polygon = {{c.from.x, c.from.y}, {c.from.x + 1, c.from.y}, {c.from.x, c.from.y + 1}};
    obstacle.height = 0.2 + unit(rng);
    const ServoCamera cam = FromPose(c.px, c.py, c.u0, c.v0, c.wMc, robot.height);
    const Vec2 reference = c.point - Vec2{cm.x(), cm.y()};  // the robot's reference point
    auto measure = [&](Vec2 q) {
      Eigen::Isometry3d wMr = Eigen::Isometry3d::Identity();
      wMr.translation() = Eigen::Vector3d(q.x, q.y, 0);
      return vision::SignedImageDistance(camera, c.wMc, robot, cMw * wMr, 1, obstacle, cMw, 0);
    };
    const double h = 1e-5;
    const Vec2 fd{(measure(reference + Vec2{h, 0}) - measure(reference - Vec2{h, 0})) / (2 * h),
                  (measure(reference + Vec2{0, h}) - measure(reference - Vec2{0, h})) / (2 * h)};
    const Vec2 row = CameraInteractionRow(cam, c.direction, c.point, 1e-9);
    const double err = Norm(row - fd) / Norm(fd);
    const double d_vision = measure(reference), d_model = ModelSignedDistance(cam, c.direction, c.point);
    const double err_d = std::abs(d_model - d_vision) / (std::abs(d_vision) + 1.0);
    worst = std::max(worst, err), worst_d = std::max(worst_d, err_d);
    EXPECT_LT(err, 1e-6) << "trial " << trial << ": J (" << row.x << ", " << row.y << ") vs finite differences ("
                         << fd.x << ", " << fd.y << ")";
    EXPECT_LT(err_d, 1e-8) << "trial " << trial << ": model d " << d_model << " vs vision's " << d_vision;
  }
  std::printf("300 random cases against vision's measurement: worst relative difference J %.2e, d %.2e\n", worst,
              worst_d);
}

void ExpectSameCamera(const ServoCamera& a, const ServoCamera& b) {
  ASSERT_TRUE(a.valid && b.valid);
  EXPECT_DOUBLE_EQ(a.px, b.px);
  EXPECT_DOUBLE_EQ(a.py, b.py);
  EXPECT_DOUBLE_EQ(a.u0, b.u0);
  EXPECT_DOUBLE_EQ(a.v0, b.v0);
  EXPECT_DOUBLE_EQ(a.point_height_m, b.point_height_m);
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(a.cRw[i][k], b.cRw[i][k], 1e-12);
    EXPECT_NEAR(a.ctw[i], b.ctw[i], 1e-12);
  }
}

ServoCamera ThroughVision(const std::string& calibration, const std::string& extrinsics, const std::string& objects) {
  const vision::CameraModel camera = vision::LoadCamera(calibration);
  return FromPose(camera.px, camera.py, camera.u0, camera.v0, vision::LoadExtrinsics(extrinsics),
                  vision::LoadObjectModels(objects).robot.height);
}

TEST(ServoCameraFiles, GiveWhatVisionsLoadersGive) {
  const std::string cal = "data/sim/slot_camera.xml", ext = "data/sim/slot_extrinsics.json",
                    obj = "data/sim/slot_objects.json";
  ExpectSameCamera(LoadServoCamera(cal, ext, obj), ThroughVision(cal, ext, obj));
  const auto dir = std::filesystem::temp_directory_path() / ("servo_camera_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  // Both ViSP models: the one with distortion is preferred (vision::LoadCamera).
  const std::string both = (dir / "both.xml").string();
  std::ofstream(both) << "<?xml version=\"1.0\"?>\n<root>\n  <camera>\n    <name>c</name>\n"
                         "    <image_width>640</image_width>\n    <image_height>480</image_height>\n"
                         "    <model>\n      <type>perspectiveProjWithoutDistortion</type>\n      <px>600</px>\n"
                         "      <py>601</py>\n      <u0>320</u0>\n      <v0>240</v0>\n    </model>\n"
                         "    <model>\n      <type>perspectiveProjWithDistortion</type>\n      <px>610.5</px>\n"
                         "      <py>611.5</py>\n      <u0>321</u0>\n      <v0>241</v0>\n      <kud>-0.1</kud>\n"
                         "      <kdu>0.1</kdu>\n    </model>\n  </camera>\n</root>\n";
  // The pose as roll/pitch/yaw.
  const std::string rpy = (dir / "rpy.json").string();
  std::ofstream(rpy) << R"({"wMc": {"t": [1, 2, 3], "rpy_deg": [170, 20, -35]}})";
  ExpectSameCamera(LoadServoCamera(both, rpy, obj), ThroughVision(both, rpy, obj));
  EXPECT_DOUBLE_EQ(LoadServoCamera(both, rpy, obj).px, 610.5);
  // OpenCV's JSON.
  vision::CameraModel opencv = vision::CameraModel::Pinhole(700.25, 699.75, 330.5, 250.25, 640, 480);
  opencv.distortion = vision::DistortionModel::kOpenCV;
  opencv.dist = {0.01, -0.02, 0.001, 0.002};
  const std::string json = (dir / "cv.json").string();
  vision::SaveCameraOpenCV(opencv, json);
  ExpectSameCamera(LoadServoCamera(json, ext, obj), ThroughVision(json, ext, obj));
  // YAML is vision's alone: refused with a hint.
  const std::string yaml = (dir / "cv.yaml").string();
  vision::SaveCameraOpenCV(opencv, yaml);
  EXPECT_THROW(LoadServoCamera(yaml, ext, obj), InputError);
  // A pose that is no rotation.
  const std::string bad = (dir / "bad.json").string();
  std::ofstream(bad) << R"({"wMc": {"t": [1, 2, 3], "R": [[1, 0, 0], [0, 1, 0], [0, 0, 2]]}})";
  EXPECT_THROW(LoadServoCamera(cal, bad, obj), InputError);
  std::filesystem::remove_all(dir);
}

// Closed loop: the tracked point complies to the VC line, moving along the ray at 5 cm/s, the law evaluated every
// millisecond on vision's measurement of d (continuous-time limit). Returns the decay rate of |d| (1/s), fitted
// on ln|d| from 0.05 s until |d| falls below 1% of its start (or 1.5 s).
struct LoopResult {
  double rate;
  double final_d;
};

LoopResult Loop(const RandomCase& c, const ServoConfig& config, bool exact, double offset_m) {
  const vision::CameraModel camera = vision::CameraModel::Pinhole(c.px, c.py, c.u0, c.v0, 640, 480);
  const Eigen::Isometry3d cMw = c.wMc.inverse();
  vision::ObjectModel robot;
  robot.polygon = {{0, 0}, {0, 0}, {0.1, 0.1}};  // the CM vertex (1) is the reference point
  robot.height = c.height;
  vision::ObjectModel obstacle;
  obstacle.polygon = {{c.from.x, c.from.y}, {c.from.x + 1, c.from.y}, {c.from.x, c.from.y + 1}};
  obstacle.height = 0.3;
  const ServoCamera cam = FromPose(c.px, c.py, c.u0, c.v0, c.wMc, c.height);
  const Vec2 foot{c.wMc.translation().x(), c.wMc.translation().y()};
  auto measure = [&](Vec2 q) {
    Eigen::Isometry3d wMr = Eigen::Isometry3d::Identity();
    wMr.translation() = Eigen::Vector3d(q.x, q.y, 0);
    return vision::SignedImageDistance(camera, c.wMc, robot, cMw * wMr, 1, obstacle, cMw, 0);
  };
  // Start on the ray's line through the point, offset sideways.
  const Vec2 t = c.direction;
  Vec2 q = c.from + Dot(c.point - c.from, t) * t + offset_m * LeftNormal(t);
  const double dt = 1e-3;
  const double d0 = measure(q);
  double sum_t = 0, sum_l = 0, sum_tt = 0, sum_tl = 0;
  int n = 0;
  double d = d0;
  for (int k = 0; k < 1500; ++k) {
    d = measure(q);
    const double time = k * dt;
    if (std::abs(d) < 0.01 * std::abs(d0)) break;
    if (time >= 0.05) {
      const double l = std::log(std::abs(d));
      sum_t += time, sum_l += l, sum_tt += time * time, sum_tl += time * l;
      ++n;
    }
    const ServoOutput out =
        exact ? VisualComplianceLaw(config, t, t, 0.05, d, CameraInteractionRow(cam, t, q, config.min_range_m))
              : VisualComplianceLaw(config, t, t, 0.05, d, Norm(q - foot));
    q = q + dt * out.velocity;
  }
  const double slope = (n * sum_tl - sum_t * sum_l) / (n * sum_tt - sum_t * sum_t);
  return {-slope, d};
}

TEST(ServoLawClosedLoop, TiltedCameraConvergesAtTheGainsRate) {
  ServoConfig config;             // gain 4/s
  config.max_normal_speed = 1.0;  // no saturation: the rate is the law's
  // The default scene's camera (data/sim): 9 m above (9.5, 7.5), looking at (5, 3.8, 0); the ray vc9 from the right
  // lip (5.2, 2) to the foot point, the robot's top at 0.6 m, 4 cm off the line.
  RandomCase slot;
  const ServoCamera file_cam =
      LoadServoCamera("data/sim/slot_camera.xml", "data/sim/slot_extrinsics.json", "data/sim/slot_objects.json");
  slot.px = file_cam.px, slot.py = file_cam.py, slot.u0 = file_cam.u0, slot.v0 = file_cam.v0;
  slot.wMc = vision::LoadExtrinsics("data/sim/slot_extrinsics.json");
  slot.height = file_cam.point_height_m;
  slot.from = {5.2, 2.0};
  const Vec2 foot{slot.wMc.translation().x(), slot.wMc.translation().y()};
  slot.direction = (1 / Norm(foot - slot.from)) * (foot - slot.from);
  slot.point = slot.from + 1.0 * slot.direction;
  config.focal_px = slot.px;  // the old law's best guess: the calibration's focal length
  const LoopResult exact = Loop(slot, config, true, 0.04);
  const LoopResult planar = Loop(slot, config, false, 0.04);
  std::printf(
      "default scene's camera, gain %.1f/s: exact law rate %.3f/s (%.1f%% off), planar f/range law %.3f/s "
      "(%.1f%% off)\n",
      config.gain, exact.rate, 100 * (exact.rate / config.gain - 1), planar.rate,
      100 * (planar.rate / config.gain - 1));
  EXPECT_NEAR(exact.rate / config.gain, 1.0, 0.01);
  EXPECT_GT(std::abs(planar.rate / config.gain - 1), 0.2);  // the old law is measurably off with this tilt
  // Random tilted cameras.
  std::mt19937_64 rng(1204);
  std::vector<double> old_error;
  double worst_exact = 0;
  for (int trial = 0; trial < 100; ++trial) {
    const RandomCase c = Draw(rng);
    config.focal_px = c.px;
    const LoopResult e = Loop(c, config, true, 0.02);
    const LoopResult p = Loop(c, config, false, 0.02);
    worst_exact = std::max(worst_exact, std::abs(e.rate / config.gain - 1));
    old_error.push_back(std::abs(p.rate / config.gain - 1));
    EXPECT_NEAR(e.rate / config.gain, 1.0, 0.01) << "trial " << trial;
  }
  std::sort(old_error.begin(), old_error.end());
  std::printf(
      "100 random tilted cameras: exact law rate within %.2f%% of the gain; planar law off by %.0f%% "
      "(median), %.0f%% (90th percentile)\n",
      100 * worst_exact, 100 * old_error[50], 100 * old_error[90]);
  EXPECT_GT(old_error[50], 0.1);
}

}  // namespace
}  // namespace visco::control

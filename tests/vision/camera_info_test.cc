// The calibration channel (camera_info_t): every calibration vision can load travels through a real LCM bus and
// comes back bit for bit; unusable messages are refused with the field that is wrong; differences are reported.

#include "vision/camera_info.h"

#include <gtest/gtest.h>

#include <lcm/lcm-cpp.hpp>
#include <string>
#include <vector>

#include "common/error.h"
#include "lcmtypes/channels.h"

namespace visco::vision {
namespace {

template <typename F>
std::string InputErrorOf(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "no InputError";
}

// Publishes the message on a memq:// bus and returns what a subscriber decoded.
visco::camera_info_t ThroughBus(const visco::camera_info_t& sent) {
  lcm::LCM bus("memq://");
  EXPECT_TRUE(bus.good());
  struct Receiver {
    std::vector<visco::camera_info_t> got;
    void Handle(const lcm::ReceiveBuffer*, const std::string&, const visco::camera_info_t* m) { got.push_back(*m); }
  } receiver;
  bus.subscribe(channels::kCameraInfo, &Receiver::Handle, &receiver);
  EXPECT_EQ(bus.publish(channels::kCameraInfo, &sent), 0);
  EXPECT_EQ(bus.handleTimeout(1000), 1);
  EXPECT_EQ(receiver.got.size(), 1u);
  return receiver.got.empty() ? visco::camera_info_t{} : receiver.got[0];
}

void ExpectSameCalibration(const CameraCalibration& a, const CameraCalibration& b) {
  EXPECT_EQ(a.camera.name, b.camera.name);
  EXPECT_EQ(a.source, b.source);
  EXPECT_EQ(a.camera.width, b.camera.width);
  EXPECT_EQ(a.camera.height, b.camera.height);
  // Exact: the numbers must travel bit for bit (a replay compares outputs byte for byte).
  EXPECT_EQ(a.camera.px, b.camera.px);
  EXPECT_EQ(a.camera.py, b.camera.py);
  EXPECT_EQ(a.camera.u0, b.camera.u0);
  EXPECT_EQ(a.camera.v0, b.camera.v0);
  EXPECT_EQ(a.camera.distortion, b.camera.distortion);
  EXPECT_EQ(a.camera.kud, b.camera.kud);
  EXPECT_EQ(a.camera.kdu, b.camera.kdu);
  EXPECT_EQ(a.camera.dist, b.camera.dist);
  ASSERT_EQ(a.extrinsics.has_value(), b.extrinsics.has_value());
  if (a.extrinsics) {
    EXPECT_TRUE(a.extrinsics->wMc.matrix() == b.extrinsics->wMc.matrix());
    EXPECT_TRUE(a.extrinsics->covariance == b.extrinsics->covariance);
  }
  EXPECT_TRUE(CalibrationDifferences(a, "a", b, "b").empty());
}

CameraCalibration FromFiles(const std::string& camera, const std::string& extrinsics) {
  CameraCalibration c;
  c.camera = LoadCamera(camera);
  c.source = camera;
  if (!extrinsics.empty()) {
    c.extrinsics = LoadExtrinsicsWithUncertainty(extrinsics);
    c.source += ", " + extrinsics;
  }
  return c;
}

TEST(CameraInfo, CheckedInCalibrationsTravelBitForBit) {
  for (const auto& [camera, extrinsics] : std::vector<std::pair<std::string, std::string>>{
           {"data/sim/slot_camera.xml", "data/sim/slot_extrinsics.json"},
           {"data/vision/synthetic_camera.xml", "data/vision/demo_extrinsics.json"},
           {"tests/vision/data/apriltag_pgm_camera.xml", ""}}) {
    SCOPED_TRACE(camera);
    const CameraCalibration files = FromFiles(camera, extrinsics);
    const visco::camera_info_t sent = EncodeCameraInfo(files, 1700000000123456);
    const visco::camera_info_t got = ThroughBus(sent);
    EXPECT_EQ(got.utime, 1700000000123456);
    EXPECT_EQ(got.has_extrinsics, !extrinsics.empty());
    ExpectSameCalibration(files, DecodeCameraInfo(got, channels::kCameraInfo));
  }
}

TEST(CameraInfo, EveryDistortionModelAndAnUncertainPose) {
  CameraCalibration c;
  c.camera = CameraModel::Pinhole(600.25, 601.75, 319.5, 241.125, 640, 480);
  c.camera.name = "usb0";
  c.extrinsics = Extrinsics{};
  c.extrinsics->wMc.linear() = RotationFromRpy(-2.3, 0.1, 0.7);  // not exactly representable numbers
  c.extrinsics->wMc.translation() << 0.1, -0.45, 0.5;
  for (int i = 0; i < 6; ++i) c.extrinsics->covariance(i, i) = 1e-6 * (i + 1);
  c.extrinsics->covariance(0, 1) = c.extrinsics->covariance(1, 0) = 3e-7;
  std::vector<CameraCalibration> cases;
  cases.push_back(c);  // no distortion
  c.camera.distortion = DistortionModel::kViSP;
  c.camera.kud = -0.1734;
  c.camera.kdu = 0.1791;
  cases.push_back(c);
  c.camera.kud = c.camera.kdu = 0;
  for (const std::vector<double>& d :
       {std::vector<double>{-0.1, 0.01, 1e-3, -2e-3}, std::vector<double>{-0.1, 0.01, 1e-3, -2e-3, 5e-4},
        std::vector<double>{-0.1, 0.01, 1e-3, -2e-3, 5e-4, 0.1, 0.02, 0.003}}) {
    c.camera.distortion = DistortionModel::kOpenCV;
    c.camera.dist = d;
    cases.push_back(c);
  }
  for (const CameraCalibration& calibration : cases) {
    SCOPED_TRACE(static_cast<int>(calibration.camera.distortion));
    SCOPED_TRACE(calibration.camera.dist.size());
    const CameraCalibration back =
        DecodeCameraInfo(ThroughBus(EncodeCameraInfo(calibration, 1)), channels::kCameraInfo);
    ExpectSameCalibration(calibration, back);
    // The decoded model projects as the original does.
    const Eigen::Vector3d p(0.12, -0.07, 0.8);
    EXPECT_EQ(back.camera.Project(p), calibration.camera.Project(p));
  }
}

TEST(CameraInfo, UnusableMessagesAreRefusedNamingTheField) {
  CameraCalibration c;
  c.camera = CameraModel::Pinhole(600, 600, 320, 240, 640, 480);
  c.camera.name = "usb0";
  c.extrinsics = Extrinsics{};
  const visco::camera_info_t good = EncodeCameraInfo(c, 1);
  EXPECT_NO_THROW(DecodeCameraInfo(good, "VISCO_CAMERA_INFO"));
  struct Case {
    const char* expected;
    void (*spoil)(visco::camera_info_t&);
  };
  const Case cases[] = {
      {"focal lengths must be positive", [](visco::camera_info_t& m) { m.px = 0; }},
      {"py is not finite", [](visco::camera_info_t& m) { m.py = std::nan(""); }},
      {"image size must not be negative", [](visco::camera_info_t& m) { m.height = -1; }},
      {"unknown distortion_model 7", [](visco::camera_info_t& m) { m.distortion_model = 7; }},
      {"VISP needs 2 coefficients",
       [](visco::camera_info_t& m) { m.distortion_model = visco::camera_info_t::DISTORTION_VISP; }},
      {"OPENCV needs 4, 5 or 8 coefficients",
       [](visco::camera_info_t& m) {
         m.distortion_model = visco::camera_info_t::DISTORTION_OPENCV;
         m.distortion = {1, 2, 3};
         m.num_distortion = 3;
       }},
      {"num_distortion is 2 but 0 coefficients follow", [](visco::camera_info_t& m) { m.num_distortion = 2; }},
      {"rotation is not a rotation matrix", [](visco::camera_info_t& m) { m.rotation[0][0] = -1; }},
      {"position is not finite", [](visco::camera_info_t& m) { m.position[2] = INFINITY; }},
      {"negative variance", [](visco::camera_info_t& m) { m.extrinsics_covariance[3][3] = -1e-6; }},
      {"not symmetric", [](visco::camera_info_t& m) { m.extrinsics_covariance[0][4] = 1e-6; }},
  };
  for (const Case& k : cases) {
    visco::camera_info_t m = good;
    k.spoil(m);
    const std::string error = InputErrorOf([&] { DecodeCameraInfo(m, "VISCO_CAMERA_INFO"); });
    EXPECT_NE(error.find(std::string("VISCO_CAMERA_INFO: camera_info 'usb0': ")), std::string::npos) << error;
    EXPECT_NE(error.find(k.expected), std::string::npos) << error;
  }
  // Without extrinsics the pose fields are not looked at.
  visco::camera_info_t m = good;
  m.has_extrinsics = false;
  m.rotation[0][0] = -1;
  EXPECT_FALSE(DecodeCameraInfo(m, "x").extrinsics.has_value());
}

TEST(CameraInfo, DifferencesAreReportedOneLineEach) {
  const CameraCalibration files = FromFiles("data/sim/slot_camera.xml", "data/sim/slot_extrinsics.json");
  CameraCalibration bus = files;
  EXPECT_TRUE(CalibrationDifferences(files, "files", bus, "bus").empty());
  bus.camera.px = 561;
  bus.camera.width = 800;
  bus.camera.name = "other";
  bus.extrinsics->wMc.translation().x() += 0.01;
  std::vector<std::string> d = CalibrationDifferences(files, "files", bus, "bus");
  ASSERT_EQ(d.size(), 4u);
  EXPECT_EQ(d[0], "camera name: slot_sim (files) vs other (bus)");
  EXPECT_EQ(d[1], "image size: 640x480 (files) vs 800x480 (bus)");
  EXPECT_EQ(d[2], "px: 560 (files) vs 561 (bus)");
  EXPECT_EQ(d[3].rfind("extrinsics: camera centres 0.0099", 0), 0u) << d[3];
  bus = files;
  bus.extrinsics.reset();
  d = CalibrationDifferences(files, "files", bus, "bus");
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0], "extrinsics: only in files");
  bus = files;
  bus.camera.distortion = DistortionModel::kViSP;
  d = CalibrationDifferences(files, "files", bus, "bus");
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0], "distortion model: none (files) vs ViSP (bus)");
}

}  // namespace
}  // namespace visco::vision

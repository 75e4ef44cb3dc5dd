// Camera model: loaders (ViSP XML, OpenCV YAML, extrinsics JSON), their errors, and the distortion models checked
// against ViSP's and OpenCV's own conversions on seeded random points.

#include "vision/camera.h"

#include <gtest/gtest.h>
#include <visp3/core/vpCameraParameters.h>
#include <visp3/core/vpMeterPixelConversion.h>
#include <visp3/core/vpPixelMeterConversion.h>

#include <array>
#include <filesystem>
#include <fstream>
#include <opencv2/calib3d.hpp>
#include <random>
#include <vector>

#include "common/error.h"

namespace visco::vision {
namespace {

std::filesystem::path TempDir() {
  return std::filesystem::temp_directory_path() / ("visco_camera_test_" + std::to_string(::getpid()));
}

std::string TempPath(const std::string& name) {
  std::filesystem::create_directories(TempDir());
  return (TempDir() / name).string();
}

// Removes this process's scratch folder when the tests end (each test runs in its own process under CTest).
class RemoveTempDir : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ignored;
    std::filesystem::remove_all(TempDir(), ignored);
  }
};
[[maybe_unused]] ::testing::Environment* const kRemoveTempDir = ::testing::AddGlobalTestEnvironment(new RemoveTempDir);

void WriteText(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

template <typename F>
std::string InputErrorOf(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "no InputError";
}

TEST(Camera, LoadsCheckedInViSPXmlAndOpenCVYaml) {
  const CameraModel a = LoadCamera("tests/vision/data/apriltag_pgm_camera.xml");
  EXPECT_EQ(a.name, "apriltag_pgm");
  EXPECT_EQ(a.width, 640);
  EXPECT_EQ(a.height, 480);
  EXPECT_DOUBLE_EQ(a.px, 615.1674805);
  EXPECT_DOUBLE_EQ(a.v0, 243.4373779);
  EXPECT_EQ(a.distortion, DistortionModel::kNone);
  const CameraModel b = LoadCamera("tests/vision/data/benchmark_camera.yaml");
  EXPECT_EQ(b.name, "benchmark");
  EXPECT_DOUBLE_EQ(b.px, 700);
  EXPECT_DOUBLE_EQ(b.u0, 320);
  EXPECT_EQ(b.distortion, DistortionModel::kNone);  // all-zero coefficients
}

TEST(Camera, RoundTripsBothFormatsWithDistortion) {
  CameraModel v = CameraModel::Pinhole(600, 601, 321, 239, 640, 480);
  v.name = "cam1";
  v.distortion = DistortionModel::kViSP;
  v.kud = 0.12;
  v.kdu = -0.11;
  SaveCameraViSP(v, TempPath("v.xml"));
  const CameraModel v2 = LoadCamera(TempPath("v.xml"));
  EXPECT_EQ(v2.distortion, DistortionModel::kViSP);
  EXPECT_DOUBLE_EQ(v2.kud, 0.12);
  EXPECT_DOUBLE_EQ(v2.kdu, -0.11);
  EXPECT_DOUBLE_EQ(v2.py, 601);
  EXPECT_EQ(v2.name, "cam1");

  CameraModel o = CameraModel::Pinhole(800, 805, 330, 250, 752, 480);
  o.distortion = DistortionModel::kOpenCV;
  o.dist = {-0.2, 0.05, 0.001, -0.002, 0.01};
  SaveCameraOpenCV(o, TempPath("o.yaml"));
  const CameraModel o2 = LoadCamera(TempPath("o.yaml"));
  EXPECT_EQ(o2.distortion, DistortionModel::kOpenCV);
  ASSERT_EQ(o2.dist.size(), 5u);
  EXPECT_DOUBLE_EQ(o2.dist[4], 0.01);
  EXPECT_EQ(o2.width, 752);
}

TEST(Camera, ViSPModelMatchesViSPConversions) {
  vpCameraParameters cam;
  cam.initPersProjWithDistortion(600, 610, 320, 240, -0.15, 0.16);
  CameraModel c = CameraModel::Pinhole(600, 610, 320, 240);
  c.distortion = DistortionModel::kViSP;
  c.kud = -0.15;
  c.kdu = 0.16;
  std::mt19937 rng(6);
  std::uniform_real_distribution<double> x(-0.5, 0.5), u(0, 640), v(0, 480);
  for (int i = 0; i < 500; ++i) {
    const double xn = x(rng), yn = x(rng);
    double pu, pv;
    vpMeterPixelConversion::convertPoint(cam, xn, yn, pu, pv);
    const Eigen::Vector2d p = c.NormalizedToPixel({xn, yn});
    EXPECT_NEAR(p.x(), pu, 1e-9);
    EXPECT_NEAR(p.y(), pv, 1e-9);
    const double uu = u(rng), vv = v(rng);
    double mx, my;
    vpPixelMeterConversion::convertPoint(cam, uu, vv, mx, my);
    const Eigen::Vector2d m = c.PixelToNormalized({uu, vv});
    EXPECT_NEAR(m.x(), mx, 1e-12);
    EXPECT_NEAR(m.y(), my, 1e-12);
  }
}

TEST(Camera, OpenCVModelMatchesProjectPointsAndInverts) {
  CameraModel c = CameraModel::Pinhole(700, 702, 330, 242);
  c.distortion = DistortionModel::kOpenCV;
  c.dist = {-0.25, 0.08, 0.0012, -0.0008, -0.01};
  const cv::Matx33d k(700, 0, 330, 0, 702, 242, 0, 0, 1);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> x(-0.4, 0.4);
  for (int i = 0; i < 300; ++i) {
    const double xn = x(rng), yn = x(rng);
    std::vector<cv::Point3d> obj{{xn, yn, 1}};
    std::vector<cv::Point2d> img;
    cv::projectPoints(obj, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k, c.dist, img);
    const Eigen::Vector2d p = c.NormalizedToPixel({xn, yn});
    EXPECT_NEAR(p.x(), img[0].x, 1e-9);
    EXPECT_NEAR(p.y(), img[0].y, 1e-9);
    const Eigen::Vector2d back = c.PixelToNormalized(p);
    EXPECT_NEAR(back.x(), xn, 1e-8);
    EXPECT_NEAR(back.y(), yn, 1e-8);
  }
}

TEST(Camera, BadOrMissingCalibrationIsAnInputErrorNamingFileAndObject) {
  EXPECT_NE(InputErrorOf([] { LoadCamera("/nonexistent/cam.xml"); }).find("does not exist"), std::string::npos);
  WriteText(TempPath("garbage.xml"), "<root><camera><name>x</name></camera>");
  EXPECT_NE(InputErrorOf([] { LoadCamera(TempPath("garbage.xml")); }).find("garbage.xml"), std::string::npos);
  WriteText(TempPath("nok.yaml"), "%YAML:1.0\n---\nimage_width: 640\n");
  EXPECT_NE(InputErrorOf([] { LoadCamera(TempPath("nok.yaml")); }).find("camera_matrix: missing"), std::string::npos);
  WriteText(TempPath("neg.yaml"),
            "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
            "   data: [ -700., 0., 320., 0., 700., 240., 0., 0., 1. ]\n");
  EXPECT_NE(InputErrorOf([] { LoadCamera(TempPath("neg.yaml")); }).find("focal lengths must be positive"),
            std::string::npos);
  WriteText(TempPath("d3.yaml"),
            "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
            "   data: [ 700., 0., 320., 0., 700., 240., 0., 0., 1. ]\n"
            "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 3\n   dt: d\n   data: [ 0.1, 0., 0. ]\n");
  EXPECT_NE(InputErrorOf([] { LoadCamera(TempPath("d3.yaml")); }).find("distortion_coefficients"), std::string::npos);
  WriteText(TempPath("broken.yaml"), "%YAML:1.0\n---\ncamera_matrix: [ 1, 2\n");
  EXPECT_NE(InputErrorOf([] { LoadCamera(TempPath("broken.yaml")); }).find("broken.yaml"), std::string::npos);
  EXPECT_NE(
      InputErrorOf([] { LoadCamera("tests/vision/data/apriltag_pgm_camera.xml", "other"); }).find("camera 'other'"),
      std::string::npos);
  WriteText(TempPath("cam.txt"), "px 1\n");
  EXPECT_NE(InputErrorOf([] { LoadCamera(TempPath("cam.txt")); }).find("unknown calibration format"),
            std::string::npos);
}

TEST(Extrinsics, LoadsRotationOrRpyAndRejectsBadInput) {
  Eigen::Isometry3d wMc = Eigen::Isometry3d::Identity();
  wMc.linear() = RotationFromRpy(2.5, 0.1, -0.3);
  wMc.translation() = Eigen::Vector3d(0.4, -0.2, 1.3);
  SaveExtrinsics(wMc, TempPath("e.json"));
  EXPECT_TRUE(LoadExtrinsics(TempPath("e.json")).isApprox(wMc, 1e-12));
  WriteText(TempPath("rpy.json"), R"({"wMc": {"t": [1, 2, 3], "rpy_deg": [180, 0, 90]}})");
  const Eigen::Isometry3d r = LoadExtrinsics(TempPath("rpy.json"));
  EXPECT_TRUE(r.linear().isApprox(RotationFromRpy(M_PI, 0, M_PI / 2), 1e-12));
  WriteText(TempPath("bad_r.json"), R"({"wMc": {"t": [1, 2, 3], "R": [[1, 0, 0], [0, 1, 0], [0, 0, 2]]}})");
  EXPECT_NE(InputErrorOf([] { LoadExtrinsics(TempPath("bad_r.json")); }).find("wMc.R"), std::string::npos);
  WriteText(TempPath("no_t.json"), R"({"wMc": {"R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}})");
  EXPECT_NE(InputErrorOf([] { LoadExtrinsics(TempPath("no_t.json")); }).find("wMc.t"), std::string::npos);
  WriteText(TempPath("typo.json"), R"({"wMc": {"t": [0, 0, 1], "rpy_deg": [0, 0, 0]}, "camra": "x"})");
  EXPECT_NE(InputErrorOf([] { LoadExtrinsics(TempPath("typo.json")); }).find("camra: unknown field"),
            std::string::npos);
  EXPECT_NE(InputErrorOf([] { LoadExtrinsics("/nonexistent.json"); }).find("cannot be read"), std::string::npos);
}

TEST(Extrinsics, OptionalStddev) {
  // Absent: exact (zero covariance), the same pose.
  WriteText(TempPath("exact.json"), R"({"wMc": {"t": [1, 2, 3], "rpy_deg": [180, 0, 90]}})");
  const Extrinsics exact = LoadExtrinsicsWithUncertainty(TempPath("exact.json"));
  EXPECT_TRUE(exact.exact());
  EXPECT_TRUE(exact.wMc.isApprox(LoadExtrinsics(TempPath("exact.json")), 1e-15));
  // Isotropic numbers, or per world axis; rotation first, radians.
  WriteText(
      TempPath("sd.json"),
      R"({"wMc": {"t": [1, 2, 3], "rpy_deg": [180, 0, 90], "stddev": {"position_m": 0.002, "rotation_deg": 0.5}}})");
  const Extrinsics sd = LoadExtrinsicsWithUncertainty(TempPath("sd.json"));
  EXPECT_FALSE(sd.exact());
  EXPECT_TRUE(sd.wMc.isApprox(exact.wMc, 1e-15));
  Eigen::Matrix<double, 6, 1> diag;
  const double r = 0.5 * M_PI / 180;
  diag << r * r, r * r, r * r, 4e-6, 4e-6, 4e-6;
  EXPECT_TRUE(sd.covariance.isApprox(Eigen::Matrix<double, 6, 6>(diag.asDiagonal()), 1e-12));
  EXPECT_TRUE(LoadExtrinsics(TempPath("sd.json")).isApprox(exact.wMc, 1e-15));  // the pose for existing callers
  WriteText(TempPath("axes.json"),
            R"({"wMc": {"t": [1, 2, 3], "rpy_deg": [0, 0, 0], "stddev": {"position_m": [0.001, 0, 0.003]}}})");
  const Extrinsics axes = LoadExtrinsicsWithUncertainty(TempPath("axes.json"));
  diag << 0, 0, 0, 1e-6, 0, 9e-6;
  EXPECT_TRUE(axes.covariance.isApprox(Eigen::Matrix<double, 6, 6>(diag.asDiagonal()), 1e-12));
  // Bad values: the file and the field named.
  const auto error_of = [](const std::string& name, const std::string& stddev) {
    WriteText(TempPath(name), R"({"wMc": {"t": [1, 2, 3], "rpy_deg": [0, 0, 0], "stddev": )" + stddev + "}}");
    return InputErrorOf([&] { LoadExtrinsicsWithUncertainty(TempPath(name)); });
  };
  for (const auto& [name, stddev, field] : std::vector<std::array<std::string, 3>>{
           {"neg.json", R"({"position_m": -0.001})", "wMc.stddev.position_m"},
           {"neg_axis.json", R"({"rotation_deg": [0.1, -0.1, 0]})", "wMc.stddev.rotation_deg"},
           {"str.json", R"({"rotation_deg": "1"})", "wMc.stddev.rotation_deg"},
           {"two.json", R"({"position_m": [0.1, 0.1]})", "wMc.stddev.position_m"},
           {"typo.json", R"({"position": 0.1})", "wMc.stddev.position: unknown field"},
           {"num.json", "0.1", "wMc.stddev"}}) {
    const std::string e = error_of(name, stddev);
    EXPECT_NE(e.find(name), std::string::npos) << e;
    EXPECT_NE(e.find(field), std::string::npos) << e;
  }
}

TEST(Extrinsics, FromTableTag) {
  Eigen::Isometry3d wMc = Eigen::Isometry3d::Identity();
  wMc.linear() = RotationFromRpy(M_PI - 0.4, 0.05, 0.2);
  wMc.translation() = Eigen::Vector3d(0.1, -0.5, 0.9);
  Eigen::Isometry3d wMt = Eigen::Isometry3d::Identity();
  wMt.translation() = Eigen::Vector3d(0.2, 0.1, 0);
  const Eigen::Isometry3d cMt = wMc.inverse() * wMt;
  EXPECT_TRUE(ExtrinsicsFromTableTag(wMt, cMt).isApprox(wMc, 1e-12));
}

}  // namespace
}  // namespace visco::vision

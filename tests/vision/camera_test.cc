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
#include <opencv2/core/persistence.hpp>
#include <random>
#include <vector>

#include "common/error.h"
#include "vision/ros_camera_info.h"

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

// ROS camera_info YAML as camera_calibration writes it (numpy-printed matrices over several lines, "0." numbers).
TEST(Camera, LoadsRosCameraInfoAsCameraCalibrationWritesIt) {
  const CameraModel c = LoadCamera("tests/vision/data/ros_ost.yaml");
  EXPECT_EQ(c.name, "narrow_stereo");
  EXPECT_EQ(c.width, 640);
  EXPECT_EQ(c.height, 480);
  EXPECT_DOUBLE_EQ(c.px, 612.43208);
  EXPECT_DOUBLE_EQ(c.py, 613.07751);
  EXPECT_DOUBLE_EQ(c.u0, 318.95127);
  EXPECT_DOUBLE_EQ(c.v0, 244.61903);
  EXPECT_EQ(c.distortion, DistortionModel::kOpenCV);
  EXPECT_EQ(c.dist, (std::vector<double>{0.117521, -0.238702, 0.001392, -0.000841, 0.0}));
  // The reason for a reader of its own: OpenCV's FileStorage does not read this file.
  bool opencv_reads = true;
  try {
    cv::FileStorage fs("tests/vision/data/ros_ost.yaml", cv::FileStorage::READ);
    cv::Mat k;
    fs["camera_matrix"] >> k;
    opencv_reads = fs.isOpened() && k.rows == 3 && k.cols == 3;
  } catch (const cv::Exception&) {
    opencv_reads = false;
  }
  EXPECT_FALSE(opencv_reads);
}

// As usb_cam ships it (one line per matrix, a rectification that is not the identity), rational_polynomial.
TEST(Camera, LoadsRosCameraInfoAsUsbCamShipsIt) {
  const CameraModel c = LoadCamera("tests/vision/data/ros_usb_cam.yaml");
  EXPECT_EQ(c.name, "head_camera");
  EXPECT_DOUBLE_EQ(c.px, 431.905012);
  EXPECT_DOUBLE_EQ(c.v0, 238.554017);
  EXPECT_EQ(c.distortion, DistortionModel::kOpenCV);
  ASSERT_EQ(c.dist.size(), 8u);
  EXPECT_DOUBLE_EQ(c.dist[7], -0.00125);
  // ROS's models are OpenCV's: the same projection as cv::projectPoints with the same coefficients.
  const cv::Matx33d k(c.px, 0, c.u0, 0, c.py, c.v0, 0, 0, 1);
  std::vector<cv::Point3d> obj{{0.21, -0.13, 1}};
  std::vector<cv::Point2d> img;
  cv::projectPoints(obj, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k, c.dist, img);
  const Eigen::Vector2d p = c.NormalizedToPixel({0.21, -0.13});
  EXPECT_NEAR(p.x(), img[0].x, 1e-9);
  EXPECT_NEAR(p.y(), img[0].y, 1e-9);
}

TEST(Camera, RosCameraInfoRoundTripsAndZeroDistortionIsNone) {
  CameraModel o = CameraModel::Pinhole(800.25, 805.5, 330.125, 250.75, 752, 480);
  o.name = "cam_r";
  o.distortion = DistortionModel::kOpenCV;
  o.dist = {-0.2, 0.05, 0.001, -0.002, 0.01};
  SaveCameraRos(o, TempPath("r.yaml"));
  const CameraModel r = LoadCamera(TempPath("r.yaml"));
  EXPECT_EQ(r.name, "cam_r");
  EXPECT_EQ(r.width, 752);
  EXPECT_DOUBLE_EQ(r.px, 800.25);
  EXPECT_DOUBLE_EQ(r.v0, 250.75);
  EXPECT_EQ(r.dist, o.dist);
  o.distortion = DistortionModel::kNone;
  o.dist.clear();
  SaveCameraRos(o, TempPath("r0.yaml"));
  EXPECT_EQ(LoadCamera(TempPath("r0.yaml")).distortion, DistortionModel::kNone);
}

TEST(Camera, BadRosCameraInfoNamesFileAndField) {
  const std::string k = "camera_matrix:\n  rows: 3\n  cols: 3\n  data: [600, 0, 320, 0, 600, 240, 0, 0, 1]\n";
  const std::string size = "image_width: 640\nimage_height: 480\n";
  const std::string d5 =
      "distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n"
      "  data: [0.1, -0.2, 0, 0, 0]\n";
  auto error_of = [](const std::string& name, const std::string& text) {
    WriteText(TempPath(name), text);
    return InputErrorOf([&] { LoadCamera(TempPath(name)); });
  };
  EXPECT_EQ(error_of("ok.yaml", size + k + d5), "no InputError");
  EXPECT_NE(error_of("nok.yaml", size + d5).find("nok.yaml: camera_matrix: missing"), std::string::npos);
  EXPECT_NE(error_of("now.yaml", "image_height: 480\n" + k).find("now.yaml: image_width: missing"), std::string::npos);
  EXPECT_NE(
      error_of("k8.yaml", size + "camera_matrix:\n  rows: 3\n  cols: 3\n  data: [600, 0, 320, 0, 600, 240, 0, 0]\n")
          .find("k8.yaml: camera_matrix.data: holds 8 numbers, rows x cols = 3 x 3 needs 9"),
      std::string::npos);
  EXPECT_NE(error_of("k23.yaml", size + "camera_matrix:\n  rows: 2\n  cols: 3\n  data: [600, 0, 320, 0, 600, 240]\n")
                .find("k23.yaml: camera_matrix: must be 3x3, got rows: 2, cols: 3"),
            std::string::npos);
  EXPECT_NE(error_of("kno.yaml", size + "camera_matrix: [600, 0, 320, 0, 600, 240, 0, 0, 1]\n")
                .find("kno.yaml: camera_matrix: must be a map {rows: 3, cols: 3, data:"),
            std::string::npos);
  EXPECT_NE(
      error_of("kstr.yaml", size + "camera_matrix:\n  rows: 3\n  cols: 3\n  data: [600, 0, 320, 0, x, 240, 0, 0, 1]\n")
          .find("kstr.yaml: camera_matrix.data[4]: must be a number (line 6)"),
      std::string::npos);
  EXPECT_NE(error_of("skew.yaml",
                     size + "camera_matrix:\n  rows: 3\n  cols: 3\n  data: [600, 2, 320, 0, 600, 240, 0, 0, 1]\n")
                .find("camera_matrix: must be [fx 0 cx; 0 fy cy; 0 0 1]"),
            std::string::npos);
  EXPECT_NE(error_of("neg.yaml",
                     size + "camera_matrix:\n  rows: 3\n  cols: 3\n  data: [-600, 0, 320, 0, 600, 240, 0, 0, 1]\n")
                .find("focal lengths must be positive"),
            std::string::npos);
  EXPECT_NE(error_of("d3.yaml", size + k +
                                    "distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n"
                                    "  cols: 3\n  data: [0.1, 0, 0]\n")
                .find("d3.yaml: distortion_coefficients: plumb_bob has 5 coefficients"),
            std::string::npos);
  EXPECT_NE(error_of("rp5.yaml", size + k +
                                     "distortion_model: rational_polynomial\ndistortion_coefficients:\n"
                                     "  rows: 1\n  cols: 5\n  data: [0.1, 0, 0, 0, 0]\n")
                .find("rp5.yaml: distortion_coefficients: rational_polynomial has 8 coefficients"),
            std::string::npos);
  EXPECT_NE(error_of("fish.yaml", size + k +
                                      "distortion_model: equidistant\ndistortion_coefficients:\n"
                                      "  rows: 1\n  cols: 4\n  data: [0.1, 0.01, 0, 0]\n")
                .find("fish.yaml: distortion_model: 'equidistant' (fisheye) is not supported"),
            std::string::npos);
  EXPECT_NE(error_of("what.yaml", size + k + "distortion_model: bob\n")
                .find("what.yaml: distortion_model: unknown model 'bob'"),
            std::string::npos);
  EXPECT_NE(error_of("nomodel.yaml", size + k +
                                         "distortion_coefficients:\n  rows: 1\n  cols: 5\n"
                                         "  data: [0.1, -0.2, 0, 0, 0]\n")
                .find("nomodel.yaml: distortion_model: missing"),
            std::string::npos);
  EXPECT_NE(error_of("typo.yaml", size + k +
                                      "distortion_coeficients:\n  rows: 1\n  cols: 5\n"
                                      "  data: [0.1, -0.2, 0, 0, 0]\n")
                .find("typo.yaml: distortion_coeficients: unknown field (line 7)"),
            std::string::npos);
  EXPECT_NE(error_of("rect.yaml", size + k + d5 +
                                      "rectification_matrix:\n  rows: 3\n  cols: 3\n"
                                      "  data: [1, 0, 0, 0, 2, 0, 0, 0, 1]\n")
                .find("rect.yaml: rectification_matrix: is not a rotation"),
            std::string::npos);
  EXPECT_NE(error_of("p33.yaml", size + k + d5 +
                                     "projection_matrix:\n  rows: 3\n  cols: 3\n"
                                     "  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n")
                .find("p33.yaml: projection_matrix: must be 3x4"),
            std::string::npos);
  EXPECT_NE(error_of("broken.yaml", size + "camera_matrix:\n  rows: 3\n  data: [1, 2\n")
                .find("broken.yaml: not valid YAML (line"),
            std::string::npos);
  EXPECT_NE(error_of("list.yaml", "- 1\n- 2\n").find("list.yaml: not a ROS camera_info file"), std::string::npos);
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

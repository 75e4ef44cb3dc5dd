// `visco extrinsics` and `visco robot-frame` as a user runs them: rendered frames of a tag on the table in a folder
// and a ROS camera_info calibration in, the extrinsics file out (read back by `visco track`'s reader, the truth
// within its stated uncertainty); a points file in, the robot frame out; bad input exits 2 naming file and field.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "common/extrinsics.h"
#include "common/robot_frame.h"
#include "vision/ros_camera_info.h"
#include "vision/tag_renderer.h"

namespace visco::vision {
namespace {

std::filesystem::path TempDir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

std::string Slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Runs `visco ARGS` with stdout and stderr to files; returns the exit status.
int Visco(const std::string& args, const std::filesystem::path& dir) {
  const std::string cmd =
      std::string(VISCO_BIN) + " " + args + " >" + (dir / "stdout").string() + " 2>" + (dir / "stderr").string();
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(CalibrationCli, ExtrinsicsFromRenderedFolderWithRosCalibration) {
  const auto dir = TempDir("visco_extrinsics_cli");
  // A distorted camera (plumb_bob), as a ROS calibration describes it.
  CameraModel camera = CameraModel::Pinhole(560, 562, 321.5, 238.5, 640, 480);
  camera.name = "table_cam";
  camera.distortion = DistortionModel::kOpenCV;
  camera.dist = {-0.08, 0.02, 0.0005, -0.0003, 0};
  SaveCameraRos(camera, (dir / "camera.yaml").string());
  Eigen::Isometry3d wMt = Eigen::Isometry3d::Identity();
  wMt.linear() = RotationFromRpy(0, 0, 30 * M_PI / 180);
  wMt.translation() = Eigen::Vector3d(0.2, 0.1, 0);
  Eigen::Isometry3d truth = Eigen::Isometry3d::Identity();
  truth.linear() = RotationFromRpy(-150 * M_PI / 180, 5 * M_PI / 180, 10 * M_PI / 180);
  truth.translation() = Eigen::Vector3d(0.15, -0.2, 0.6);
  RenderScene scene;
  scene.polygons.push_back({{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, 150});
  scene.tags.push_back({"tag36h11", 5, 0.1, wMt});
  std::filesystem::create_directories(dir / "frames");
  for (int i = 0; i < 6; ++i) {
    RenderOptions ro;
    ro.blur_sigma = 0.6;
    ro.noise_stddev = 2;
    ro.seed = static_cast<std::uint32_t>(i + 1);
    char name[32];
    std::snprintf(name, sizeof name, "%03d.png", i);
    WriteGrayImage(Render(camera, truth, scene, ro).view(), (dir / "frames" / name).string());
  }
  const std::string common = "extrinsics --camera " + (dir / "camera.yaml").string() + " --images " +
                             (dir / "frames").string() + " --tag-size 0.1 --tag-t 0.2 0.1 0 --tag-rpy-deg 0 0 30";
  ASSERT_EQ(Visco(common + " --tag-id 5 --frames 10 --out " + (dir / "ext.json").string(), dir), 0)
      << Slurp(dir / "stderr");
  const nlohmann::json summary = nlohmann::json::parse(Slurp(dir / "stdout"));
  EXPECT_EQ(summary["frames"]["used"], 6);
  EXPECT_LT(summary["reprojection_rms_px"]["mean"].get<double>(), 0.5);
  EXPECT_NE(Slurp(dir / "stderr").find("6 of the 10 frames"), std::string::npos);
  // The file is the one `visco track --extrinsics` reads, with its uncertainty.
  const Extrinsics e = LoadExtrinsicsWithUncertainty((dir / "ext.json").string());
  EXPECT_FALSE(e.exact());
  const Eigen::AngleAxisd rotation_error(e.wMc.linear() * truth.linear().transpose());
  const Eigen::Vector3d w = rotation_error.angle() * rotation_error.axis();
  const Eigen::Vector3d v = e.wMc.translation() - truth.translation();
  const Eigen::Matrix<double, 6, 1> sd = e.covariance.diagonal().cwiseSqrt();
  for (int k = 0; k < 3; ++k) {
    EXPECT_LE(std::abs(w[k]), 3 * sd[k]) << k;
    EXPECT_LE(std::abs(v[k]), 3 * sd[3 + k]) << k;
  }
  EXPECT_LT(v.norm(), 0.01);
  EXPECT_EQ(nlohmann::json::parse(Slurp(dir / "ext.json"))["camera"], "table_cam");

  // Another tag id: found in none of the frames (exit 1); bad input: exit 2 naming what is wrong.
  EXPECT_EQ(Visco(common + " --tag-id 6 --out " + (dir / "x.json").string(), dir), 1);
  EXPECT_NE(Slurp(dir / "stderr").find("tag tag36h11 id 6 was found (with a pose) in none of the 6 frames"),
            std::string::npos)
      << Slurp(dir / "stderr");
  std::ofstream(dir / "fisheye.yaml") << "image_width: 640\nimage_height: 480\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
                                         "  data: [560, 0, 320, 0, 560, 240, 0, 0, 1]\ndistortion_model: equidistant\n"
                                         "distortion_coefficients:\n  rows: 1\n  cols: 4\n  data: [0.1, 0, 0, 0]\n";
  EXPECT_EQ(Visco("extrinsics --camera " + (dir / "fisheye.yaml").string() + " --images " + (dir / "frames").string() +
                      " --tag-size 0.1 --out " + (dir / "x.json").string(),
                  dir),
            2);
  EXPECT_NE(Slurp(dir / "stderr").find("fisheye.yaml: distortion_model: 'equidistant' (fisheye) is not supported"),
            std::string::npos)
      << Slurp(dir / "stderr");
  EXPECT_EQ(Visco(common + " --tag-size -1 --out " + (dir / "x.json").string(), dir), 2);
  EXPECT_EQ(Visco("extrinsics --camera " + (dir / "camera.yaml").string() + " --tag-size 0.1 --out x.json", dir), 2);
  EXPECT_NE(Slurp(dir / "stderr").find("give exactly one frame source"), std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(CalibrationCli, RobotFrame) {
  const auto dir = TempDir("visco_robot_frame_cli");
  std::ofstream(dir / "points.json") << R"({"points": [
    {"commanded": [0.0, 0.0], "observed": [0.500, 0.200]},
    {"commanded": [0.2, 0.0], "observed": [0.500, 0.401]},
    {"commanded": [0.2, 0.2], "observed": [0.299, 0.400]},
    {"commanded": [0.0, 0.2], "observed": [0.300, 0.199]}]})";
  ASSERT_EQ(Visco("robot-frame " + (dir / "points.json").string() + " --out " + (dir / "frame.json").string(), dir), 0)
      << Slurp(dir / "stderr");
  const nlohmann::json s = nlohmann::json::parse(Slurp(dir / "stdout"));
  EXPECT_NEAR(s["robot_frame"]["theta_deg"].get<double>(), 90, 0.5);
  EXPECT_EQ(s["residuals"].size(), 4u);
  EXPECT_LT(s["rms_residual_m"].get<double>(), 0.002);
  const RobotFrame f = LoadRobotFrame((dir / "frame.json").string());
  EXPECT_NEAR((f.ToWorld({0.2, 0.2}) - Eigen::Vector2d(0.3, 0.4)).norm(), 0, 0.002);
  std::ofstream(dir / "one.json") << R"({"points": [{"commanded": [0, 0], "observed": [1, 1]}]})";
  EXPECT_EQ(Visco("robot-frame " + (dir / "one.json").string(), dir), 2);
  EXPECT_NE(Slurp(dir / "stderr").find("one.json: points: the commanded positions do not determine the robot frame"),
            std::string::npos)
      << Slurp(dir / "stderr");
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace visco::vision

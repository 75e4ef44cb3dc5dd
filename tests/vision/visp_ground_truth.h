#pragma once
// Ground truth of visp-images-data's AprilTag images, shared by tests/vision and tests/bench/vision:
// - AprilTag/AprilTag.pgm: 12 tag36h11 tags, corners (stored as v u) and poses (t, theta-u) from ViSP's
//   testAprilTag.cpp, with that test's camera and tag size;
// - AprilTag/benchmark/640x480/tag36_11_640x480.png: 5 rendered tags, corners_tag36_11.txt (id, then 4 u v lines)
//   and cMo_<id>.txt (4x4), with the camera and sizes of ViSP's catchAprilTag.cpp.

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <map>
#include <string>

#include "vision/camera.h"
#include "vision/tag_detector.h"

namespace visco::vision::testdata {

inline const std::string kAprilTagDir = "/usr/share/visp-images-data/ViSP-images/AprilTag/";
inline const std::string kBenchmarkDir = kAprilTagDir + "benchmark/640x480/";

inline CameraModel PgmCamera() {
  return CameraModel::Pinhole(615.1674805, 615.1675415, 312.1889954, 243.4373779, 640, 480);
}
constexpr double kPgmTagSize = 0.053;

inline CameraModel BenchmarkCamera() { return CameraModel::Pinhole(700, 700, 320, 240, 640, 480); }
/// Tags 0-2 have 0.25 m total width, 3-4 half of it; the black border of tag36h11 is 8/10 of the total width.
inline double BenchmarkTagSize(int id) { return (id >= 3 ? 0.125 : 0.25) * 8.0 / 10.0; }

/// AprilTag.pgm's corners by id (AprilTag library convention, as ViSP's detector reports them).
inline std::map<int, Corners> PgmCorners() {
  std::map<int, Corners> out;
  std::ifstream in(kAprilTagDir + "ground_truth_detection.txt");
  std::string msg;
  double v[8];
  while (in >> msg >> v[0] >> v[1] >> v[2] >> v[3] >> v[4] >> v[5] >> v[6] >> v[7]) {
    const int id = std::stoi(msg.substr(msg.rfind('_') + 1));
    for (int k = 0; k < 4; ++k) out[id][k] = {v[2 * k + 1], v[2 * k]};  // (v, u) pairs: vpImagePoint::set_ij
  }
  return out;
}

/// AprilTag.pgm's poses by id: (tx, ty, tz, theta-u).
inline std::map<int, Eigen::Matrix<double, 6, 1>> PgmPoses() {
  std::map<int, Eigen::Matrix<double, 6, 1>> out;
  std::ifstream in(kAprilTagDir + "ground_truth_pose.txt");
  std::string msg;
  Eigen::Matrix<double, 6, 1> p;
  while (in >> msg >> p[0] >> p[1] >> p[2] >> p[3] >> p[4] >> p[5]) out[std::stoi(msg.substr(msg.rfind('_') + 1))] = p;
  return out;
}

/// The benchmark image's reference corners by id (the AprilTag library's own output on it: the true cMo projected
/// differs from them by 0.1-0.3 px scattered, so sub-pixel accuracy there is judged on poses against cMo).
inline std::map<int, Corners> BenchmarkCorners() {
  std::map<int, Corners> out;
  std::ifstream in(kBenchmarkDir + "corners_tag36_11.txt");
  int id;
  double p[8];
  while (in >> id >> p[0] >> p[1] >> p[2] >> p[3] >> p[4] >> p[5] >> p[6] >> p[7]) {
    for (int k = 0; k < 4; ++k) out[id][k] = {p[2 * k], p[2 * k + 1]};
  }
  return out;
}

/// The benchmark's true pose of tag `id` (ViSP convention).
inline Eigen::Isometry3d BenchmarkCmo(int id) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  std::ifstream in(kBenchmarkDir + "cMo_" + std::to_string(id) + ".txt");
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) in >> m(r, c);
  }
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.matrix() = m;
  return out;
}

/// ViSP's theta-u vector of a rotation.
inline Eigen::Vector3d ThetaU(const Eigen::Matrix3d& r) {
  const Eigen::AngleAxisd aa(r);
  return aa.axis() * aa.angle();
}

}  // namespace visco::vision::testdata

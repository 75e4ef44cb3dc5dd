// Detection and pose accuracy on images no one here made: visp-images-data's AprilTag.pgm (ground truth from
// ViSP's own test) and the AprilTag/benchmark/640x480 synthetic set (ground-truth corners and cMo).

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "tests/vision/visp_ground_truth.h"
#include "vision/camera.h"
#include "vision/image.h"
#include "vision/tag_detector.h"

namespace visco::vision {
namespace {

const std::string kData = "/usr/share/visp-images-data/ViSP-images/AprilTag/";

// ViSP's theta-u vector of a rotation.
Eigen::Vector3d ThetaU(const Eigen::Matrix3d& r) {
  const Eigen::AngleAxisd aa(r);
  return aa.axis() * aa.angle();
}

TEST(AprilTagPgm, CornersAndPosesMatchViSPGroundTruth) {
  // Camera and tag size of ViSP's testAprilTag.cpp.
  const CameraModel cam = CameraModel::Pinhole(615.1674805, 615.1675415, 312.1889954, 243.4373779, 640, 480);
  const double tag_size = 0.053;
  const GrayImage image = ReadGrayImage(kData + "AprilTag.pgm");
  TagDetector detector;
  const auto tags = detector.Detect(image.view());

  std::map<int, Corners> truth_corners;
  {
    std::ifstream in(kData + "ground_truth_detection.txt");
    ASSERT_TRUE(in);
    std::string msg;
    double v[8];
    while (in >> msg >> v[0] >> v[1] >> v[2] >> v[3] >> v[4] >> v[5] >> v[6] >> v[7]) {
      const int id = std::stoi(msg.substr(msg.rfind('_') + 1));
      // Stored as (v, u) pairs (ViSP's vpImagePoint::set_ij).
      for (int k = 0; k < 4; ++k) truth_corners[id][k] = {v[2 * k + 1], v[2 * k]};
    }
  }
  std::map<int, Eigen::Matrix<double, 6, 1>> truth_pose;
  {
    std::ifstream in(kData + "ground_truth_pose.txt");
    ASSERT_TRUE(in);
    std::string msg;
    Eigen::Matrix<double, 6, 1> p;
    while (in >> msg >> p[0] >> p[1] >> p[2] >> p[3] >> p[4] >> p[5]) {
      truth_pose[std::stoi(msg.substr(msg.rfind('_') + 1))] = p;
    }
  }
  ASSERT_EQ(truth_corners.size(), 12u);
  ASSERT_EQ(tags.size(), truth_corners.size());
  double max_corner_err = 0, max_pose_err = 0;
  for (const auto& tag : tags) {
    ASSERT_TRUE(truth_corners.count(tag.id)) << tag.id;
    for (int k = 0; k < 4; ++k) {
      const double e = (tag.corners[k] - truth_corners[tag.id][k]).norm();
      max_corner_err = std::max(max_corner_err, e);
      EXPECT_LT(e, 0.1) << "tag " << tag.id << " corner " << k;
    }
    const auto pose = EstimateTagPose(cam, tag.corners, tag_size);
    ASSERT_TRUE(pose.has_value()) << tag.id;
    Eigen::Matrix<double, 6, 1> got;
    got << pose->cMo.translation(), ThetaU(pose->cMo.linear());
    const auto& want = truth_pose[tag.id];
    for (int k = 0; k < 6; ++k) {
      max_pose_err = std::max(max_pose_err, std::abs(got[k] - want[k]));
      // ViSP's own tolerance in testAprilTag.cpp: 0.005 on each of t (m) and theta-u (rad).
      EXPECT_NEAR(got[k], want[k], 0.005) << "tag " << tag.id << " component " << k;
    }
  }
  std::printf("AprilTag.pgm: %zu tags, max corner error %.4f px, max pose component error %.5f\n", tags.size(),
              max_corner_err, max_pose_err);
}

TEST(AprilTagBenchmark640x480, Tag36h11CornersAndPoses) {
  // Camera and sizes of ViSP's catchAprilTag.cpp: tags 0-2 have 0.25 m total width, 3-4 half of it; the tag size
  // (black border) of tag36h11 is 8/10 of the total width.
  const CameraModel cam = CameraModel::Pinhole(700, 700, 320, 240, 640, 480);
  const std::string dir = kData + "benchmark/640x480/";
  const GrayImage image = ReadGrayImage(dir + "tag36_11_640x480.png");
  TagDetector detector;
  const auto tags = detector.Detect(image.view());
  ASSERT_EQ(tags.size(), 5u);
  std::map<int, Corners> truth;
  {
    std::ifstream in(dir + "corners_tag36_11.txt");
    int id;
    double p[8];
    while (in >> id >> p[0] >> p[1] >> p[2] >> p[3] >> p[4] >> p[5] >> p[6] >> p[7]) {
      for (int k = 0; k < 4; ++k) truth[id][k] = {p[2 * k], p[2 * k + 1]};
    }
  }
  const double trans_max[] = {0.025, 0.09, 0.05, 0.13, 0.09};  // ViSP's per-tag thresholds (RMS over x, y, z)
  const double rot_max[] = {0.04, 0.075, 0.07, 0.18, 0.13};    // (RMS over theta-u components)
  for (const auto& tag : tags) {
    ASSERT_GE(tag.id, 0);
    ASSERT_LT(tag.id, 5);
    double rms = 0;
    for (int k = 0; k < 4; ++k) rms += (tag.corners[k] - truth[tag.id][k]).squaredNorm();
    rms = std::sqrt(rms / 8);
    for (int k = 0; k < 4; ++k) EXPECT_LT((tag.corners[k] - truth[tag.id][k]).norm(), 0.5) << tag.id << " " << k;
    Eigen::Matrix4d m;
    {
      std::ifstream in(dir + "cMo_" + std::to_string(tag.id) + ".txt");
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) in >> m(r, c);
    }
    const double size = (tag.id >= 3 ? 0.125 : 0.25) * 8.0 / 10.0;
    const auto pose = EstimateTagPose(cam, tag.corners, size);
    ASSERT_TRUE(pose.has_value());
    const double et = std::sqrt((pose->cMo.translation() - m.block<3, 1>(0, 3)).squaredNorm() / 3);
    const double er = std::sqrt((ThetaU(pose->cMo.linear()) - ThetaU(m.block<3, 3>(0, 0))).squaredNorm() / 3);
    std::printf("benchmark tag36h11 id %d: corner RMSE %.4f px, translation error %.5f m, rotation error %.5f rad\n",
                tag.id, rms, et, er);
    EXPECT_LT(et, trans_max[tag.id]);
    EXPECT_LT(er, rot_max[tag.id]);
  }
}

}  // namespace
}  // namespace visco::vision

namespace visco::vision {
namespace {

TEST(AprilTagPgm, DetectionLeavesTheImageUntouched) {
  // The AprilTag library blurs its input in place when quad_sigma != 0; the detector must work on a copy.
  const GrayImage image = ReadGrayImage(kData + "AprilTag.pgm");
  const std::vector<std::uint8_t> before = image.pixels;
  DetectorOptions o;
  o.quad_sigma = 0.8f;
  TagDetector detector(o);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(detector.Detect(image.view()).size(), 12u) << "pass " << i;
  EXPECT_TRUE(image.pixels == before);
}

}  // namespace
}  // namespace visco::vision

namespace visco::vision {
namespace {

// Decimated detection (quads at half resolution, corners refined at full resolution: what the tracker does for big
// tags) against full detection, on the benchmark image's true poses.
TEST(AprilTagBenchmark640x480, DecimatedDetectionKeepsThePoseAccuracy) {
  const GrayImage image = ReadGrayImage(testdata::kBenchmarkDir + "tag36_11_640x480.png");
  const auto reference = testdata::BenchmarkCorners();
  TagDetector detector;
  const auto full = detector.Detect(image.view());
  const auto dec = detector.DetectInRegion(image.view(), 0, 0, image.width, image.height, 2.0f);
  ASSERT_EQ(full.size(), 5u);
  ASSERT_EQ(dec.size(), 5u);
  double corner_diff = 0, et[2] = {0, 0}, er[2] = {0, 0};
  for (int t = 0; t < 5; ++t) {
    ASSERT_EQ(full[t].id, t);
    ASSERT_EQ(dec[t].id, t);
    for (int k = 0; k < 4; ++k) corner_diff = std::max(corner_diff, (dec[t].corners[k] - reference.at(t)[k]).norm());
    const Eigen::Isometry3d truth = testdata::BenchmarkCmo(t);
    const Corners* c[2] = {&full[t].corners, &dec[t].corners};
    for (int m = 0; m < 2; ++m) {
      const auto pose = EstimateTagPose(testdata::BenchmarkCamera(), *c[m], testdata::BenchmarkTagSize(t));
      ASSERT_TRUE(pose.has_value());
      et[m] = std::max(et[m], (pose->cMo.translation() - truth.translation()).norm());
      er[m] = std::max(er[m], Eigen::AngleAxisd(pose->cMo.linear().transpose() * truth.linear()).angle());
    }
  }
  std::printf(
      "benchmark 640x480 tag36h11: decimated+refined corners within %.3f px of the full detection; worst pose error vs "
      "cMo: full %.1f mm %.2f mrad, decimated+refined %.1f mm %.2f mrad\n",
      corner_diff, 1e3 * et[0], 1e3 * er[0], 1e3 * et[1], 1e3 * er[1]);
  EXPECT_LT(corner_diff, 0.3);
  EXPECT_LT(et[1], 1.5 * et[0]);
  EXPECT_LT(er[1], 1.5 * er[0]);
}

}  // namespace
}  // namespace visco::vision

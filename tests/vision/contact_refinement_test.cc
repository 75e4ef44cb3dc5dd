// Face-contact refinement of the object poses (vision/contact_refinement.h, planning's MakeFlush) on a rendered scene
// with ground truth: the robot pushed against a block, a wall standing against the block's other side, all three on
// the table. The raw poses come from one tag each (noise, blur); the refined ones must be closer to the truth and
// their face contacts exact.

#include "vision/contact_refinement.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "tests/vision/demo_world.h"
#include "vision/camera.h"
#include "vision/features.h"
#include "vision/tag_renderer.h"

namespace visco::vision {
namespace {

const CameraModel& kCam = test_world::kDemoCamera;

using test_world::Planar;

ObjectModels Models() {
  return ParseObjectModels(R"({
    "robot": {"id": "robot", "polygon": [[-0.04, -0.04], [0.04, -0.04], [0.04, 0.04], [-0.04, 0.04]], "height": 0.03,
              "tags": [{"family": "tag36h11", "id": 0, "size": 0.06, "t": [0, 0, 0.03], "rpy_deg": [0, 0, 0]}]},
    "obstacles": [
      {"id": "block", "polygon": [[0, 0], [0.1, 0], [0.1, 0.1], [0, 0.1]], "height": 0.05,
       "tags": [{"family": "tag36h11", "id": 1, "size": 0.08, "t": [0.05, 0.05, 0.05], "rpy_deg": [0, 0, 0]}]},
      {"id": "wall", "polygon": [[0, 0], [0.06, 0], [0.06, 0.16], [0, 0.16]], "height": 0.04,
       "tags": [{"family": "tag36h11", "id": 2, "size": 0.05, "t": [0.03, 0.08, 0.04], "rpy_deg": [0, 0, 90]}]}
    ]})",
                           "test models");
}

TEST(ObjectPrism, IsAClosedOutwardPrism) {
  const ObjectModels m = Models();
  const PrismMesh p = ObjectPrism(m.obstacles[0]);
  ASSERT_EQ(p.vertices.size(), 8u);
  ASSERT_EQ(p.faces.size(), 6u);
  // Every face's normal (Newell) points away from the centroid.
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& v : p.vertices) c += v / 8;
  EXPECT_NEAR(c.z(), 0.025, 1e-12);
  for (const auto& f : p.faces) {
    Eigen::Vector3d n = Eigen::Vector3d::Zero(), fc = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < f.size(); ++i) {
      n += p.vertices[f[i]].cross(p.vertices[f[(i + 1) % f.size()]]);
      fc += p.vertices[f[i]] / static_cast<double>(f.size());
    }
    EXPECT_GT(n.dot(fc - c), 0);
  }
}

TEST(ContactRefinement, RenderedSceneRefinedPosesCloserToTruthAndFlush) {
  const ObjectModels m = Models();
  Eigen::Isometry3d wMc = Eigen::Isometry3d::Identity();
  wMc.linear() = RotationFromRpy(-2.2, 0, 0.1);
  wMc.translation() = Eigen::Vector3d(0.02, -0.42, 0.42);
  const Eigen::Isometry3d cMw = wMc.inverse();
  DetectorOptions dopt;
  dopt.quad_sigma = 0.8f;
  TagDetector detector(dopt);
  ContactOptions off;
  off.enabled = false;
  double err_raw_t = 0, err_ref_t = 0, err_raw_r = 0, err_ref_r = 0, worst_residue = 0, worst_gap = 0;
  int n = 0, refined = 0;
  const int frames = 8;
  for (int i = 0; i < frames; ++i) {
    // Block at a random-ish yaw; the robot flush against its -x side, the wall flush against its +x side.
    const double yaw = -0.3 + 0.08 * i;
    const Eigen::Isometry3d wMb = Planar(-0.03, 0.0, yaw);
    const Eigen::Isometry3d wMr = wMb * Planar(-0.04, 0.035 + 0.004 * i, 0);
    const Eigen::Isometry3d wMw = wMb * Planar(0.1, -0.03, 0);
    const Eigen::Isometry3d truth[3] = {wMr, wMb, wMw};
    RenderScene scene;
    scene.polygons.push_back({{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, 120});
    AddPrism(scene, m.robot.polygon, m.robot.height, wMr, 70, 60);
    AddPrism(scene, m.obstacles[0].polygon, m.obstacles[0].height, wMb, 160, 140);
    AddPrism(scene, m.obstacles[1].polygon, m.obstacles[1].height, wMw, 200, 180);
    scene.tags.push_back({"tag36h11", 0, m.robot.tags[0].size, wMr * m.robot.tags[0].oMt});
    scene.tags.push_back({"tag36h11", 1, m.obstacles[0].tags[0].size, wMb * m.obstacles[0].tags[0].oMt});
    scene.tags.push_back({"tag36h11", 2, m.obstacles[1].tags[0].size, wMw * m.obstacles[1].tags[0].oMt});
    RenderOptions ro;
    ro.noise_stddev = 2;
    ro.blur_sigma = 0.6;
    ro.seed = 4000 + i;
    const GrayImage img = Render(kCam, wMc, scene, ro);
    const auto tags = detector.Detect(img.view());
    ASSERT_EQ(tags.size(), 3u) << "frame " << i;
    // Fresh estimators per frame: no prior from the previous frame, the same measurement both ways.
    FeatureEstimator raw(kCam, wMc, m, NoiseModel{}, PoseOptions{}, off);
    FeatureEstimator ref(kCam, wMc, m);
    const FrameFeatures fr = raw.Update(tags);
    const FrameFeatures ff = ref.Update(tags);
    ASSERT_TRUE(ff.contact.ok) << ff.contact.message;
    // Three objects on the table, robot-block and block-wall: 5 contacts.
    EXPECT_EQ(ff.contact.contacts, 5) << ff.contact.message;
    worst_residue = std::max(worst_residue, ff.contact.max_residue_m);
    worst_gap = std::max(worst_gap, ff.contact.observed_gap_m);
    const ObjectEstimate* a[3] = {&fr.robot_pose, &fr.obstacle_poses[0], &fr.obstacle_poses[1]};
    const ObjectEstimate* b[3] = {&ff.robot_pose, &ff.obstacle_poses[0], &ff.obstacle_poses[1]};
    for (int k = 0; k < 3; ++k) {
      ASSERT_TRUE(a[k]->valid && b[k]->valid);
      EXPECT_FALSE(a[k]->contact_refined);
      EXPECT_TRUE(b[k]->contact_refined);
      refined += b[k]->contact_refined ? 1 : 0;
      // Position of the object's vertices (its whole shape, not only the origin): RMS over the prism.
      const PrismMesh mesh = k == 0 ? ObjectPrism(m.robot) : ObjectPrism(m.obstacles[static_cast<std::size_t>(k - 1)]);
      for (const auto& v : mesh.vertices) {
        err_raw_t += (a[k]->wMo * v - truth[k] * v).squaredNorm();
        err_ref_t += (b[k]->wMo * v - truth[k] * v).squaredNorm();
        ++n;
      }
      err_raw_r += std::pow(Eigen::AngleAxisd(a[k]->wMo.linear().transpose() * truth[k].linear()).angle(), 2);
      err_ref_r += std::pow(Eigen::AngleAxisd(b[k]->wMo.linear().transpose() * truth[k].linear()).angle(), 2);
      // cMo follows wMo.
      EXPECT_LT((b[k]->cMo.matrix() - (cMw * b[k]->wMo).matrix()).cwiseAbs().maxCoeff(), 1e-12);
    }
  }
  err_raw_t = std::sqrt(err_raw_t / n), err_ref_t = std::sqrt(err_ref_t / n);
  err_raw_r = std::sqrt(err_raw_r / (3 * frames)), err_ref_r = std::sqrt(err_ref_r / (3 * frames));
  std::printf(
      "contact refinement, %d frames x 3 objects: vertex position RMS error raw %.2f mm -> refined %.2f mm, rotation "
      "RMS error raw %.2f mrad -> refined %.2f mrad; largest measured contact gap %.2f mm, largest residue after "
      "%.1e m\n",
      frames, 1e3 * err_raw_t, 1e3 * err_ref_t, 1e3 * err_raw_r, 1e3 * err_ref_r, 1e3 * worst_gap, worst_residue);
  EXPECT_EQ(refined, 3 * frames);
  EXPECT_LT(err_ref_t, err_raw_t);
  EXPECT_LT(err_ref_r, err_raw_r);
  EXPECT_LT(worst_residue, 1e-9);
}

}  // namespace
}  // namespace visco::vision

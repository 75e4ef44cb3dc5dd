// Face-contact refinement of the object poses (vision/contact_refinement.h, face_contact's MakeFlush) on a rendered
// scene with ground truth: the robot pushed against a block, a wall standing against the block's other side, all three
// on the table. The raw poses come from one tag each (noise, blur); the refined ones must be closer to the truth and
// their face contacts exact.

#include "vision/contact_refinement.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>

#include "tests/vision/demo_world.h"
#include "tests/vision/sanitized_count.h"
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

// Every robot vertex paired with every vertex of the first obstacle (16 pairs), the first obstacle alone kept.
void PairEveryVertex(ObjectModels& m) {
  m.obstacles.resize(1);
  m.events.clear();
  for (int c = 0; c < 4; ++c) {
    for (int v = 0; v < 4; ++v) m.events.push_back({"pair", 0, v, c});
  }
}

// The true wMo of the robot (0) flush against the block's (1) -x side, both on the table.
std::array<Eigen::Isometry3d, 2> FlushTruth() {
  const Eigen::Isometry3d wMb = Planar(-0.03, 0.0, -0.2);
  return {wMb * Planar(-0.04, 0.04, 0), wMb};
}

// The first tags of the robot and the first obstacle seen by the camera at cMw with the objects at `truth`: their
// corners projected (AprilTag's convention: pixel centres at +0.5) plus offset(object, corner).
template <typename Offset>
std::vector<TagObservation> SeenTags(const ObjectModels& m, const Eigen::Isometry3d& cMw,
                                     const std::array<Eigen::Isometry3d, 2>& truth, Offset offset) {
  const ObjectModel* models[2] = {&m.robot, &m.obstacles[0]};
  std::vector<TagObservation> tags;
  for (int k = 0; k < 2; ++k) {
    const TagMount& mount = models[k]->tags[0];
    TagObservation t;
    t.family = mount.family;
    t.id = mount.id;
    const auto local = TagCornersInTagFrame(mount.size);
    for (int c = 0; c < 4; ++c) {
      const Eigen::Vector2d off = offset(k, c);
      t.corners[c] =
          kCam.Project(cMw * truth[k] * mount.oMt * local[c]) + Eigen::Vector2d(0.5 + off.x(), 0.5 + off.y());
    }
    tags.push_back(t);
  }
  return tags;
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
  const Eigen::Isometry3d wMc = test_world::TiltedCameraPose();
  const Eigen::Isometry3d cMw = wMc.inverse();
  DetectorOptions dopt;
  dopt.quad_sigma = 0.8f;
  TagDetector detector(dopt);
  ContactOptions off;
  off.enabled = false;
  double err_raw_t = 0, err_ref_t = 0, err_raw_r = 0, err_ref_r = 0, worst_residue = 0, worst_gap = 0;
  int n = 0, refined = 0;
  double sd_raw = 0, sd_ref = 0;
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
      // The covariance follows the contacts: the measured one kept, the refined one smaller (Sigma - Sigma' >= 0).
      EXPECT_TRUE(ff.contact.covariance_propagated) << ff.contact.message;
      EXPECT_LT((b[k]->cov_cMo_measured - a[k]->cov_cMo).cwiseAbs().maxCoeff(), 1e-12 * a[k]->cov_cMo.norm());
      using Cov = Eigen::Matrix<double, 6, 6>;
      const double min_ev =
          Eigen::SelfAdjointEigenSolver<Cov>(b[k]->cov_cMo_measured - b[k]->cov_cMo).eigenvalues().minCoeff();
      EXPECT_GT(min_ev, -1e-12 * a[k]->cov_cMo.norm());
      EXPECT_LT(b[k]->position_stddev, a[k]->position_stddev);
      EXPECT_LE(b[k]->orientation_stddev, a[k]->orientation_stddev * (1 + 1e-9));
      sd_raw += a[k]->position_stddev, sd_ref += b[k]->position_stddev;
    }
  }
  err_raw_t = std::sqrt(err_raw_t / n), err_ref_t = std::sqrt(err_ref_t / n);
  err_raw_r = std::sqrt(err_raw_r / (3 * frames)), err_ref_r = std::sqrt(err_ref_r / (3 * frames));
  std::printf(
      "contact refinement, %d frames x 3 objects: vertex position RMS error raw %.2f mm -> refined %.2f mm, rotation "
      "RMS error raw %.2f mrad -> refined %.2f mrad; largest measured contact gap %.2f mm, largest residue after "
      "%.1e m\n",
      frames, 1e3 * err_raw_t, 1e3 * err_ref_t, 1e3 * err_raw_r, 1e3 * err_ref_r, 1e3 * worst_gap, worst_residue);
  std::printf("stated position stddev (largest axis), mean: measured %.2f mm -> propagated %.2f mm\n",
              1e3 * sd_raw / (3 * frames), 1e3 * sd_ref / (3 * frames));
  EXPECT_EQ(refined, 3 * frames);
  EXPECT_LT(err_ref_t, err_raw_t);
  EXPECT_LT(err_ref_r, err_raw_r);
  EXPECT_LT(worst_residue, 1e-9);
}

using Cov6 = PoseCovariance;

// ContactObject::covariance's perturbation is PerturbPose; its inverse:
Eigen::Matrix<double, 6, 1> PoseError(const Eigen::Isometry3d& m, const Eigen::Isometry3d& truth) {
  const Eigen::AngleAxisd aa(m.linear() * truth.linear().transpose());
  Eigen::Matrix<double, 6, 1> e;
  e << aa.angle() * aa.axis(), m.translation() - truth.translation();
  return e;
}

double MinEigenvalue(const Cov6& m) { return Eigen::SelfAdjointEigenSolver<Cov6>(m).eigenvalues().minCoeff(); }

// The covariance of the flush poses, propagated through the contact constraints (Sigma' = Sigma - Sigma J^T
// (J Sigma J^T)^+ J Sigma), against a seeded Monte Carlo of the actual refinement: the robot flush against the block,
// both on the table (3 contacts); the measurement covariances are the features' own for these objects seen by the
// rendered test's camera (their tags' exact corners, the initial corner noise), in the world frame. Measured poses
// are drawn from N(truth, Sigma) and refined by RefineContacts; the empirical covariance of the refined poses about
// their mean must match Sigma' entry by entry (within 5 standard errors for the sample size, plus 2 % of Sigma'
// for the second-order effects of the rotations), the constrained directions (height, roll and
// pitch on the table) must have no variance, and Sigma - Sigma' must be positive semi-definite.
TEST(ContactRefinement, PropagatedCovarianceMatchesMonteCarlo) {
  ObjectModels m = Models();
  m.obstacles.resize(1);  // robot and block
  std::erase_if(m.events, [](const EventPair& e) { return e.obstacle != 0; });
  const Eigen::Isometry3d wMc = test_world::TiltedCameraPose();
  const Eigen::Isometry3d cMw = wMc.inverse();
  const std::array<Eigen::Isometry3d, 2> truth = FlushTruth();
  const std::vector<TagObservation> tags = SeenTags(m, cMw, truth, [](int, int) { return Eigen::Vector2d(0, 0); });
  ContactOptions off;
  off.enabled = false;
  FeatureEstimator raw(kCam, wMc, m, NoiseModel{}, PoseOptions{}, off);
  const FrameFeatures f = raw.Update(tags);
  ASSERT_TRUE(f.robot_pose.valid && f.obstacle_poses[0].valid);
  Cov6 b = Cov6::Zero();
  b.topLeftCorner<3, 3>() = b.bottomRightCorner<3, 3>() = wMc.linear();
  const Cov6 sigma[2] = {b * f.robot_pose.cov_cMo * b.transpose(), b * f.obstacle_poses[0].cov_cMo * b.transpose()};
  const ObjectModel* models[2] = {&m.robot, &m.obstacles[0]};
  auto objects = [&](const std::array<Eigen::Isometry3d, 2>& wMo) {
    std::vector<ContactObject> o(2);
    for (int k = 0; k < 2; ++k) {
      o[k].model = models[k];
      o[k].wMo = wMo[k];
      o[k].covariance = sigma[k];
      o[k].position_stddev = std::sqrt(
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(sigma[k].bottomRightCorner<3, 3>()).eigenvalues().maxCoeff());
      o[k].orientation_stddev = std::sqrt(
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(sigma[k].topLeftCorner<3, 3>()).eigenvalues().maxCoeff());
    }
    return o;
  };
  ContactOptions opt;
  opt.false_miss_probability =
      1e-9;  // every sample's contacts found (the test is about the covariance, not the thresholds)
  const ContactRefinement at_truth = RefineContacts(objects(truth), opt);
  ASSERT_TRUE(at_truth.ok) << at_truth.message;
  ASSERT_EQ(at_truth.contacts, 3) << at_truth.message;
  ASSERT_TRUE(at_truth.covariance_propagated) << at_truth.message;

  const int n = test_world::SanitizedCount(2000, 400);
  std::mt19937 rng(8080);
  std::normal_distribution<double> normal;
  Eigen::LLT<Cov6> chol[2] = {Eigen::LLT<Cov6>(sigma[0]), Eigen::LLT<Cov6>(sigma[1])};
  Eigen::Matrix<double, 12, 1> sum = Eigen::Matrix<double, 12, 1>::Zero();
  Eigen::Matrix<double, 12, 12> outer = Eigen::Matrix<double, 12, 12>::Zero();
  for (int s = 0; s < n; ++s) {
    std::array<Eigen::Isometry3d, 2> measured;
    for (int k = 0; k < 2; ++k) {
      Eigen::Matrix<double, 6, 1> z;
      for (int i = 0; i < 6; ++i) z[i] = normal(rng);
      measured[k] = PerturbPose(truth[k], chol[k].matrixL() * z);
    }
    const ContactRefinement r = RefineContacts(objects(measured), opt);
    ASSERT_TRUE(r.ok && r.covariance_propagated && r.contacts == 3) << "sample " << s << ": " << r.message;
    ASSERT_LT(r.max_residue_m, 1e-9) << s;
    Eigen::Matrix<double, 12, 1> e;
    e << PoseError(r.wMo[0], truth[0]), PoseError(r.wMo[1], truth[1]);
    sum += e;
    outer += e * e.transpose();
  }
  const Eigen::Matrix<double, 12, 1> mean = sum / n;
  const Eigen::Matrix<double, 12, 12> empirical = (outer - n * mean * mean.transpose()) / (n - 1);
  const char* names[2] = {"robot", "block"};
  for (int k = 0; k < 2; ++k) {
    const Cov6& pred = at_truth.covariance[static_cast<std::size_t>(k)];
    const Cov6 emp = empirical.block<6, 6>(6 * k, 6 * k);
    const Cov6& prior = sigma[k];
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j) {
        const double se =
            std::sqrt((std::max(pred(i, i), 0.0) * std::max(pred(j, j), 0.0) + pred(i, j) * pred(i, j)) / n);
        EXPECT_NEAR(emp(i, j), pred(i, j),
                    5 * se + 0.02 * std::sqrt(std::max(pred(i, i), 0.0) * std::max(pred(j, j), 0.0)) +
                        1e-9 * std::sqrt(prior(i, i) * prior(j, j)))
            << names[k] << " (" << i << ", " << j << ")";
      }
    }
    // Constrained by the table: rotation about world x and y, height.
    for (int i : {0, 1, 5}) {
      EXPECT_LT(pred(i, i), 1e-9 * prior(i, i)) << names[k] << " " << i;
      EXPECT_LT(emp(i, i), 1e-9 * prior(i, i)) << names[k] << " " << i;
    }
    // Sigma' <= Sigma, and Sigma' a covariance.
    EXPECT_GT(MinEigenvalue(prior - pred), -1e-12 * prior.trace()) << names[k];
    EXPECT_GT(MinEigenvalue(pred), -1e-12 * prior.trace()) << names[k];
    std::printf(
        "%s: stddev measured -> propagated -> Monte Carlo (%d samples): x %.3f -> %.3f -> %.3f mm, y %.3f -> %.3f "
        "-> %.3f mm, z %.3f -> %.3f -> %.3f mm, yaw %.2f -> %.2f -> %.2f mrad, roll %.2f -> %.2f -> %.2f mrad\n",
        names[k], n, 1e3 * std::sqrt(prior(3, 3)), 1e3 * std::sqrt(pred(3, 3)), 1e3 * std::sqrt(emp(3, 3)),
        1e3 * std::sqrt(prior(4, 4)), 1e3 * std::sqrt(pred(4, 4)), 1e3 * std::sqrt(emp(4, 4)),
        1e3 * std::sqrt(prior(5, 5)), 1e3 * std::sqrt(std::max(0.0, pred(5, 5))), 1e3 * std::sqrt(emp(5, 5)),
        1e3 * std::sqrt(prior(2, 2)), 1e3 * std::sqrt(pred(2, 2)), 1e3 * std::sqrt(emp(2, 2)),
        1e3 * std::sqrt(prior(0, 0)), 1e3 * std::sqrt(std::max(0.0, pred(0, 0))), 1e3 * std::sqrt(emp(0, 0)));
  }
}

// The signed distances' stddev sigma_d after the contact refinement, against a seeded Monte Carlo of the whole
// per-frame path: tag corners with Gaussian noise (the noise model's own sigma_c, held fixed), the pose fits, the
// contact refinement and d, by FeatureEstimator::Update. The robot flush against the block on the table (as above);
// every robot vertex paired with every block vertex (16 pairs). For each pair the empirical stddev of d over the
// samples must match the stated sigma_d (its mean) within 15 %, and the hysteresis must keep its promise: a d
// whose truth is on the line is declared off it (|d - truth| > k_hi sigma_d) in at most alpha = 1e-3 of the frames
// (allowing 3 alpha for the sample). The old propagation (the two poses independent, Jacobians at the measured
// poses) is printed beside it.
TEST(ContactRefinement, SignedDistanceStddevMatchesMonteCarlo) {
  ObjectModels m = Models();
  PairEveryVertex(m);
  const Eigen::Isometry3d wMc = test_world::TiltedCameraPose();
  const Eigen::Isometry3d cMw = wMc.inverse();
  const std::array<Eigen::Isometry3d, 2> truth = FlushTruth();
  NoiseModel noise;
  noise.estimate_online = false;  // the stated noise is the true one
  const double sigma_c = noise.corner_sigma_px;
  const int n = test_world::SanitizedCount(1500, 300);
  const std::size_t pairs = m.events.size();
  std::vector<double> truth_d(pairs), sum(pairs, 0), sum2(pairs, 0), stated(pairs, 0), stated_old(pairs, 0);
  for (std::size_t e = 0; e < pairs; ++e) {
    truth_d[e] = SignedImageDistance(kCam, wMc, m.robot, cMw * truth[0], m.events[e].cm_vertex, m.obstacles[0],
                                     cMw * truth[1], m.events[e].vertex);
  }
  std::mt19937 rng(4242);
  std::normal_distribution<double> normal;
  int off_line = 0, draws = 0, refined = 0;
  for (int s = 0; s < n; ++s) {
    const std::vector<TagObservation> tags = SeenTags(m, cMw, truth, [&](int, int) -> Eigen::Vector2d {
      return sigma_c * Eigen::Vector2d(normal(rng), normal(rng));
    });
    FeatureEstimator estimator(kCam, wMc, m, noise);
    const FrameFeatures& f = estimator.Update(tags);
    ASSERT_TRUE(f.robot_pose.valid && f.obstacle_poses[0].valid) << s;
    refined += f.contact.covariance_propagated ? 1 : 0;
    const double k_hi = estimator.thresholds().k_hi;
    for (std::size_t e = 0; e < pairs; ++e) {
      const PairMeasurement& pm = f.pairs[e];
      ASSERT_TRUE(pm.valid);
      sum[e] += pm.signed_distance_px - truth_d[e];
      sum2[e] += (pm.signed_distance_px - truth_d[e]) * (pm.signed_distance_px - truth_d[e]);
      stated[e] += pm.stddev_px * pm.stddev_px / n;
      off_line += std::abs(pm.signed_distance_px - truth_d[e]) > k_hi * pm.stddev_px ? 1 : 0;
      ++draws;
      // The old propagation: independent poses, Jacobians at the measured poses.
      const EventPair& ev = m.events[e];
      const Eigen::Matrix<double, 6, 6>& cr = f.robot_pose.cov_cMo;
      const Eigen::Matrix<double, 6, 6>& co = f.obstacle_poses[0].cov_cMo;
      Eigen::Matrix<double, 1, 6> gr, go;
      for (int i = 0; i < 6; ++i) {
        const double h = i < 3 ? 1e-6 : 1e-7;
        Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
        d[i] = h;
        auto dr = [&](const Eigen::Matrix<double, 6, 1>& x) {
          return SignedImageDistance(kCam, wMc, m.robot, PerturbPose(f.robot_pose.cMo_measured, x), ev.cm_vertex,
                                     m.obstacles[0], f.obstacle_poses[0].cMo, ev.vertex);
        };
        auto dob = [&](const Eigen::Matrix<double, 6, 1>& x) {
          return SignedImageDistance(kCam, wMc, m.robot, f.robot_pose.cMo, ev.cm_vertex, m.obstacles[0],
                                     PerturbPose(f.obstacle_poses[0].cMo_measured, x), ev.vertex);
        };
        gr[i] = (dr(d) - dr(-d)) / (2 * h);
        go[i] = (dob(d) - dob(-d)) / (2 * h);
      }
      stated_old[e] += ((gr * cr * gr.transpose())(0, 0) + (go * co * go.transpose())(0, 0)) / n;
    }
  }
  EXPECT_EQ(refined, n);
  double worst = 1, worst_old = 1, mean_ratio = 0, mean_ratio_old = 0;
  for (std::size_t e = 0; e < pairs; ++e) {
    const double mean = sum[e] / n;
    const double emp = std::sqrt((sum2[e] - n * mean * mean) / (n - 1));
    const double ratio = std::sqrt(stated[e]) / emp, ratio_old = std::sqrt(stated_old[e]) / emp;
    if (std::abs(ratio - 1) > std::abs(worst - 1)) worst = ratio;
    if (std::abs(ratio_old - 1) > std::abs(worst_old - 1)) worst_old = ratio_old;
    mean_ratio += ratio / static_cast<double>(pairs);
    mean_ratio_old += ratio_old / static_cast<double>(pairs);
    EXPECT_NEAR(ratio, 1, 0.15) << "pair cm" << m.events[e].cm_vertex << ".v" << m.events[e].vertex
                                << ": stated sigma_d " << std::sqrt(stated[e]) << " px, Monte Carlo " << emp << " px";
  }
  const double rate = static_cast<double>(off_line) / draws;
  std::printf(
      "sigma_d stated / Monte Carlo std over %zu pairs, %d samples: mean %.3f, worst %.3f (before: independent poses, "
      "Jacobians at the measured poses: mean %.3f, worst %.3f); |d - truth| > k_hi sigma_d in %d of %d (%.2g, "
      "promise %.2g)\n",
      pairs, n, mean_ratio, worst, mean_ratio_old, worst_old, off_line, draws, rate, noise.false_alarm);
  EXPECT_LE(rate, 3 * noise.false_alarm);
}

// The extrinsics' uncertainty in sigma_d (NoiseModel::extrinsics_covariance, the extrinsics file's `wMc.stddev`):
// the scene of SignedDistanceStddevMatchesMonteCarlo, but in every frame the true camera pose is the stated wMc
// perturbed by a draw of the stated extrinsics covariance (PerturbPose, world frame), and the tags' corners are
// its exact projections plus the corner noise. The estimator believes the stated wMc, so the contact refinement
// makes the poses flush with a table plane that is off by the extrinsics error. The truth of d is the true image:
// the true poses seen by the true camera. Per pair the stated sigma_d (RMS over the frames) must match the
// empirical stddev of d - truth within 15 %, and sigma_d without the extrinsics term must understate it (the
// worst pair by more than 15 %; the figures are printed). Hysteresis: |d - truth| > k_hi sigma_d in at most
// 3 alpha of the pair-frames.
TEST(ContactRefinement, ExtrinsicsStddevMatchesMonteCarlo) {
  ObjectModels m = Models();
  PairEveryVertex(m);
  const Eigen::Isometry3d wMc = test_world::TiltedCameraPose();
  const std::array<Eigen::Isometry3d, 2> truth = FlushTruth();
  const double sd_position = 0.002, sd_rotation_deg = 0.3;  // a hand-measured camera pose
  NoiseModel noise;
  noise.estimate_online = false;  // the stated corner noise is the true one
  noise.extrinsics_covariance.diagonal() << Eigen::Vector3d::Constant(std::pow(sd_rotation_deg * M_PI / 180, 2)),
      Eigen::Vector3d::Constant(sd_position * sd_position);
  const double sigma_c = noise.corner_sigma_px;
  // VISCO_MC_FRAMES overrides the frame count (the figures in docs/vision.md: 2000).
  const int n = std::getenv("VISCO_MC_FRAMES") != nullptr ? std::atoi(std::getenv("VISCO_MC_FRAMES"))
                                                          : test_world::SanitizedCount(400, 100);
  const std::size_t pairs = m.events.size();
  std::vector<double> sum(pairs, 0), sum2(pairs, 0), stated(pairs, 0), stated_ext(pairs, 0);
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  const Eigen::Matrix<double, 6, 1> sd_extrinsics = noise.extrinsics_covariance.diagonal().cwiseSqrt();
  int off_line = 0, off_line_without = 0, draws = 0;
  // The robot's planar position (what the planner's position uncertainty comes from): its error against the truth
  // normalised by the stated covariance (mean 2 if right), with and without the extrinsics term.
  double planar_nees = 0, planar_nees_without = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int s = 0; s < n; ++s) {
    Eigen::Matrix<double, 6, 1> z;
    for (int i = 0; i < 6; ++i) z[i] = normal(rng);
    const Eigen::Isometry3d wMc_true = PerturbPose(wMc, sd_extrinsics.cwiseProduct(z));
    const Eigen::Isometry3d cMw_true = wMc_true.inverse();
    const std::vector<TagObservation> tags = SeenTags(m, cMw_true, truth, [&](int, int) -> Eigen::Vector2d {
      return sigma_c * Eigen::Vector2d(normal(rng), normal(rng));
    });
    FeatureEstimator estimator(kCam, wMc, m, noise);
    const FrameFeatures& f = estimator.Update(tags);
    ASSERT_TRUE(f.robot_pose.valid && f.obstacle_poses[0].valid) << s;
    ASSERT_TRUE(f.contact.ok && f.contact.covariance_propagated) << s << ": " << f.contact.message;
    if (f.contact.contacts != 3)
      std::printf("frame %d: %d contacts: %s\n", s, f.contact.contacts, f.contact.message.c_str());
    const double k_hi = estimator.thresholds().k_hi;
    {
      ASSERT_TRUE(f.robot.valid);
      const Eigen::Vector2d e = f.robot.position - truth[0].translation().head<2>();
      planar_nees += e.dot(f.robot.covariance.ldlt().solve(e)) / n;
      NoiseModel exact = noise;
      exact.extrinsics_covariance.setZero();
      FeatureEstimator without(kCam, wMc, m, exact);
      const FrameFeatures& g = without.Update(tags);
      planar_nees_without += e.dot(g.robot.covariance.ldlt().solve(e)) / n;
    }
    for (std::size_t e = 0; e < pairs; ++e) {
      const PairMeasurement& pm = f.pairs[e];
      ASSERT_TRUE(pm.valid);
      const double d_true = SignedImageDistance(kCam, wMc_true, m.robot, cMw_true * truth[0], m.events[e].cm_vertex,
                                                m.obstacles[0], cMw_true * truth[1], m.events[e].vertex);
      const double err = pm.signed_distance_px - d_true;
      sum[e] += err;
      sum2[e] += err * err;
      stated[e] += pm.stddev_px * pm.stddev_px / n;
      stated_ext[e] += pm.extrinsics_stddev_px * pm.extrinsics_stddev_px / n;
      const double without = std::sqrt(pm.stddev_px * pm.stddev_px - pm.extrinsics_stddev_px * pm.extrinsics_stddev_px);
      off_line += std::abs(err) > k_hi * pm.stddev_px ? 1 : 0;
      off_line_without += std::abs(err) > k_hi * without ? 1 : 0;
      ++draws;
    }
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  double worst = 1, worst_without = 1, mean_ratio = 0, mean_ratio_without = 0, mean_share = 0;
  for (std::size_t e = 0; e < pairs; ++e) {
    const double mean = sum[e] / n;
    const double emp = std::sqrt((sum2[e] - n * mean * mean) / (n - 1));
    const double ratio = std::sqrt(stated[e]) / emp, ratio_without = std::sqrt(stated[e] - stated_ext[e]) / emp;
    if (std::abs(ratio - 1) > std::abs(worst - 1)) worst = ratio;
    worst_without = std::min(worst_without, ratio_without);
    mean_ratio += ratio / static_cast<double>(pairs);
    mean_ratio_without += ratio_without / static_cast<double>(pairs);
    mean_share += std::sqrt(stated_ext[e] / stated[e]) / static_cast<double>(pairs);
    EXPECT_NEAR(ratio, 1, 0.15) << "pair cm" << m.events[e].cm_vertex << ".v" << m.events[e].vertex
                                << ": stated sigma_d " << std::sqrt(stated[e]) << " px, Monte Carlo " << emp << " px";
  }
  const double rate = static_cast<double>(off_line) / draws;
  std::printf(
      "extrinsics stddev %.1f mm, %.2f deg; sigma_d stated / Monte Carlo std over %zu pairs, %d frames: mean %.3f, "
      "worst %.3f (the extrinsics term's share of sigma_d, mean %.2f); without the extrinsics term: mean %.3f, worst "
      "%.3f; |d - truth| > k_hi sigma_d in %d of %d (%.2g, promise %.2g; without the term %d); %.2f ms per frame\n",
      1e3 * sd_position, sd_rotation_deg, pairs, n, mean_ratio, worst, mean_share, mean_ratio_without, worst_without,
      off_line, draws, rate, noise.false_alarm, off_line_without, 1e3 * seconds / n);
  EXPECT_LT(worst_without, 0.85);
  EXPECT_LE(rate, 3 * noise.false_alarm);
  std::printf(
      "robot planar position: mean normalised error %.2f (2 if the stated covariance is right); without the "
      "extrinsics term %.1f\n",
      planar_nees, planar_nees_without);
  EXPECT_NEAR(planar_nees, 2, 0.6);
  EXPECT_GT(planar_nees_without, 4);
}

// Without an extrinsics uncertainty nothing changes: the extrinsics term is 0 and sigma_d the corner noise's alone.
// With one, d is the same (the same contacts found), and sigma_d^2 is the corner noise's plus the extrinsics term's.
TEST(ContactRefinement, ExactExtrinsicsAddNothing) {
  ObjectModels m = Models();
  m.obstacles.resize(1);
  std::erase_if(m.events, [](const EventPair& e) { return e.obstacle != 0; });
  const Eigen::Isometry3d wMc = test_world::TiltedCameraPose();
  const Eigen::Isometry3d cMw = wMc.inverse();
  const std::array<Eigen::Isometry3d, 2> truth = FlushTruth();
  const std::vector<TagObservation> tags =
      SeenTags(m, cMw, truth, [](int, int c) { return Eigen::Vector2d(0.1 * c, 0); });
  NoiseModel exact;
  NoiseModel uncertain;
  uncertain.extrinsics_covariance.diagonal() << 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6;
  FeatureEstimator a(kCam, wMc, m, exact), b(kCam, wMc, m, uncertain);
  const FrameFeatures fa = a.Update(tags);
  const FrameFeatures fb = b.Update(tags);
  ASSERT_FALSE(fa.pairs.empty());
  for (std::size_t e = 0; e < fa.pairs.size(); ++e) {
    ASSERT_TRUE(fa.pairs[e].valid && fb.pairs[e].valid);
    EXPECT_EQ(fa.pairs[e].extrinsics_stddev_px, 0);
    EXPECT_EQ(fa.pairs[e].signed_distance_px, fb.pairs[e].signed_distance_px);
    EXPECT_GT(fb.pairs[e].extrinsics_stddev_px, 0);
    EXPECT_NEAR(fb.pairs[e].stddev_px * fb.pairs[e].stddev_px,
                fa.pairs[e].stddev_px * fa.pairs[e].stddev_px +
                    fb.pairs[e].extrinsics_stddev_px * fb.pairs[e].extrinsics_stddev_px,
                1e-9 * fb.pairs[e].stddev_px * fb.pairs[e].stddev_px);
  }
}

}  // namespace
}  // namespace visco::vision

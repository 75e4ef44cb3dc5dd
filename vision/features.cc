#include "vision/features.h"

#include <Eigen/Eigenvalues>
#include <cmath>

#include "common/error.h"
#include "vision/multi_tag_pose.h"

namespace visco::vision {
namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

// Inverse of the standard normal CDF, by bisection on erfc (only called at construction).
double NormalQuantile(double p) {
  double lo = -40, hi = 40;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    const double cdf = 0.5 * std::erfc(-mid / std::sqrt(2.0));
    (cdf < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// Numeric Jacobian (central differences) of a function of a 6-vector perturbation (rotation, then translation; the
// steps in radians and metres); N rows, or Eigen::Dynamic for as many as f returns.
template <int N, typename F>
Eigen::Matrix<double, N, 6> NumericJacobian(F f, double rotation_step = 1e-6, double translation_step = 1e-7) {
  Eigen::Matrix<double, N, 6> j;
  for (int k = 0; k < 6; ++k) {
    const double h = k < 3 ? rotation_step : translation_step;
    Vec6 d = Vec6::Zero();
    d[k] = h;
    const Eigen::Matrix<double, N, 1> plus = f(d);
    d[k] = -h;
    const Eigen::Matrix<double, N, 1> minus = f(d);
    if (k == 0) j.resize(plus.rows(), 6);
    j.col(k) = (plus - minus) / (2 * h);
  }
  return j;
}

double LargestStddev(const Eigen::Matrix3d& cov) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  return std::sqrt(std::max(0.0, es.eigenvalues().maxCoeff()));
}

}  // namespace

Thresholds HysteresisThresholds(const NoiseModel& noise) {
  if (!(noise.false_alarm > 0 && noise.false_alarm < 1 && noise.fall_back > 0 && noise.fall_back < 0.5)) {
    throw InputError("noise model", "false_alarm/fall_back", "probabilities must lie in (0, 1) and (0, 0.5)");
  }
  Thresholds k;
  k.k_hi = NormalQuantile(1 - noise.false_alarm / 2);
  k.k_lo = std::max(0.0, k.k_hi - NormalQuantile(1 - noise.fall_back));
  return k;
}

SideState NextSideState(SideState previous, double d, double sigma, const Thresholds& k) {
  const double hi = k.k_hi * sigma, lo = k.k_lo * sigma;
  switch (previous) {
    case SideState::kPositive:
      if (d < -hi) return SideState::kNegative;
      return d > lo ? SideState::kPositive : SideState::kOnLine;
    case SideState::kNegative:
      if (d > hi) return SideState::kPositive;
      return d < -lo ? SideState::kNegative : SideState::kOnLine;
    case SideState::kOnLine:
    case SideState::kUnknown:
      if (d > hi) return SideState::kPositive;
      if (d < -hi) return SideState::kNegative;
      return SideState::kOnLine;
  }
  return SideState::kUnknown;
}

double SignedImageDistance(const CameraModel& camera, const Eigen::Isometry3d& wMc, const ObjectModel& robot,
                           const Eigen::Isometry3d& cMr, int cm_vertex, const ObjectModel& obstacle,
                           const Eigen::Isometry3d& cMo, int vertex, Eigen::Vector3d* line, Eigen::Vector2d* cm_image) {
  const Eigen::Vector2d& bv = obstacle.polygon[vertex];
  const Eigen::Vector3d bot_c = cMo * Eigen::Vector3d(bv.x(), bv.y(), 0);
  const Eigen::Vector3d top_c = cMo * Eigen::Vector3d(bv.x(), bv.y(), obstacle.height);
  const Eigen::Vector2d p1 = camera.ProjectIdeal(bot_c), p2 = camera.ProjectIdeal(top_c);
  Eigen::Vector3d l = Eigen::Vector3d(p1.x(), p1.y(), 1).cross(Eigen::Vector3d(p2.x(), p2.y(), 1));
  // Orientation: positive on the side of the VC ray's left normal. The ray runs on the table from the vertex to the
  // camera centre's foot point P; a point just left of it (in the world) must come out positive.
  const Eigen::Vector3d b_w = wMc * bot_c;
  const Eigen::Vector2d dir = wMc.translation().head<2>() - b_w.head<2>();
  const Eigen::Vector2d left = Eigen::Vector2d(-dir.y(), dir.x()).normalized();
  const Eigen::Vector3d q_w(b_w.x() + 0.01 * left.x(), b_w.y() + 0.01 * left.y(), b_w.z());
  const Eigen::Vector2d q = camera.ProjectIdeal(wMc.inverse() * q_w);
  if (l.dot(Eigen::Vector3d(q.x(), q.y(), 1)) < 0) l = -l;
  l /= l.head<2>().norm();
  const Eigen::Vector2d& av = robot.polygon[cm_vertex];
  const Eigen::Vector2d a = camera.ProjectIdeal(cMr * Eigen::Vector3d(av.x(), av.y(), robot.height));
  if (line != nullptr) *line = l;
  if (cm_image != nullptr) *cm_image = a;
  return l.dot(Eigen::Vector3d(a.x(), a.y(), 1));
}

FeatureEstimator::FeatureEstimator(const CameraModel& camera, const Eigen::Isometry3d& wMc, const ObjectModels& models,
                                   const NoiseModel& noise, const PoseOptions& pose_options,
                                   const ContactOptions& contact_options)
    : camera_(camera),
      wMc_(wMc),
      cMw_(wMc.inverse()),
      models_(models),
      noise_(noise),
      pose_options_(pose_options),
      contact_options_(contact_options),
      k_(HysteresisThresholds(noise)),
      sigma2_(noise.corner_sigma_px * noise.corner_sigma_px) {
  if (models_.robot.tags.empty()) throw InputError("object models", "robot.tags", "the robot carries no tag");
  if (noise_.extrinsics_covariance.trace() > 0) {
    // The extrinsics' error moves every measured object rigidly (the camera turned by w about its centre t_c and
    // shifted by v: p' = Exp(w) (p - t_c) + t_c + v ~ p + w x p + v + t_c x w); relative to them the table moves by
    // the inverse, [w, v + [t_c]x w] up to sign, about the world origin (ContactOptions::table_covariance).
    Mat6 h = Mat6::Identity();
    h.block<3, 3>(3, 0) = Skew(wMc_.translation());
    contact_options_.table_covariance += h * noise_.extrinsics_covariance * h.transpose();
  }
  Reset();
}

void FeatureEstimator::Reset() {
  robot_priors_.assign(models_.robot.tags.size(), std::nullopt);
  obstacle_priors_.clear();
  for (const auto& o : models_.obstacles) obstacle_priors_.emplace_back(o.tags.size(), std::nullopt);
  robot_object_prior_.reset();
  obstacle_object_priors_.assign(models_.obstacles.size(), std::nullopt);
  states_.assign(models_.events.size(), SideState::kUnknown);
  last_ = FrameFeatures();
}

ObjectEstimate FeatureEstimator::EstimateObject(const ObjectModel& model, const std::vector<TagObservation>& tags,
                                                std::vector<std::optional<Eigen::Isometry3d>>& priors,
                                                std::optional<Eigen::Isometry3d>& object_prior) {
  ObjectEstimate out;
  // The table normal in the camera frame resolves the planar ambiguity of face-up tags without a prior, and that of
  // the object (its z axis is up: it stands on the table).
  const Eigen::Vector3d table_normal_c = cMw_.linear() * Eigen::Vector3d::UnitZ();
  std::vector<ObjectTagObservation> seen;
  std::vector<std::size_t> mount_index;
  for (std::size_t i = 0; i < model.tags.size(); ++i) {
    const TagMount& mount = model.tags[i];
    const TagObservation* obs = nullptr;
    for (const auto& t : tags) {
      if (t.id == mount.id && t.family == mount.family) obs = &t;
    }
    if (obs == nullptr) {
      priors[i].reset();
      continue;
    }
    std::optional<Eigen::Vector3d> normal;
    if (std::abs(mount.oMt.linear()(2, 2)) > 0.9) normal = table_normal_c * (mount.oMt.linear()(2, 2) > 0 ? 1 : -1);
    PoseOptions tag_options = pose_options_;
    tag_options.corner_noise_px = std::sqrt(sigma2_);  // the ambiguity rule on the online noise estimate
    const auto pose = EstimateTagPose(camera_, obs->corners, mount.size, tag_options, priors[i], normal);
    if (!pose) {
      priors[i].reset();
      continue;
    }
    priors[i] = pose->cMo;
    // Online noise estimate from each tag's own fit: E[4 rms^2] = E[SSR] = (8 - 6) sigma^2.
    if (noise_.estimate_online) {
      const double s2 = 2 * pose->rms_error_px * pose->rms_error_px;
      sigma2_ = (1 - noise_.online_weight) * sigma2_ + noise_.online_weight * s2;
      sigma2_ = std::max(sigma2_, noise_.min_corner_sigma_px * noise_.min_corner_sigma_px);
    }
    ObjectTagObservation o;
    o.id = mount.id;
    o.corners = obs->corners;
    o.size = mount.size;
    o.oMt = mount.oMt;
    o.pose = *pose;
    seen.push_back(o);
    mount_index.push_back(i);
  }
  if (seen.empty()) {
    object_prior.reset();
    return out;
  }
  std::optional<ObjectPoseFit> fit;
  if (pose_options_.joint_fit || seen.size() == 1) {
    fit = EstimateObjectPose(camera_, seen, pose_options_, std::sqrt(sigma2_), object_prior, table_normal_c);
  } else {
    // The single best tag (smallest translation variance of its own pose), the others unused.
    std::size_t best = 0;
    for (std::size_t k = 1; k < seen.size(); ++k) {
      if (seen[k].pose.unit_covariance.block<3, 3>(3, 3).trace() <
          seen[best].pose.unit_covariance.block<3, 3>(3, 3).trace()) {
        best = k;
      }
    }
    fit = EstimateObjectPose(camera_, {seen[best]}, pose_options_, std::sqrt(sigma2_), object_prior, table_normal_c);
    if (fit) {
      fit->reference = static_cast<int>(best);
      fit->inliers = {static_cast<int>(best)};
      fit->outliers.clear();
      fit->tag_rms_px.assign(seen.size(), 0);
      for (std::size_t k = 0; k < seen.size(); ++k) {
        fit->tag_rms_px[k] = TagRmsAtObjectPose(camera_, seen[k], fit->cMo, pose_options_.corner_offset_px);
      }
    }
  }
  if (!fit) {
    object_prior.reset();
    return out;
  }
  out.valid = true;
  out.tag_id = seen[fit->reference].id;
  out.cMo = out.cMo_measured = fit->cMo;
  out.wMo = wMc_ * out.cMo;
  out.cov_cMo = fit->unit_covariance;  // scaled by sigma^2 in Update
  out.rms_error_px = fit->rms_error_px;
  out.ambiguous = fit->ambiguous;
  out.pose_decision = fit->decided_by;
  out.tags_used = static_cast<int>(fit->inliers.size());
  object_prior = fit->cMo;
  for (std::size_t k = 0; k < seen.size(); ++k) {
    TagEstimate te;
    te.id = seen[k].id;
    te.cMt = seen[k].pose.cMo;
    te.rms_error_px = seen[k].pose.rms_error_px;
    te.joint_rms_px = fit->tag_rms_px[k];
    te.outlier = std::find(fit->outliers.begin(), fit->outliers.end(), static_cast<int>(k)) != fit->outliers.end();
    // A tag in the fit takes the object's pose as its prior (the object's branch of its planar ambiguity).
    if (pose_options_.joint_fit && !te.outlier && seen.size() > 1) priors[mount_index[k]] = fit->cMo * seen[k].oMt;
    out.tags.push_back(te);
  }
  last_.tags_used += out.tags_used;
  return out;
}

const FrameFeatures& FeatureEstimator::Update(const std::vector<TagObservation>& tags, const RobotPoseRefiner& refine) {
  FrameFeatures f;
  last_.tags_used = 0;
  f.robot_pose = EstimateObject(models_.robot, tags, robot_priors_, robot_object_prior_);
  for (std::size_t k = 0; k < models_.obstacles.size(); ++k) {
    f.obstacle_poses.push_back(
        EstimateObject(models_.obstacles[k], tags, obstacle_priors_[k], obstacle_object_priors_[k]));
  }
  f.tags_used = last_.tags_used;
  f.corner_sigma_px = std::sqrt(sigma2_);
  const double s2 = sigma2_;
  // The camera-frame perturbation (R' = Exp(w) R, t' = t + v) in the world frame: w and v rotated by wRc. World
  // covariances are to_world * cov_cMo * to_world^T (the translation's Jacobian is exactly [0, wRc]).
  Eigen::Matrix<double, 6, 6> to_world = Eigen::Matrix<double, 6, 6>::Zero();
  to_world.topLeftCorner<3, 3>() = to_world.bottomRightCorner<3, 3>() = wMc_.linear();
  // The extrinsics' error moves a measured pose rigidly with the camera (turned by w about its centre t_c, shifted by
  // v): R' = Exp(w) R, p' = p + w x (p - t_c) + v. Its world covariance, added to every world-frame uncertainty the
  // estimates report (the stddevs, the robot's planar covariance); zero when the extrinsics are exact.
  const bool extrinsics_uncertain = noise_.extrinsics_covariance.trace() > 0;
  auto extrinsics_jacobian = [&](const Eigen::Vector3d& p) {
    Mat6 j = Mat6::Identity();
    j.block<3, 3>(3, 0) = -Skew(p - wMc_.translation());
    return j;
  };
  auto extrinsics_world = [&](const Eigen::Vector3d& p) {
    const Mat6 j = extrinsics_jacobian(p);
    return Mat6(j * noise_.extrinsics_covariance * j.transpose());
  };
  auto set_stddevs = [&](ObjectEstimate& o, const Eigen::Matrix<double, 6, 6>& cov_w) {
    const Mat6 c = extrinsics_uncertain ? Mat6(cov_w + extrinsics_world(o.wMo.translation())) : Mat6(cov_w);
    o.position_stddev = LargestStddev(c.bottomRightCorner<3, 3>());
    o.orientation_stddev = LargestStddev(c.topLeftCorner<3, 3>());
  };
  auto finish_object = [&](ObjectEstimate& o) {
    if (!o.valid) return;
    o.cov_cMo *= s2;
    o.cov_cMo_measured = o.cov_cMo;
    set_stddevs(o, to_world * o.cov_cMo * to_world.transpose());
  };
  finish_object(f.robot_pose);
  for (auto& o : f.obstacle_poses) finish_object(o);
  if (refine) {
    if (const std::optional<RobotPoseMeasurement> m = refine(f.robot_pose)) {
      ObjectEstimate& r = f.robot_pose;
      r.valid = true;
      r.model_tracked = true;
      r.cMo = r.cMo_measured = m->cMo;
      r.wMo = wMc_ * r.cMo;
      r.cov_cMo = r.cov_cMo_measured = m->cov_cMo;
      set_stddevs(r, to_world * r.cov_cMo * to_world.transpose());
    }
  }

  // Face contacts: the poses made flush with the table and with each other (the tag poses cMt stay as measured).
  // The joint covariance of robot and obstacles in the camera frame (cov_cMo's convention), 6 rows per estimate
  // (robot, then obstacles): block-diagonal, with the cross terms of the objects the contact projection moved
  // together.
  const int n_est = 1 + static_cast<int>(f.obstacle_poses.size());
  Eigen::MatrixXd joint = Eigen::MatrixXd::Zero(6 * n_est, 6 * n_est);
  std::vector<ContactObject> objs;
  std::vector<ObjectEstimate*> ests;
  std::vector<int> est_index;  // objs -> 0 robot, 1 + k obstacle k
  // The objects as measured, in the world of the extrinsics wMc (the measured cMo and their covariance, rotated).
  auto contact_objects = [&](const Eigen::Isometry3d& wMc) {
    Mat6 tw = Mat6::Zero();
    tw.topLeftCorner<3, 3>() = tw.bottomRightCorner<3, 3>() = wMc.linear();
    std::vector<ContactObject> out = objs;
    for (std::size_t i = 0; i < out.size(); ++i) {
      out[i].wMo = wMc * ests[i]->cMo_measured;
      out[i].covariance = tw * ests[i]->cov_cMo_measured * tw.transpose();
    }
    return out;
  };
  {
    auto add = [&](ObjectEstimate& o, const ObjectModel& m) {
      if (!o.valid) return;
      est_index.push_back(&o == &f.robot_pose ? 0 : 1 + static_cast<int>(&o - f.obstacle_poses.data()));
      ContactObject c;  // its pose and covariance: contact_objects
      c.model = &m;
      c.position_stddev = o.position_stddev;
      c.orientation_stddev = o.orientation_stddev;
      objs.push_back(c);
      ests.push_back(&o);
    };
    add(f.robot_pose, models_.robot);
    for (std::size_t k = 0; k < models_.obstacles.size(); ++k) add(f.obstacle_poses[k], models_.obstacles[k]);
    if (contact_options_.enabled && !objs.empty()) {
      f.contact = RefineContacts(contact_objects(wMc_), contact_options_);
      if (f.contact.ok) {
        for (std::size_t i = 0; i < ests.size(); ++i) {
          if (!f.contact.in_contact[i]) continue;
          ests[i]->wMo = f.contact.wMo[i];
          ests[i]->cMo = cMw_ * ests[i]->wMo;
          ests[i]->contact_refined = true;
          if (!f.contact.covariance_propagated) continue;
          ests[i]->cov_cMo = to_world.transpose() * f.contact.covariance[i] * to_world;
          set_stddevs(*ests[i], f.contact.covariance[i]);
        }
      }
    }
    for (std::size_t i = 0; i < ests.size(); ++i) {
      joint.block<6, 6>(6 * est_index[i], 6 * est_index[i]) = ests[i]->cov_cMo;
      if (!f.contact.ok || !f.contact.covariance_propagated) continue;
      for (std::size_t j = 0; j < ests.size(); ++j) {
        if (i == j) continue;
        const Eigen::Matrix<double, 6, 6> w =
            f.contact.joint_covariance.block<6, 6>(6 * static_cast<Eigen::Index>(i), 6 * static_cast<Eigen::Index>(j));
        joint.block<6, 6>(6 * est_index[i], 6 * est_index[j]) = to_world.transpose() * w * to_world;
      }
    }
  }

  // The robot on the motion plane.
  if (f.robot_pose.valid) {
    f.robot.valid = true;
    const Eigen::Isometry3d wMr = f.robot_pose.wMo;
    f.robot.position = wMr.translation().head<2>();
    f.robot.heading = std::atan2(wMr.linear()(1, 0), wMr.linear()(0, 0));
    f.robot.covariance =
        (to_world * f.robot_pose.cov_cMo * to_world.transpose()).block<2, 2>(3, 3);  // world x, y of the origin
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(f.robot.covariance);
    f.robot.position_stddev = std::sqrt(std::max(0.0, es.eigenvalues().maxCoeff()));
    for (const auto& v : models_.robot.polygon) {
      f.cm_images.push_back(
          camera_.ProjectIdeal(f.robot_pose.cMo * Eigen::Vector3d(v.x(), v.y(), models_.robot.height)));
    }
  }

  // The extrinsics' uncertainty (NoiseModel::extrinsics_covariance): d depends on wMc through the contact refinement
  // (the poses are made flush with the table plane z = 0 of wMc's world, then mapped back to the camera) and in
  // SignedImageDistance. First order over the 6 extrinsic parameters through that whole chain: wMc perturbed, the
  // measured poses (camera frame, independent of wMc) refined again and every pair's d recomputed; central
  // differences, once per frame for all pairs, only when an uncertainty is given. Independent of the corner noise,
  // so its variance adds.
  const std::size_t n_events = models_.events.size();
  // Rows: every pair's d, then the robot's world x and y (its planar position, below).
  Eigen::MatrixXd g_ext = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(n_events) + 2, 6);
  if (extrinsics_uncertain && contact_options_.enabled && f.contact.ok) {
    auto distances_at = [&](const Vec6& x) -> Eigen::VectorXd {
      const Eigen::Isometry3d wMc = PerturbPose(wMc_, x);
      std::vector<Eigen::Isometry3d> cMo(static_cast<std::size_t>(n_est));
      for (std::size_t i = 0; i < ests.size(); ++i) cMo[static_cast<std::size_t>(est_index[i])] = ests[i]->cMo_measured;
      const ContactRefinement c = RefineContacts(contact_objects(wMc), contact_options_);
      if (c.ok) {
        const Eigen::Isometry3d cMw = wMc.inverse();
        for (std::size_t i = 0; i < ests.size(); ++i) {
          if (c.in_contact[i]) cMo[static_cast<std::size_t>(est_index[i])] = cMw * c.wMo[i];
        }
      }
      Eigen::VectorXd d = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(n_events) + 2);
      if (f.robot_pose.valid) d.tail<2>() = (wMc * cMo[0]).translation().head<2>();
      for (std::size_t e = 0; e < n_events; ++e) {
        const EventPair& ev = models_.events[e];
        if (!f.robot_pose.valid || !f.obstacle_poses[ev.obstacle].valid) continue;
        d[static_cast<Eigen::Index>(e)] =
            SignedImageDistance(camera_, wMc, models_.robot, cMo[0], ev.cm_vertex, models_.obstacles[ev.obstacle],
                                cMo[1 + static_cast<std::size_t>(ev.obstacle)], ev.vertex);
      }
      return d;
    };
    // Steps well above the projection's convergence (~1e-14) and far inside its nonlinearity (~1 rad, ~0.1 m).
    g_ext = NumericJacobian<Eigen::Dynamic>(distances_at, 1e-5, 1e-6);
  }
  if (f.robot.valid && extrinsics_uncertain) {
    // The robot's world position moves with wMc too: through the contact refinement where it ran (it turns the
    // table's tilt into a shift along the table), else rigidly with the camera.
    const Eigen::Matrix<double, 2, 6> gp =
        contact_options_.enabled && f.contact.ok
            ? Eigen::Matrix<double, 2, 6>(g_ext.bottomRows<2>())
            : Eigen::Matrix<double, 2, 6>(extrinsics_jacobian(f.robot_pose.wMo.translation()).block<2, 6>(3, 0));
    f.robot.covariance += gp * noise_.extrinsics_covariance * gp.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(f.robot.covariance);
    f.robot.position_stddev = std::sqrt(std::max(0.0, es.eigenvalues().maxCoeff()));
  }

  // Pairs: signed distance, its uncertainty (first order in both tag poses and the extrinsics), hysteresis.
  f.pairs.resize(n_events);
  for (std::size_t e = 0; e < models_.events.size(); ++e) {
    const EventPair& ev = models_.events[e];
    PairMeasurement& pm = f.pairs[e];
    const ObjectEstimate& ob = f.obstacle_poses[ev.obstacle];
    const ObjectModel& om = models_.obstacles[ev.obstacle];
    if (!f.robot_pose.valid || !ob.valid) {
      pm.state = SideState::kUnknown;
      states_[e] = SideState::kUnknown;  // never a silently stale state: the next known state is not a crossing
      continue;
    }
    pm.valid = true;
    pm.signed_distance_px = SignedImageDistance(camera_, wMc_, models_.robot, f.robot_pose.cMo, ev.cm_vertex, om,
                                                ob.cMo, ev.vertex, &pm.vc_line, &pm.cm_image);
    // First order through the joint covariance of the two poses d is computed from (the refined ones, correlated
    // when the contact projection moved them together), the Jacobians at those poses.
    const auto gr = NumericJacobian<1>([&](const Vec6& d) -> Eigen::Matrix<double, 1, 1> {
      return Eigen::Matrix<double, 1, 1>(SignedImageDistance(
          camera_, wMc_, models_.robot, PerturbPose(f.robot_pose.cMo, d), ev.cm_vertex, om, ob.cMo, ev.vertex));
    });
    const auto go = NumericJacobian<1>([&](const Vec6& d) -> Eigen::Matrix<double, 1, 1> {
      return Eigen::Matrix<double, 1, 1>(SignedImageDistance(camera_, wMc_, models_.robot, f.robot_pose.cMo,
                                                             ev.cm_vertex, om, PerturbPose(ob.cMo, d), ev.vertex));
    });
    Eigen::Matrix<double, 1, 12> g;
    g << gr, go;
    const Eigen::Index ko = 6 * (1 + static_cast<Eigen::Index>(ev.obstacle));
    Eigen::Matrix<double, 12, 12> pair_cov;
    pair_cov << joint.block<6, 6>(0, 0), joint.block<6, 6>(0, ko), joint.block<6, 6>(ko, 0), joint.block<6, 6>(ko, ko);
    const double var = (g * pair_cov * g.transpose())(0, 0);
    if (extrinsics_uncertain) {
      const Eigen::Matrix<double, 1, 6> ge = g_ext.row(static_cast<Eigen::Index>(e));
      pm.extrinsics_stddev_px = std::sqrt(std::max(0.0, (ge * noise_.extrinsics_covariance * ge.transpose())(0, 0)));
    }
    pm.stddev_px = std::sqrt(std::max(var + pm.extrinsics_stddev_px * pm.extrinsics_stddev_px, 1e-12));
    const SideState prev = states_[e];
    pm.state = NextSideState(prev, pm.signed_distance_px, pm.stddev_px, k_);
    pm.crossed = prev != SideState::kUnknown && pm.state != prev;
    states_[e] = pm.state;
  }
  last_ = std::move(f);
  return last_;
}

}  // namespace visco::vision

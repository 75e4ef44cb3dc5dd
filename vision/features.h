#pragma once
// Per-frame features for the strategies (Fox & Hutchinson with a real camera, docs/semantics.md): object poses from
// their tags, the robot's position on the motion plane with its uncertainty, the image of each CM vertex, the VC line
// of each obstacle vertex (the image of the plane through the camera centre and the vertical obstacle edge: the line
// through the images of the edge's ends), their signed image distance and crossing events with hysteresis.
//
// Image quantities are in ideal (undistorted) pixels: with lens distortion the image of a straight edge is curved,
// and the VC surface's image is a line only after undistortion.
//
// Noise model (docs/vision.md): the tag corners carry independent isotropic Gaussian noise of standard deviation
// sigma_c pixels. Each tag pose fit leaves a residual with 8 - 6 = 2 degrees of freedom, E[SSR] = 2 sigma_c^2, so
// sigma_c is estimated online from the fits (exponentially weighted over tags and frames, never below a floor).
// Pose covariances are sigma_c^2 (J^T J)^-1 of the fits; distances and positions get theirs by first-order
// propagation. Hysteresis: a pair is declared off the line when |d| > k_hi sigma_d with k_hi = Phi^-1(1 - alpha / 2)
// (a vertex exactly on the line is declared off it with probability alpha per frame) and falls back to "on the line"
// only when d is below k_lo sigma_d on its side, k_lo = k_hi - Phi^-1(1 - beta) (a vertex that has just entered a
// side at k_hi sigma_d falls back with probability beta per frame).

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "vision/camera.h"
#include "vision/contact_refinement.h"
#include "vision/multi_tag_pose.h"
#include "vision/object_model.h"
#include "vision/tag_detector.h"

namespace visco::vision {

/// Noise-model settings.
struct NoiseModel {
  double corner_sigma_px = 0.3;  ///< initial corner noise (pixels), then estimated online
  bool estimate_online = true;   ///< update corner_sigma from the pose-fit residuals
  double min_corner_sigma_px = 0.05;
  double online_weight = 0.02;  ///< weight of one tag's estimate in the running mean of sigma^2
  double false_alarm = 1e-3;    ///< alpha: per-frame probability of declaring an on-line vertex off the line
  double fall_back = 1e-3;      ///< beta: per-frame probability of falling back right after entering a side
  /// Uncertainty of the extrinsics wMc (Extrinsics::covariance, common/extrinsics.h: world frame, rotation vector on
  /// the left, then translation). Zero: the camera pose, hence the table plane, is exact. Otherwise each pair's
  /// sigma_d gets the variance this error causes through the contact refinement (docs/vision.md).
  PoseCovariance extrinsics_covariance = PoseCovariance::Zero();
};

/// Event state of a pair after hysteresis (values of visual_event_t::STATE_*).
enum class SideState : std::int8_t { kUnknown = 0, kNegative = 1, kOnLine = 2, kPositive = 3 };

/// One tag of an object that gave a pose in one frame.
struct TagEstimate {
  int id = -1;
  Eigen::Isometry3d cMt = Eigen::Isometry3d::Identity();  ///< its own pose (EstimateTagPose), as measured
  double rms_error_px = 0;                                ///< of its own pose
  double joint_rms_px = 0;                                ///< RMS of its corners at the object's pose (the joint fit)
  bool outlier = false;  ///< inconsistent with the object's other tags: left out of the object's pose
};

/// The pose of one object in one frame.
struct ObjectEstimate {
  bool valid = false;
  int tag_id = -1;  ///< the tag whose pose seeded the fit (with several tags the pose comes from all inliers)
  Eigen::Isometry3d cMo = Eigen::Isometry3d::Identity();  ///< object in the camera frame
  Eigen::Isometry3d wMo = Eigen::Isometry3d::Identity();  ///< object in the world
  /// cMo as measured from the tags (before the contact refinement) and its covariance (rotation vector perturbation
  /// on the left in the camera frame, then translation; sigma_c^2 (J^T J)^-1 of the fit over all inlier corners).
  Eigen::Isometry3d cMo_measured = Eigen::Isometry3d::Identity();
  Eigen::Matrix<double, 6, 6> cov_cMo_measured = Eigen::Matrix<double, 6, 6>::Zero();
  /// Covariance of cMo (same parametrisation): cov_cMo_measured, or, when contact_refined, that covariance propagated
  /// through the contact constraints (ContactRefinement::covariance; smaller: the contacts fix some directions).
  /// position_stddev, orientation_stddev, the robot's planar covariance and the pairs' stddev follow it.
  Eigen::Matrix<double, 6, 6> cov_cMo = Eigen::Matrix<double, 6, 6>::Zero();
  std::vector<TagEstimate> tags;  ///< every tag of the object that gave a pose, in model order
  int tags_used = 0;              ///< tags in the fit (inliers)
  double rms_error_px = 0;        ///< of the fit, over the inlier tags' corners
  bool ambiguous = false;         ///< another pose fitted the tags within the noise (ObjectPoseFit::ambiguous)
  PoseDecision pose_decision = PoseDecision::kUnique;  ///< what chose the pose (ObjectPoseFit::decided_by)
  double position_stddev = 0;     ///< metres, world position of the object origin, 1 sigma (largest axis)
  double orientation_stddev = 0;  ///< radians, 1 sigma (largest axis)
  /// cMo / wMo were made flush with the table and the touching objects (contact_refinement.h); cMo_measured and the
  /// tags' cMt stay the measurements.
  bool contact_refined = false;
  /// cMo_measured and cov_cMo_measured come from the model-based tracker (the robot's silhouette edges,
  /// vision/model_tracker.h), not from the tags; `tags` and `tags_used` still say which tags were seen.
  bool model_tracked = false;
};

/// A pose of the robot measured otherwise than by its tags (the model-based tracker): replaces the tags' pose before
/// the contact refinement. Covariance in ObjectEstimate::cov_cMo's convention.
struct RobotPoseMeasurement {
  Eigen::Isometry3d cMo = Eigen::Isometry3d::Identity();
  Eigen::Matrix<double, 6, 6> cov_cMo = Eigen::Matrix<double, 6, 6>::Zero();
};
/// Called by FeatureEstimator::Update with the robot's pose from its tags (valid or not, covariance scaled); returns
/// the pose to use instead, or nothing to keep the tags'.
using RobotPoseRefiner = std::function<std::optional<RobotPoseMeasurement>(const ObjectEstimate& from_tags)>;

/// The robot on the motion plane.
struct RobotPlanarEstimate {
  bool valid = false;
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  ///< world, metres (reference point = robot-frame origin)
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
  double position_stddev = 0;  ///< metres, sqrt of the largest eigenvalue of covariance
  double heading = 0;          ///< radians, robot x axis from world x
};

/// One CM vertex / VC line pair in one frame.
struct PairMeasurement {
  bool valid = false;
  Eigen::Vector2d cm_image = Eigen::Vector2d::Zero();  ///< ideal pixels, top of the robot's vertical edge
  Eigen::Vector3d vc_line = Eigen::Vector3d::Zero();   ///< a u + b v + c = 0, a^2 + b^2 = 1, positive side = left
                                                       ///< normal of the VC ray (from the vertex to the camera foot)
  double signed_distance_px = 0;
  double stddev_px = 0;  ///< 1 sigma of signed_distance_px, all sources (corner noise, extrinsics)
  /// The part of stddev_px due to the extrinsics' uncertainty (NoiseModel::extrinsics_covariance; 0 without it):
  /// stddev_px^2 = (corner noise part)^2 + extrinsics_stddev_px^2.
  double extrinsics_stddev_px = 0;
  SideState state = SideState::kUnknown;
  bool crossed = false;  ///< the state changed from a known state in this frame
};

/// Everything computed from one frame.
struct FrameFeatures {
  ObjectEstimate robot_pose;
  std::vector<ObjectEstimate> obstacle_poses;  ///< in ObjectModels::obstacles order
  RobotPlanarEstimate robot;
  std::vector<Eigen::Vector2d> cm_images;  ///< ideal pixels of every robot vertex (top), empty if not seen
  std::vector<PairMeasurement> pairs;      ///< in ObjectModels::events order
  double corner_sigma_px = 0;              ///< noise estimate used in this frame
  int tags_used = 0;                       ///< tags in the objects' fits (outliers not counted)
  ContactRefinement contact;               ///< the face-contact refinement of this frame's poses
};

/// Hysteresis thresholds (in units of sigma_d) derived from the noise model.
struct Thresholds {
  double k_hi;
  double k_lo;
};
Thresholds HysteresisThresholds(const NoiseModel& noise);

/// Applies the hysteresis rule: the next state from the previous one and the measurement.
SideState NextSideState(SideState previous, double d, double sigma, const Thresholds& k);

/// Computes features frame after frame; keeps the previous poses (to resolve pose ambiguity) and the event states.
/// Not real-time safe (allocates); run it on the vision thread.
class FeatureEstimator {
 public:
  /// @throws InputError if the models are inconsistent with the camera (no tags, bad sizes).
  FeatureEstimator(const CameraModel& camera, const Eigen::Isometry3d& wMc, const ObjectModels& models,
                   const NoiseModel& noise = {}, const PoseOptions& pose_options = {},
                   const ContactOptions& contact_options = {});

  /// Processes the tag observations of one frame (detected or tracked corners, AprilTag convention). `refine` (may
  /// be empty) may replace the robot's pose measured from the tags (TagTrackingMode::kModelBased).
  const FrameFeatures& Update(const std::vector<TagObservation>& tags, const RobotPoseRefiner& refine = {});

  /// Forgets priors and event states (e.g. after a gap in the stream).
  void Reset();

  const FrameFeatures& last() const { return last_; }
  const ObjectModels& models() const { return models_; }
  const CameraModel& camera() const { return camera_; }
  const Eigen::Isometry3d& wMc() const { return wMc_; }
  double corner_sigma_px() const { return std::sqrt(sigma2_); }
  const Thresholds& thresholds() const { return k_; }

 private:
  ObjectEstimate EstimateObject(const ObjectModel& model, const std::vector<TagObservation>& tags,
                                std::vector<std::optional<Eigen::Isometry3d>>& priors,
                                std::optional<Eigen::Isometry3d>& object_prior);

  CameraModel camera_;
  Eigen::Isometry3d wMc_;
  Eigen::Isometry3d cMw_;
  ObjectModels models_;
  NoiseModel noise_;
  PoseOptions pose_options_;
  ContactOptions contact_options_;
  Thresholds k_;
  double sigma2_;
  std::vector<std::optional<Eigen::Isometry3d>> robot_priors_;                  // per robot tag
  std::vector<std::vector<std::optional<Eigen::Isometry3d>>> obstacle_priors_;  // per obstacle, per tag
  std::optional<Eigen::Isometry3d> robot_object_prior_;                         // last measured cMo
  std::vector<std::optional<Eigen::Isometry3d>> obstacle_object_priors_;
  std::vector<SideState> states_;
  FrameFeatures last_;
};

/// Signed distance (ideal pixels) of the CM vertex `cm_vertex` of the robot at pose cMr to the VC line of vertex
/// `vertex` of an obstacle at cMo, with the orientation convention of PairMeasurement. Exposed for tests.
double SignedImageDistance(const CameraModel& camera, const Eigen::Isometry3d& wMc, const ObjectModel& robot,
                           const Eigen::Isometry3d& cMr, int cm_vertex, const ObjectModel& obstacle,
                           const Eigen::Isometry3d& cMo, int vertex, Eigen::Vector3d* line = nullptr,
                           Eigen::Vector2d* cm_image = nullptr);

}  // namespace visco::vision

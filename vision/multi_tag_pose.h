#pragma once
// The pose of an object carrying several AprilTags, fitted to the corners of all its tags seen in a frame at once
// (each corner's position in the object frame is known from the object model: the tag's pose oMt and its size).
//
// Method (docs/vision.md, "Objects with several tags"):
// - every tag first gets its own pose (EstimateTagPose: both planar solutions); each solution of each tag, carried
//   to the object frame, seeds a consensus: starting from that tag alone, the other tags are added one at a time
//   (nearest first) and the pose refitted to all corners of the set; a tag stays in the set only if, at the refitted
//   pose, every tag of the set reprojects within the gate (its residual sum of squares below the chi-square
//   quantile for 8 degrees of freedom at `tag_outlier_alpha`, for the current corner noise; never below
//   `mount_tolerance_px` RMS);
// - the largest consistent set wins; tags outside it are outliers (a tag stuck on wrongly, a misdecoded id,
//   corrupted corners) and are reported, never averaged in;
// - several distinct poses for the same largest set (planar ambiguity of coplanar tags): the smaller error wins when
//   the other poses are unlikely for the corner noise (likelihood ratio below `joint_ambiguity_alpha`), else the
//   pose closest to the previous frame's, else the one whose z axis is closest to the expected "up" (objects stand on
//   the table);
// - equally large but different sets (two tags that disagree): the pose closest to the previous frame's, else the
//   set whose fit has the smallest translation variance (the single-tag rule), the others reported as outliers;
// - covariance: sigma_c^2 (J^T J)^-1 of the joint fit over all inlier corners.
// With one tag the result is that tag's own pose (EstimateTagPose's ambiguity rule applies unchanged).

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <vector>

#include "vision/camera.h"
#include "vision/tag_detector.h"

namespace visco::vision {

/// One tag of an object as seen in one frame.
struct ObjectTagObservation {
  int id = -1;
  Corners corners;                                        ///< pixels, AprilTag convention
  double size = 0;                                        ///< metres
  Eigen::Isometry3d oMt = Eigen::Isometry3d::Identity();  ///< tag frame in the object frame
  TagPose pose;                                           ///< its own pose (EstimateTagPose)
};

/// What decided the object's pose among the poses that fit its tags.
enum class PoseDecision : std::int8_t {
  kSingleTag,     ///< one tag: EstimateTagPose's own rule (see TagPose::ambiguous)
  kUnique,        ///< the largest consistent set of tags has one pose
  kSmallerError,  ///< several poses of the set; the others are too unlikely for the corner noise
  kPrior,         ///< several poses fit within the noise; the one closest in rotation to the previous frame's
  kExpectedUp,    ///< several poses fit within the noise, no prior; the one whose z axis is closest to "up"
  kUndecided,     ///< several poses fit within the noise, neither prior nor "up": the smaller error, a guess
};

/// Name of a decision as printed in JSON ("single_tag", "unique", "smaller_error", "prior", "expected_up",
/// "undecided"); object_pose_t's POSE_DECISION_* constants have the enum's values.
const char* PoseDecisionName(PoseDecision decision);

/// The object's pose from its tags.
struct ObjectPoseFit {
  Eigen::Isometry3d cMo = Eigen::Isometry3d::Identity();  ///< object frame in the camera frame
  double rms_error_px = 0;                                ///< RMS over the inlier tags' corners, ideal pixels
  bool ambiguous = false;  ///< another pose of the same tags fits within the noise; prior / "up" decided
  PoseDecision decided_by = PoseDecision::kUnique;
  /// Distinct poses (local minima of the reprojection error) found for the chosen set of tags: 2 when the planar
  /// ambiguity of coplanar tags leaves a second minimum, whether or not the noise can tell them apart.
  int candidate_poses = 1;
  /// The best other minimum of the chosen set (the mirrored pose of coplanar tags), when candidate_poses > 1: its
  /// cMo (object in camera) and RMS error over the same corners.
  std::optional<PoseCandidate> alternative;
  int reference = -1;              ///< index of the tag whose solution seeded the chosen fit
  std::vector<int> inliers;        ///< indices into the observations, ascending
  std::vector<int> outliers;       ///< indices of the tags inconsistent with the chosen pose
  std::vector<double> tag_rms_px;  ///< per observation: RMS of its corners at cMo
  double gate_px = 0;              ///< the consistency gate used (RMS, pixels)
  /// Covariance of cMo for an isotropic corner noise of 1 pixel (rotation vector perturbation on the left in the
  /// camera frame, then translation in metres); scale by sigma_c^2.
  Eigen::Matrix<double, 6, 6> unit_covariance = Eigen::Matrix<double, 6, 6>::Identity();
};

/// Fits the object's pose to its tags (see the file comment). `corner_sigma_px` is the current corner-noise estimate
/// (for the consistency gate); `prior_cMo` the previous frame's object pose, if any; `expected_up_c` the direction
/// the object's z axis should have in the camera frame (the table normal), if known. Returns nullopt if `tags` is
/// empty. Not real-time safe (allocates).
std::optional<ObjectPoseFit> EstimateObjectPose(const CameraModel& camera,
                                                const std::vector<ObjectTagObservation>& tags,
                                                const PoseOptions& options, double corner_sigma_px,
                                                const std::optional<Eigen::Isometry3d>& prior_cMo = std::nullopt,
                                                const std::optional<Eigen::Vector3d>& expected_up_c = std::nullopt);

/// Refits `cMo` (object in camera) to the corners of the given tags with `solver`, starting from `cMo` (ignored by
/// SQPnP). Returns the RMS reprojection error over all their corners (ideal pixels), or a negative value if the
/// solver failed (cMo unchanged). Exposed for the benchmark and tests.
double FitObjectPose(const CameraModel& camera, const std::vector<ObjectTagObservation>& tags,
                     const std::vector<int>& use, JointPoseSolver solver, Eigen::Isometry3d& cMo,
                     double corner_offset_px = 0.5);

/// Per-tag RMS reprojection error (ideal pixels) of the object pose cMo.
double TagRmsAtObjectPose(const CameraModel& camera, const ObjectTagObservation& tag, const Eigen::Isometry3d& cMo,
                          double corner_offset_px = 0.5);

/// Quantile of the chi-square distribution with `dof` (even, >= 2) degrees of freedom: P(X > q) = alpha.
double ChiSquareQuantileEven(int dof, double alpha);

}  // namespace visco::vision

#pragma once
// The camera's pose in the world from an AprilTag lying on the table at a known pose, observed over several frames
// (`visco extrinsics`, docs/camera.md). Each frame gives wMc = wMt cMt^-1 (ExtrinsicsFromTableTag); the result is
// their mean with an uncertainty from their spread and from the reprojection error. Frames and covariances as in
// common/extrinsics.h: [w, v] in the world frame, R' = Exp(w) R, t' = t + v (radians, metres).

#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

#include "vision/camera.h"
#include "vision/image.h"
#include "vision/tag_detector.h"

namespace visco::vision {

using PoseCovariance6 = Eigen::Matrix<double, 6, 6>;

/// The tag on the table: family, id, size (metres, the black border's outer edge) and its pose in the world (ViSP
/// convention: tag x right, y up as printed, z out of the face; lying face up: wMt's z axis is the world's z), with
/// the uncertainty of that placement (1 sigma, world frame; 0: placed exactly).
struct TableTag {
  std::string family = "tag36h11";
  int id = 0;
  double size = 0;
  Eigen::Isometry3d wMt = Eigen::Isometry3d::Identity();
  double position_stddev_m = 0;
  double rotation_stddev_rad = 0;
};

/// One frame's observation of the table tag.
struct TableTagView {
  TagPose pose;                     ///< cMt with its unit covariance and reprojection error
  Eigen::Isometry3d wMc;            ///< ExtrinsicsFromTableTag(wMt, cMt)
  PoseCovariance6 unit_covariance;  ///< of wMc (world frame) for 1 px of corner noise
};

/// Detects the table tag in `image` and estimates its pose; nullopt if the tag is not found or its pose is rejected
/// (PoseOptions::max_rms_error_px). `prior_cMt` (e.g. an earlier frame's) chooses between the two planar solutions
/// when the corners cannot. Not real-time safe.
std::optional<TableTagView> ObserveTableTag(TagDetector& detector, const GrayImageView& image,
                                            const CameraModel& camera, const TableTag& tag,
                                            const PoseOptions& pose_options,
                                            const std::optional<Eigen::Isometry3d>& prior_cMt = std::nullopt);

/// Covariance of wMc = wMt cMt^-1 (world frame) from a covariance of cMt (camera frame, left perturbation
/// R' = Exp(a) R, t' = t + b): J C J^T with J = [[-R_wc, 0], [-R_wc [t_ct]x, -R_wc]].
PoseCovariance6 WorldCovarianceFromTagCovariance(const Eigen::Isometry3d& wMc, const Eigen::Isometry3d& cMt,
                                                 const PoseCovariance6& tag_covariance);

/// The combined estimate.
struct TableExtrinsics {
  Eigen::Isometry3d wMc = Eigen::Isometry3d::Identity();  ///< mean of the frames' poses
  /// Reported uncertainty: spread / N (the frames' random error, averaged) + one frame's covariance for the corner
  /// noise the reprojection error shows (errors common to all frames of a still camera and tag, which averaging does
  /// not remove) + the tag placement's.
  PoseCovariance6 covariance = PoseCovariance6::Zero();
  PoseCovariance6 spread = PoseCovariance6::Zero();        ///< sample covariance of the frames' poses about the mean
  PoseCovariance6 reprojection = PoseCovariance6::Zero();  ///< unit covariance (mean over frames) x corner_sigma^2
  PoseCovariance6 placement = PoseCovariance6::Zero();     ///< the tag placement's, carried to wMc
  double corner_sigma_px = 0;  ///< corner noise from the residuals: sqrt(sum SSR / (2 N)) (8 residuals, 6 parameters)
  double mean_rms_px = 0, max_rms_px = 0;  ///< the frames' reprojection errors
  int frames = 0;
  int ambiguous_frames = 0;  ///< frames whose two planar solutions the corners could not tell apart
  /// Per world axis 1-sigma of the covariance's diagonal: rotation (radians), position (metres).
  Eigen::Vector3d rotation_stddev() const { return covariance.diagonal().head<3>().cwiseSqrt(); }
  Eigen::Vector3d position_stddev() const { return covariance.diagonal().tail<3>().cwiseSqrt(); }
};

/// Combines the frames' views. @throws JobFailed if `views` is empty.
TableExtrinsics CombineTableTagViews(const std::vector<TableTagView>& views, const TableTag& tag);

/// Writes extrinsics (common/extrinsics.h's format) with `wMc.stddev` per world axis from the covariance's diagonal
/// and "camera": `camera_name` when not empty. @throws JobFailed if the file cannot be written.
void SaveExtrinsicsWithStddev(const Eigen::Isometry3d& wMc, const PoseCovariance6& covariance,
                              const std::string& camera_name, const std::string& path);

}  // namespace visco::vision

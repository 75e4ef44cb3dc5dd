#pragma once
// The robot followed by its silhouette: ViSP's model-based tracker (vpMbGenericTracker, moving edges) on the robot's
// prism (its object-model polygon extruded to its height), started from the AprilTag pose. Selected by
// TagTrackingMode::kModelBased (docs/vision.md, "Model-based tracking of the robot"). ViSP stays in the .cc file.

#include <Eigen/Geometry>
#include <memory>

#include "vision/camera.h"
#include "vision/image.h"
#include "vision/object_model.h"

namespace visco::vision {

struct ModelTrackerOptions {
  /// Moving edges: pixels searched on each side of the predicted edge. The robot's tag border runs about 9 px inside
  /// the top face's edges in the demo world: a wider search latches onto it.
  int me_range = 3;
  /// ViSP's likelihood threshold of a moving-edge site (vpMe::setThreshold, ViSP 3.5 units). Measured on the rendered
  /// robot (a 50-grey-level step between table and prism): every site is kept up to 1e5, none from 1e6.
  double me_threshold = 30000;
  double me_sample_step = 3;  ///< pixels between moving-edge sites along an edge
  int me_mask_size = 5;
  /// A face's edges are tracked while the angle between its normal and the line of sight is below this (degrees;
  /// they stop beyond angle_disappear_deg): a face seen edge-on puts its edges within a pixel or two of each other.
  double angle_appear_deg = 70;
  double angle_disappear_deg = 75;
  /// The tracked pose is used when at least this many moving-edge sites took part ...
  int min_edge_features = 16;
  /// ... and the robust weighted RMS of their distances to the edges is below this (pixels).
  double max_rms_px = 1.0;
  /// With tags: the tracked pose is kept only while its CM vertices lie within this many pixels of the tag pose's
  /// (else the edges latched onto something else: the tag pose is used, and starts the next frame).
  double tag_gate_px = 2.0;
  /// Without tags the tracker runs on its own (constant-velocity prediction) for at most this many frames.
  int max_frames_without_tags = 30;
  /// The prism stands on the table (its z axis up): ask ViSP to estimate only its translation in its x-y plane and
  /// its rotation about z (vpMbTracker::setEstimatedDoF). NOTE: ViSP 3.5's vpMbGenericTracker ignores it (its
  /// computeVVS resets the estimated degrees of freedom to all six), so the pose is 6-dof and only the contact
  /// refinement puts it back on the table. Kept for a ViSP that honours it.
  bool planar = true;
  /// Compute the pose covariance from the edge residuals (ViSP's VVS covariance).
  bool covariance = true;
  /// How well the tracked pose is stated to place the robot's vertices (1 sigma per image axis, ideal pixels) in a
  /// frame with tags; without tags it grows by this much per frame (constant-velocity drift). The pipeline adds the
  /// pose covariance this means (through the vertices' projection Jacobian) to ViSP's, which states the sites as
  /// independent and unbiased and was 10^4-10^6 times too small in NEES on the rendered sequences (docs/vision.md).
  double vertex_stddev_px = 3.0;
};

/// One frame of the model-based tracker.
struct ModelTrackResult {
  bool valid = false;
  Eigen::Isometry3d cMo = Eigen::Isometry3d::Identity();
  /// Covariance of cMo: rotation vector on the left in the camera frame, then translation (ObjectEstimate::cov_cMo's
  /// convention), from ViSP's VVS covariance (the residuals' own variance).
  Eigen::Matrix<double, 6, 6> cov_cMo = Eigen::Matrix<double, 6, 6>::Zero();
  int edge_features = 0;  ///< moving-edge sites in the last iteration
  double rms_px = 0;      ///< robust weighted RMS distance of the sites to the model edges, pixels
  const char* failure = "";
};

/// vpMbGenericTracker (moving edges) on one vertical prism. Not thread-safe; not real-time safe (allocates).
class PrismModelTracker {
 public:
  /// @throws JobFailed if the generated CAD model cannot be written or loaded.
  PrismModelTracker(const CameraModel& camera, const ObjectModel& prism, const ModelTrackerOptions& options = {});
  ~PrismModelTracker();
  PrismModelTracker(const PrismModelTracker&) = delete;
  PrismModelTracker& operator=(const PrismModelTracker&) = delete;

  /// Places the model at `prediction` (object in the camera frame) in `image` and tracks its edges there. Images are
  /// undistorted first when the camera has lens distortion (the tracker works in ideal pixels).
  ModelTrackResult Track(const GrayImageView& image, const Eigen::Isometry3d& prediction);
  const ModelTrackerOptions& options() const { return options_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  ModelTrackerOptions options_;
};

/// The CAD model ViSP's tracker loads for a prism (".cao", version 1): the base and top polygons and the sides, each
/// face counter-clockwise seen from outside. Exposed for tests.
std::string PrismCao(const ObjectModel& prism);

}  // namespace visco::vision

#pragma once
// AprilTag detection (the AprilTag C library, hidden behind a PIMPL) and tag pose estimation with the planar
// ambiguity handled explicitly. Poses follow ViSP's convention (docs/formats.md): cMo is the tag frame in the camera
// frame, tag x right and y up as printed, z out of the tag face, the tag size being the black border's outer edge.
// Corners are in the AprilTag library's own order and pixel convention: corner 0 is the bottom-left of the printed
// tag, then counter-clockwise (as printed).

#include <Eigen/Geometry>
#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vision/camera.h"
#include "vision/image.h"

namespace visco::vision {

using Corners = std::array<Eigen::Vector2d, 4>;

/// One decoded tag in one image.
struct TagObservation {
  std::string family;          ///< e.g. "tag36h11"
  int id = -1;                 ///< id within the family
  Corners corners;             ///< pixels, AprilTag order (see file comment)
  double decision_margin = 0;  ///< AprilTag decision margin (higher is more certain); 0 for tracked corners
  int hamming = 0;             ///< bits corrected
};

/// Detector settings. Rejection thresholds apply in Detect(); the pose thresholds in EstimateTagPose().
struct DetectorOptions {
  std::string family = "tag36h11";  ///< tag36h11, tag25h9, tag16h5, tagStandard41h12, tagCircle21h7
  float quad_decimate = 1.0f;       ///< 1 keeps full-resolution quads (best corners); 2 is ~3x faster
  float quad_sigma = 0.0f;          ///< Gaussian blur (pixels) before segmentation; 0.8 helps very noisy images
  int threads = 1;
  double decode_sharpening = 0.25;
  double min_decision_margin = 15;  ///< reject decodes below this margin (false positives sit well below 15)
  int max_hamming = 1;              ///< reject decodes that needed more bit corrections
};

/// Throws InputError("command line", "--family", ...) for an unknown family name.
void CheckFamilyName(const std::string& family);

/// AprilTag detector. Not thread-safe: one instance per thread. Not real-time safe (allocates).
class TagDetector {
 public:
  /// @throws InputError if the family is unknown.
  explicit TagDetector(const DetectorOptions& options = {});
  ~TagDetector();
  TagDetector(const TagDetector&) = delete;
  TagDetector& operator=(const TagDetector&) = delete;

  /// Detects all tags of the family in `image`, dropping decodes below the margin / above the hamming limits.
  /// Sorted by id.
  std::vector<TagObservation> Detect(const GrayImageView& image);
  /// Detects in the rectangle [x0, x0 + w) x [y0, y0 + h) only (clipped to the image; zero-copy); corners are in
  /// full-image pixels. `quad_decimate` > 0 overrides the options' decimation for this call; with decimation the
  /// quads are found at reduced resolution, the bits decoded at full resolution, and the corners refined at full
  /// resolution by RefineCorners (the library's own edge refinement leaves them ~0.2 px off; measured in
  /// tests/bench/vision).
  std::vector<TagObservation> DetectInRegion(const GrayImageView& image, int x0, int y0, int w, int h,
                                             float quad_decimate = 0.0f);
  /// Number of decodes rejected by margin / hamming in the last call.
  int rejected_last() const;
  const DetectorOptions& options() const { return options_; }

 private:
  struct Impl;
  DetectorOptions options_;
  std::unique_ptr<Impl> impl_;
};

/// Refines a tag's four corners at full resolution from an estimate within about `range_px` pixels: each border edge
/// is located along its normal at evenly spaced samples (the gradient-weighted mean position of the border's contrast,
/// bilinear sampling), a line is fitted to each edge (total least squares) and the corners are the lines'
/// intersections; done `passes` times, the search range halving each pass (not below 1 px). Same pixel convention as
/// the detector (pixel centres at +0.5). Returns false (corners untouched) if an edge could not be located.
bool RefineCorners(const GrayImageView& image, Corners& corners, double range_px = 3.0, int passes = 1);

/// One of the two solutions of the planar pose problem, refined to minimise the reprojection error.
struct PoseCandidate {
  Eigen::Isometry3d cMo = Eigen::Isometry3d::Identity();
  double rms_error_px = 0;  ///< RMS reprojection error over the four corners, ideal (undistorted) pixels
};

/// A tag pose with its diagnostics.
struct TagPose {
  Eigen::Isometry3d cMo = Eigen::Isometry3d::Identity();  ///< chosen solution (ViSP convention)
  double rms_error_px = 0;                                ///< of the chosen solution
  std::optional<PoseCandidate> alternative;               ///< the other planar solution, if one exists
  bool ambiguous = false;  ///< both solutions fit within the noise; the choice used the prior or the table plane
  /// Covariance of the pose (6x6: rotation vector perturbation applied on the left in the camera frame, then
  /// translation in metres) for an isotropic corner noise of 1 pixel; scale by sigma^2.
  Eigen::Matrix<double, 6, 6> unit_covariance = Eigen::Matrix<double, 6, 6>::Identity();
};

/// Least-squares solver for the pose of an object from the corners of several tags (multi_tag_pose.h). Started from
/// the pose of one of its tags, except SQPnP (global, needs no start).
enum class JointPoseSolver {
  kOpenCvIterative,  ///< cv::solvePnP SOLVEPNP_ITERATIVE with the start as extrinsic guess (Levenberg-Marquardt)
  kOpenCvSqpnp,      ///< cv::solvePnP SOLVEPNP_SQPNP (globally optimal for its object-space cost; no start)
  kVispVirtualVs,    ///< ViSP vpPose::VIRTUAL_VS (Gauss-Newton virtual visual servoing) from the start
};

/// Pose-estimation settings and rejection rules.
struct PoseOptions {
  /// The AprilTag library puts pixel centres at +0.5 (its corners are 0.5 px larger than in the convention of ViSP's
  /// and OpenCV's calibrations, where the first pixel's centre is 0). This offset is subtracted from the corners
  /// before the pose is computed. ViSP's vpDetectorAprilTag does not correct it (0 reproduces its poses).
  double corner_offset_px = 0.5;
  double max_rms_error_px = 2.0;  ///< reject poses whose best reprojection error exceeds this (bad corners)
  /// The two planar solutions are told apart by their errors when the worse one is unlikely for the corner noise
  /// sigma_c = `corner_noise_px`: its likelihood relative to the better one, exp(-(SSR_worse - SSR_better) /
  /// (2 sigma_c^2)) (SSR = 4 rms^2 over the 4 corners), below `ambiguity_alpha` (SSR excess > 2 ln(1/alpha) sigma_c^2
  /// = 13.8 sigma_c^2); otherwise the data cannot decide and the pose is ambiguous. FeatureEstimator sets
  /// corner_noise_px to its online estimate before every tag (docs/vision.md, "Pose ambiguity and rejection").
  double corner_noise_px = 0.3;
  double ambiguity_alpha = 1e-3;
  // Objects with several tags (multi_tag_pose.h): one pose from all their tags' corners at once.
  /// Fit one pose to all tags of an object seen in a frame; false keeps the old rule (the single best tag).
  bool joint_fit = true;
  /// The solver of the joint fit (chosen by measurement: docs/vision.md, "Objects with several tags").
  JointPoseSolver joint_solver = JointPoseSolver::kOpenCvIterative;
  /// Consistency test of a tag with the joint pose: its corners' residual sum of squares against the chi-square
  /// quantile (8 degrees of freedom) at this false-alarm probability for the current corner noise.
  double tag_outlier_alpha = 1e-3;
  /// Never reject a tag whose RMS residual at the joint pose is below this (pixels): the tags' mounting on the
  /// object (position, rotation, flatness) is known to within about this much in the image.
  double mount_tolerance_px = 0.5;
  /// Planar ambiguity of a joint fit over several coplanar tags (two minima of the same tags): the other minimum
  /// stays a possibility while its likelihood relative to the best, exp(-(SSR_other - SSR_best) / (2 sigma_c^2)) for
  /// the current corner noise sigma_c, is at least this; then the prior or the table normal decides. Below it the
  /// data decide (the smaller error wins), whatever the prior says.
  double joint_ambiguity_alpha = 1e-3;
};

/// Estimates the pose of a square tag of side `tag_size` (metres) from its corners: both planar solutions (IPPE),
/// each refined with Levenberg-Marquardt on the reprojection error in undistorted pixels. Choice: the solution with
/// the clearly smaller error; when the errors do not differ beyond the noise, the one closest in rotation to
/// `prior_cMo` if given, else the one whose z axis (tag normal) is closest to `expected_normal_c` (e.g. the table
/// normal in the camera frame) if given, else the smaller error. Returns nullopt if the corners are degenerate or
/// the error exceeds options.max_rms_error_px.
std::optional<TagPose> EstimateTagPose(const CameraModel& camera, const Corners& corners, double tag_size,
                                       const PoseOptions& options = {},
                                       const std::optional<Eigen::Isometry3d>& prior_cMo = std::nullopt,
                                       const std::optional<Eigen::Vector3d>& expected_normal_c = std::nullopt);

/// The tag's corners in its own frame (ViSP convention, AprilTag order), metres.
std::array<Eigen::Vector3d, 4> TagCornersInTagFrame(double tag_size);

/// Reprojection of the object point `point_o` under `cMo` against its observation `ideal` (undistorted pixels):
/// `residual` = projected minus observed and, when `jacobian` is given, its derivative for a left perturbation of cMo
/// (rotation vector, then translation). Returns whether the point is in front of the camera (z > 0); the outputs are
/// computed either way.
bool ReprojectPoint(const CameraModel& camera, const Eigen::Isometry3d& cMo, const Eigen::Vector3d& point_o,
                    const Eigen::Vector2d& ideal, Eigen::Vector2d& residual, Eigen::Matrix<double, 2, 6>* jacobian);

/// RMS reprojection error (ideal pixels) of `cMo` for observed `corners` (AprilTag convention, see PoseOptions).
double ReprojectionRms(const CameraModel& camera, const Corners& corners, double tag_size, const Eigen::Isometry3d& cMo,
                       double corner_offset_px = 0.5);

}  // namespace visco::vision

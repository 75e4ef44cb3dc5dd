#pragma once
// Tracking between detections, with ViSP: blobs with vpDot2 (the dot targets of visp-images-data's mire-2),
// feature points with KLT (vpKltOpencv, the cube sequence), and AprilTags followed from frame to frame either by
// KLT on their corners or by detection restricted to a region around each tag's last position. The tag tracker's
// mode is chosen by measurement (tests/bench/vision, docs/vision.md): ROI-restricted detection is the default.

#include <Eigen/Core>
#include <memory>
#include <utility>
#include <vector>

#include "vision/image.h"
#include "vision/tag_detector.h"

namespace visco::vision {

/// Finds round blobs brighter (or darker) than their surroundings: Otsu threshold, connected components, filtered by
/// area (pixels) and circularity (4 pi area / perimeter^2). Centres in pixels (OpenCV/ViSP convention).
std::vector<Eigen::Vector2d> FindBlobs(const GrayImageView& image, bool bright, double min_area, double max_area,
                                       double min_circularity = 0.7);

/// Tracks blobs with ViSP's vpDot2. Not thread-safe; not real-time safe.
class DotTracker {
 public:
  DotTracker();
  ~DotTracker();
  DotTracker(const DotTracker&) = delete;
  DotTracker& operator=(const DotTracker&) = delete;
  /// Starts one vpDot2 per seed (a pixel inside each blob).
  void Init(const GrayImageView& image, const std::vector<Eigen::Vector2d>& seeds);
  /// Tracks every dot still alive; a dot that vpDot2 loses stays lost. Returns the number tracked in this frame.
  int Track(const GrayImageView& image);
  const std::vector<Eigen::Vector2d>& centers() const { return centers_; }
  const std::vector<bool>& alive() const { return alive_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<Eigen::Vector2d> centers_;
  std::vector<bool> alive_;
};

/// Tracks points with ViSP's KLT (pyramidal Lucas-Kanade through OpenCV). Not thread-safe; not real-time safe.
class KltTracker {
 public:
  struct Options {
    int max_features = 200;
    int window_size = 11;
    int pyramid_levels = 3;
    double quality = 0.01;
    double min_distance = 8;
  };
  explicit KltTracker(const Options& options);
  KltTracker();
  ~KltTracker();
  KltTracker(const KltTracker&) = delete;
  KltTracker& operator=(const KltTracker&) = delete;
  /// Starts on good features (Shi-Tomasi) found in the image.
  void InitAuto(const GrayImageView& image);
  /// Starts on the given points (pixels, OpenCV convention); their ids are 0..n-1.
  void Init(const GrayImageView& image, const std::vector<Eigen::Vector2d>& points);
  /// Tracks; lost points are dropped. Returns the number still tracked.
  int Track(const GrayImageView& image);
  /// Current points and their ids (ids from Init order).
  std::vector<Eigen::Vector2d> points() const;
  std::vector<long> ids() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// How tags are followed between full detections.
enum class TagTrackingMode {
  kDetectEveryFrame,  ///< full-image detection in every frame (the baseline)
  kRoiDetection,      ///< detection restricted to a window around each tag's last corners
  kKltCorners,        ///< KLT on each tag's four corners
  /// Tags as kRoiDetection; the robot's pose from ViSP's model-based tracker on its silhouette edges, started from
  /// the tags' pose (VisionPipeline; vision/model_tracker.h)
  kModelBased,
};

struct TagTrackerOptions {
  TagTrackingMode mode = TagTrackingMode::kRoiDetection;
  int full_detection_every = 30;  ///< frames between full detections (new tags appear); 1 = always
  /// Window around each tag = the bounding box of its predicted corners (last corners moved by the last
  /// frame-to-frame motion) grown by this fraction of its size + 8 px.
  double roi_margin = 0.6;
  /// Overlapping windows are merged (one detection per merged window) while the merged window is no larger than the
  /// two it replaces: adjacent tags are then not segmented several times.
  bool merge_windows = true;
  /// A window whose smallest predicted tag side is at least this many pixels is searched with quad_decimate 2 (the
  /// quads are found at half resolution; edges are refined and bits decoded at full resolution). 0: never.
  double decimate_min_side_px = 24;
  /// Ids that should be in view: while one of them is not tracked, every frame gets a full detection so that it is
  /// found again as soon as it reappears. The pipeline sets them per frame to the tags predicted visible
  /// (vision/visibility.h; TagTracker::SetExpectedIds), so a tag turned away or hidden does not disable tracking.
  std::vector<int> expected_ids;
};

/// A window the tracker searched in one frame (TagTracker::last_windows): [x0, x1) x [y0, y1), pixels.
struct RoiWindow {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  bool decimated = false;  ///< searched with quad_decimate 2 (big tags), corners refined at full resolution
};

/// Follows tags frame after frame. The observations of tracked frames carry decision_margin 0 for KLT corners.
class TagTracker {
 public:
  TagTracker(const DetectorOptions& detector, const TagTrackerOptions& options);
  ~TagTracker();
  TagTracker(const TagTracker&) = delete;
  TagTracker& operator=(const TagTracker&) = delete;

  /// Processes one frame. `full_detection` tells whether a full-image detection was run.
  std::vector<TagObservation> Process(const GrayImageView& image, bool* full_detection = nullptr);
  /// Ids tracked in the previous frame that were not found in the last one.
  const std::vector<int>& lost_last() const { return lost_; }
  /// The windows searched in the last frame (ROI detection only; empty after a full detection or with KLT).
  const std::vector<RoiWindow>& last_windows() const { return windows_; }
  /// Forces a full detection in the next frame.
  void Reset() { since_full_ = -1; }
  /// Replaces TagTrackerOptions::expected_ids from the next frame on.
  void SetExpectedIds(std::vector<int> ids) { options_.expected_ids = std::move(ids); }
  const std::vector<int>& expected_ids() const { return options_.expected_ids; }

 private:
  std::vector<TagObservation> DetectInWindows(const GrayImageView& image);

  struct Impl;
  std::unique_ptr<Impl> impl_;
  TagTrackerOptions options_;
  int since_full_ = -1;
  std::vector<TagObservation> last_;
  std::vector<TagObservation> before_last_;  // the frame before, for the motion prediction
  std::vector<int> lost_;
  std::vector<RoiWindow> windows_;
};

}  // namespace visco::vision

#pragma once
// The vision pipeline: frames in (an image folder, a video file through OpenCV, or LCM image_t), tag detection and
// tracking, object poses, the robot estimate and visual events out as LCM messages, and the latest estimate handed to
// the control loop through visco::LatestValue (no lock, no allocation on the loop side). Bad frames (corrupt,
// wrongly sized, out of order) and lost tags are reported as fault_t messages with the frame's timestamp; they never
// crash the pipeline and never leave a stale estimate looking fresh (the estimate carries its frame time and is
// marked invalid when the robot is not seen).

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "common/latest_value.h"
#include "lcmtypes/channels.h"
#include "visco/fault_t.hpp"
#include "visco/image_t.hpp"
#include "visco/object_poses_t.hpp"
#include "visco/robot_estimate_t.hpp"
#include "visco/tag_detections_t.hpp"
#include "visco/visual_events_t.hpp"
#include "vision/camera.h"
#include "vision/features.h"
#include "vision/image.h"
#include "vision/model_tracker.h"
#include "vision/object_model.h"
#include "vision/tracking.h"
#include "vision/visibility.h"

namespace lcm {
class LCM;
}

namespace visco::vision {

/// One camera frame.
struct Frame {
  std::int64_t utime = 0;  ///< capture time, microseconds since the epoch
  std::int64_t seq = 0;    ///< frame counter
  std::string camera;
  std::string origin;  ///< where it came from (file name, "lcm"), for messages
  GrayImage image;
};

/// What a source returns for one pull.
enum class SourceStatus { kFrame, kBadFrame, kNoFrameYet, kEnd };

/// A stream of frames. Not thread-safe; the pipeline thread owns it.
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  /// Gets the next frame (kFrame), reports an unusable one (kBadFrame: `error` says why; `frame.utime`/`seq` are
  /// set), says nothing arrived within `timeout_ms` (kNoFrameYet), or that the stream ended (kEnd).
  virtual SourceStatus Next(Frame& frame, std::string& error, int timeout_ms) = 0;
};

/// Frames from the image files of a folder in name order; timestamps start_utime + i / fps.
/// @throws InputError if the folder does not exist or holds no image file.
std::unique_ptr<FrameSource> MakeFolderSource(const std::string& folder, double fps, std::int64_t start_utime);
/// Frames from a video file (OpenCV VideoCapture); timestamps from the container, else from fps. A frame that cannot
/// be read or decoded in the middle of the video is reported (kBadFrame, with its frame number) and the video goes
/// on; the stream ends only where the container's frames end (or after 64 unreadable frames in a row).
/// @throws InputError if the file cannot be opened.
std::unique_ptr<FrameSource> MakeVideoSource(const std::string& path, std::int64_t start_utime);
/// Frames from image_t messages on `channel` of an LCM bus (the caller keeps `bus` alive; the source handles it).
std::unique_ptr<FrameSource> MakeLcmSource(lcm::LCM& bus, const std::string& channel);

/// Decodes an image_t into a grey frame. Returns false with `error` for a corrupt or inconsistent message.
bool DecodeImageMessage(const visco::image_t& msg, Frame& frame, std::string& error);

/// Fixed-size estimate for the control loop (trivially copyable, LatestValue<VisionSnapshot>).
struct VisionSnapshot {
  static constexpr int kMaxEvents = 32;
  struct Event {
    double signed_distance_px;
    double stddev_px;
    std::int8_t state;  // SideState
    bool crossed;
  };
  std::int64_t frame_utime;  ///< capture time of the frame this comes from
  std::int64_t frame_seq;
  std::int64_t publish_utime;  ///< when the pipeline finished the frame
  bool robot_valid;            ///< false: the robot was not seen in this frame
  double position[2];          ///< metres, world
  double position_stddev;
  double heading;
  std::int32_t num_events;  ///< min(pairs, kMaxEvents), in ObjectModels::events order
  Event events[kMaxEvents];
};

struct PipelineOptions {
  DetectorOptions detector;
  TagTrackerOptions tracker;
  NoiseModel noise;
  PoseOptions pose;
  ContactOptions contact;  ///< face-contact refinement of the object poses
  /// Expect (and so search the whole image for, every frame, while missing) only the tags predicted visible at the
  /// objects' last poses: facing the camera, inside the image, large enough, not hidden by the prisms. false: every
  /// model tag is expected (the rule before 2026-12-04; a tag that cannot be seen then forces full detections).
  bool expect_only_visible = true;
  VisibilityOptions visibility;
  /// The robot's model-based tracker (tracker.mode == TagTrackingMode::kModelBased).
  ModelTrackerOptions model_tracker;
  std::string camera_name = "camera";
  /// Publication times (microseconds since the epoch) of the outputs; empty: the system clock. A replay sets the
  /// log's clock here, so that nothing the pipeline produces depends on the wall clock.
  std::function<std::int64_t()> clock;
};

/// Everything published for one processed frame, plus faults.
struct PipelineOutput {
  bool processed = false;  ///< false: the frame was rejected (see faults)
  visco::tag_detections_t detections;
  visco::object_poses_t poses;
  visco::robot_estimate_t robot;
  visco::visual_events_t events;
  std::vector<visco::fault_t> faults;
  VisionSnapshot snapshot{};
  bool full_detection = false;
  /// The tags whose visibility was predicted for this frame (from their object's last pose) and the prediction; a
  /// tag of an object without a usable pose is expected without a prediction and is not listed.
  struct TagPrediction {
    int id;
    TagVisibility visibility;
  };
  std::vector<TagPrediction> predicted_tags;
  std::vector<int> expected_ids;       ///< what the tracker expected in this frame
  std::vector<RoiWindow> roi_windows;  ///< the windows the tracker searched (empty after a full detection)
  std::vector<int> lost_tags;          ///< tags tracked in the previous frame and not found in this one
  /// TagTrackingMode::kModelBased: what the robot's model-based tracker did in this frame.
  struct ModelTracking {
    bool ran = false;        ///< it had a prediction (the tags' pose, or its own for a few frames without tags)
    bool used = false;       ///< its pose is the robot's measured pose
    bool from_tags = false;  ///< started from the tags' pose of this frame (else from its own prediction)
    int edge_features = 0;
    double rms_px = 0;
    std::string failure;  ///< why its pose was not used
  } model;
};

/// Calls `f(channel, message)` for each message of `out`, in the order the pipeline thread publishes them: detections,
/// poses, robot estimate, visual events (processed frames only), then the faults. A replay uses the same order.
template <class F>
void ForEachMessage(const PipelineOutput& out, F&& f) {
  if (out.processed) {
    f(channels::kTagDetections, out.detections);
    f(channels::kObjectPoses, out.poses);
    f(channels::kRobotEstimate, out.robot);
    f(channels::kVisualEvents, out.events);
  }
  for (const auto& fault : out.faults) f(channels::kFault, fault);
}

/// The per-frame work, without threads or I/O. Not thread-safe.
class VisionPipeline {
 public:
  VisionPipeline(const CameraModel& camera, const Eigen::Isometry3d& wMc, const ObjectModels& models,
                 const PipelineOptions& options);
  ~VisionPipeline();
  VisionPipeline(const VisionPipeline&) = delete;
  VisionPipeline& operator=(const VisionPipeline&) = delete;
  /// Processes one frame that arrived at `arrival_utime` (for the latency fields).
  PipelineOutput Process(const Frame& frame, std::int64_t arrival_utime);
  /// Reports a frame the source could not deliver (or that is unusable). Its number counts as seen: it is reported
  /// here, not again as a gap before the next frame; the tracker detects in full in the next frame (its prediction
  /// skipped a frame).
  visco::fault_t BadFrame(const Frame& frame, const std::string& error);
  const FeatureEstimator& features() const { return features_; }
  /// Gaps in the frame counter (lost frames, each reported) and stream restarts (the counter went back) so far.
  std::int64_t gaps() const { return gaps_; }
  std::int64_t restarts() const { return restarts_; }

 private:
  CameraModel camera_;
  PipelineOptions options_;
  TagTracker tracker_;
  FeatureEstimator features_;
  std::optional<std::int64_t> last_utime_, last_seq_;
  bool unsequenced_ = false;  // the camera's frame counter does not advance
  std::int64_t gaps_ = 0, restarts_ = 0;
  // The tags predicted visible (PipelineOptions::expect_only_visible), with the predictions for `out`.
  std::vector<int> ExpectedTags(PipelineOutput& out) const;
  // TagTrackingMode::kModelBased: the robot's pose from its edges, started from the tags' (FeatureEstimator's
  // RobotPoseRefiner).
  std::optional<RobotPoseMeasurement> TrackRobotModel(const GrayImageView& image, const ObjectEstimate& from_tags,
                                                      PipelineOutput& out);
  /// The covariance of cMo (cov_cMo's convention) under which the robot's vertices scatter by `vertex_stddev_px` per
  /// image axis: how good the model-based tracker's pose is stated to be (ModelTrackerOptions::vertex_stddev_px).
  Eigen::Matrix<double, 6, 6> ModelPoseFloor(const Eigen::Isometry3d& cMo, double vertex_stddev_px) const;
  void ResetModelTracking();
  std::unique_ptr<PrismModelTracker> model_tracker_;
  std::optional<Eigen::Isometry3d> model_last_, model_before_last_;  // the robot's cMo in the last two frames
  int model_frames_without_tags_ = 0;
  std::vector<std::vector<int>> tag_cells_;  // per object (robot, then obstacles), per tag: cells across the border
  std::vector<std::optional<Eigen::Isometry3d>> last_known_wMo_;  // per object: its last measured pose
  bool robot_lost_reported_ = false;
  std::set<std::pair<std::string, int>> outlier_reported_;  // (object id, tag id) reported as inconsistent
};

/// Microseconds since the epoch (system clock).
std::int64_t NowUtime();

/// Runs a source through a pipeline on its own thread, publishes on LCM (if a bus is given) and into `latest`.
class PipelineThread {
 public:
  /// `bus` and `latest` may be null; `on_output` (may be empty) is called on the pipeline thread after each frame.
  PipelineThread(std::unique_ptr<FrameSource> source, VisionPipeline& pipeline, lcm::LCM* bus,
                 LatestValue<VisionSnapshot>* latest, std::function<void(const PipelineOutput&)> on_output = {});
  ~PipelineThread();
  void Start();
  /// Asks the thread to stop and waits for it.
  void Stop();
  /// Waits for the end of the stream.
  void Join();
  /// Also called on the pipeline thread after each pull, after `on_output`, with the frame itself (for pictures:
  /// vision/overlay.h). `frame.image` is this frame's only when `out.processed`. Set before Start().
  void SetFrameCallback(std::function<void(const Frame&, const PipelineOutput&)> on_frame) {
    on_frame_ = std::move(on_frame);
  }
  std::int64_t frames() const { return frames_.load(); }
  std::int64_t bad_frames() const { return bad_frames_.load(); }
  /// True once the stream has ended or the thread was stopped.
  bool finished() const { return finished_.load(); }

 private:
  void Run();
  std::unique_ptr<FrameSource> source_;
  VisionPipeline& pipeline_;
  lcm::LCM* bus_;
  LatestValue<VisionSnapshot>* latest_;
  std::function<void(const PipelineOutput&)> on_output_;
  std::function<void(const Frame&, const PipelineOutput&)> on_frame_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> finished_{false};
  std::atomic<std::int64_t> frames_{0}, bad_frames_{0};
};

}  // namespace visco::vision

#include "vision/pipeline.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <lcm/lcm-cpp.hpp>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "common/error.h"
#include "lcmtypes/channels.h"
#include "vision/tag_renderer.h"

namespace visco::vision {
namespace {

std::string Describe(const Frame& f) {
  return "frame seq " + std::to_string(f.seq) + " (utime " + std::to_string(f.utime) +
         (f.origin.empty() ? "" : ", " + f.origin) + ")";
}

visco::fault_t Fault(std::int64_t utime, std::int32_t code, std::int8_t severity, const std::string& message,
                     bool cleared = false) {
  visco::fault_t f{};
  f.utime = utime;
  f.source = "vision";
  f.code = code;
  f.severity = severity;
  f.robot_stopped = false;
  f.cleared = cleared;
  f.message = message;
  return f;
}

void ToQuaternion(const Eigen::Matrix3d& r, double out[4]) {
  const Eigen::Quaterniond q(r);
  out[0] = q.w(), out[1] = q.x(), out[2] = q.y(), out[3] = q.z();
}

bool GrayFromMat(const cv::Mat& m, GrayImage& out) {
  if (m.empty()) return false;
  cv::Mat g;
  if (m.channels() == 1) {
    g = m;
  } else if (m.channels() == 3) {
    cv::cvtColor(m, g, cv::COLOR_BGR2GRAY);
  } else if (m.channels() == 4) {
    cv::cvtColor(m, g, cv::COLOR_BGRA2GRAY);
  } else {
    return false;
  }
  if (g.depth() != CV_8U) return false;
  out = GrayImage(g.cols, g.rows);
  for (int v = 0; v < g.rows; ++v) std::copy_n(g.ptr<std::uint8_t>(v), g.cols, &out.pixels[std::size_t(v) * g.cols]);
  return true;
}

class FolderSource : public FrameSource {
 public:
  FolderSource(std::vector<std::string> files, double fps, std::int64_t start)
      : files_(std::move(files)), period_us_(static_cast<std::int64_t>(1e6 / fps)), start_(start) {}
  SourceStatus Next(Frame& frame, std::string& error, int) override {
    if (next_ >= files_.size()) return SourceStatus::kEnd;
    const std::size_t i = next_++;
    frame.seq = static_cast<std::int64_t>(i);
    frame.utime = start_ + static_cast<std::int64_t>(i) * period_us_;
    frame.origin = std::filesystem::path(files_[i]).filename().string();
    cv::Mat m;
    try {
      m = cv::imread(files_[i], cv::IMREAD_UNCHANGED);
    } catch (const cv::Exception& e) {
      error = std::string("cannot decode image: ") + e.err;
      return SourceStatus::kBadFrame;
    }
    if (!GrayFromMat(m, frame.image)) {
      error = "cannot decode image (corrupt or unsupported format)";
      return SourceStatus::kBadFrame;
    }
    return SourceStatus::kFrame;
  }

 private:
  std::vector<std::string> files_;
  std::int64_t period_us_;
  std::int64_t start_;
  std::size_t next_ = 0;
};

// A video file. OpenCV's read() returns false both at the end and for a frame it cannot decode (a corrupt JPEG of
// an MJPG stream, for instance), after which the following frames read again. So a failed read is not the end: the
// source reads on, up to kMaxUnreadable frames; a failure followed by a good frame is reported as one bad frame per
// unreadable frame (with its number) before the good one, and only a run of failures that reaches the end of the
// container (or kMaxUnreadable) ends the stream. Frame numbers count the frames read or attempted, so a frame that
// could not be read keeps its number and the pipeline sees no gap after it.
class VideoSource : public FrameSource {
 public:
  VideoSource(cv::VideoCapture cap, std::string name, std::int64_t start)
      : cap_(std::move(cap)), name_(std::move(name)), start_(start) {
    fps_ = cap_.get(cv::CAP_PROP_FPS);
    if (!(fps_ > 0)) fps_ = 30;
    const double count = cap_.get(cv::CAP_PROP_FRAME_COUNT);
    frame_count_ = count > 0 ? static_cast<std::int64_t>(count) : -1;
  }
  SourceStatus Next(Frame& frame, std::string& error, int) override {
    if (unreadable_ > 0) {
      // Frames that could not be read before the one waiting in pending_: one report each, in order.
      --unreadable_;
      frame.seq = pending_seq_ - unreadable_ - 1;
      frame.utime = pending_utime_ - static_cast<std::int64_t>(static_cast<double>(unreadable_ + 1) * 1e6 / fps_);
      frame.origin = name_;
      frame.image = GrayImage();
      error = "cannot read or decode video frame " + std::to_string(frame.seq) + " (corrupt); the video goes on";
      return SourceStatus::kBadFrame;
    }
    cv::Mat m;
    if (has_pending_) {
      m = std::move(pending_);
      has_pending_ = false;
    } else {
      std::int64_t failed = 0;
      while (!Read(m)) {
        ++failed;
        const bool past_end = frame_count_ >= 0 && seq_ + failed >= frame_count_;
        if (past_end || failed >= kMaxUnreadable) {
          if (frame_count_ >= 0 && seq_ < frame_count_) {
            // The container announced more frames than could be read: said once, then the end.
            frame.seq = seq_;
            frame.utime = start_ + static_cast<std::int64_t>(static_cast<double>(seq_) * 1e6 / fps_);
            frame.origin = name_;
            frame.image = GrayImage();
            error = "video frames " + std::to_string(seq_) + ".." + std::to_string(frame_count_ - 1) + " of " +
                    std::to_string(frame_count_) + " cannot be read (truncated or corrupt at the end)";
            seq_ = frame_count_;
            return SourceStatus::kBadFrame;
          }
          return SourceStatus::kEnd;
        }
      }
      if (failed > 0) {
        // Unreadable frames in the middle: report them first, then deliver this one.
        seq_ += failed;
        pending_ = std::move(m);
        has_pending_ = true;
        pending_seq_ = seq_;
        pending_utime_ = Utime(seq_);
        unreadable_ = failed;
        return Next(frame, error, 0);
      }
    }
    frame.seq = seq_;
    frame.utime = Utime(seq_);
    ++seq_;
    frame.origin = name_;
    if (!GrayFromMat(m, frame.image)) {
      error = "cannot convert the decoded frame to grey";
      return SourceStatus::kBadFrame;
    }
    return SourceStatus::kFrame;
  }

 private:
  static constexpr std::int64_t kMaxUnreadable = 64;
  bool Read(cv::Mat& m) {
    bool ok = false;
    try {
      ok = cap_.read(m);
    } catch (const cv::Exception&) {
      ok = false;
    }
    if (ok && !m.empty()) last_ms_ = cap_.get(cv::CAP_PROP_POS_MSEC);
    return ok && !m.empty();
  }
  // Capture time of the frame just read: the container's timestamp when it has one, else from the frame number.
  std::int64_t Utime(std::int64_t seq) const {
    return start_ + (last_ms_ > 0 ? static_cast<std::int64_t>(last_ms_ * 1000)
                                  : static_cast<std::int64_t>(static_cast<double>(seq) * 1e6 / fps_));
  }
  cv::VideoCapture cap_;
  std::string name_;
  std::int64_t start_;
  double fps_;
  std::int64_t frame_count_;  // from the container; -1 if unknown
  std::int64_t seq_ = 0;      // number of the next frame
  double last_ms_ = 0;
  cv::Mat pending_;  // a good frame read after unreadable ones
  bool has_pending_ = false;
  std::int64_t pending_seq_ = 0, pending_utime_ = 0;
  std::int64_t unreadable_ = 0;  // unreadable frames still to report before pending_
};

class LcmSource : public FrameSource {
 public:
  LcmSource(lcm::LCM& bus, const std::string& channel) : bus_(bus) {
    sub_ = bus_.subscribe(channel, &LcmSource::Handle, this);
  }
  ~LcmSource() override { bus_.unsubscribe(sub_); }
  SourceStatus Next(Frame& frame, std::string& error, int timeout_ms) override {
    if (queue_.empty()) bus_.handleTimeout(timeout_ms);
    // Drain what is waiting in the socket (bounded): left there, a backlog makes the kernel drop the newest frames
    // unseen. The queue keeps the newest few; the pipeline reports what was skipped as a gap in the frame counter.
    for (int i = 0; i < kMaxDrain && bus_.handleTimeout(0) > 0; ++i) {
    }
    if (queue_.empty()) return SourceStatus::kNoFrameYet;
    const visco::image_t msg = std::move(queue_.front());
    queue_.pop_front();
    return DecodeImageMessage(msg, frame, error) ? SourceStatus::kFrame : SourceStatus::kBadFrame;
  }
  void Handle(const lcm::ReceiveBuffer*, const std::string&, const visco::image_t* msg) {
    // Keep the newest few: vision must not fall behind the camera (dropped frames show up as seq gaps).
    if (queue_.size() >= 4) queue_.pop_front();
    queue_.push_back(*msg);
  }

 private:
  static constexpr int kMaxDrain = 64;
  lcm::LCM& bus_;
  lcm::Subscription* sub_ = nullptr;
  std::deque<visco::image_t> queue_;
};

TagTrackerOptions WithExpectedIds(TagTrackerOptions o, const ObjectModels& models) {
  for (const auto& t : models.robot.tags) o.expected_ids.push_back(t.id);
  for (const auto& ob : models.obstacles) {
    for (const auto& t : ob.tags) o.expected_ids.push_back(t.id);
  }
  return o;
}

}  // namespace

// object_pose_t::pose_decision carries PoseDecision's values.
static_assert(static_cast<int>(PoseDecision::kSingleTag) == visco::object_pose_t::POSE_DECISION_SINGLE_TAG);
static_assert(static_cast<int>(PoseDecision::kUnique) == visco::object_pose_t::POSE_DECISION_UNIQUE);
static_assert(static_cast<int>(PoseDecision::kSmallerError) == visco::object_pose_t::POSE_DECISION_SMALLER_ERROR);
static_assert(static_cast<int>(PoseDecision::kPrior) == visco::object_pose_t::POSE_DECISION_PRIOR);
static_assert(static_cast<int>(PoseDecision::kExpectedUp) == visco::object_pose_t::POSE_DECISION_EXPECTED_UP);
static_assert(static_cast<int>(PoseDecision::kUndecided) == visco::object_pose_t::POSE_DECISION_UNDECIDED);

std::int64_t NowUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

bool DecodeImageMessage(const visco::image_t& msg, Frame& frame, std::string& error) {
  frame.utime = msg.utime;
  frame.seq = msg.seq;
  frame.camera = msg.camera;
  frame.origin = "lcm";
  if (msg.size != static_cast<std::int32_t>(msg.data.size())) {
    error = "size field " + std::to_string(msg.size) + " differs from the data length";
    return false;
  }
  if (msg.width <= 0 || msg.height <= 0) {
    error = "non-positive image size " + std::to_string(msg.width) + "x" + std::to_string(msg.height);
    return false;
  }
  cv::Mat m;
  switch (msg.pixel_format) {
    case visco::image_t::PIXEL_FORMAT_GRAY8:
    case visco::image_t::PIXEL_FORMAT_RGB8:
    case visco::image_t::PIXEL_FORMAT_BGR8: {
      const int bpp = msg.pixel_format == visco::image_t::PIXEL_FORMAT_GRAY8 ? 1 : 3;
      if (msg.row_stride < msg.width * bpp ||
          static_cast<std::int64_t>(msg.row_stride) * msg.height > static_cast<std::int64_t>(msg.data.size())) {
        error = "row_stride " + std::to_string(msg.row_stride) + " x height " + std::to_string(msg.height) +
                " does not fit the " + std::to_string(msg.data.size()) + " data bytes";
        return false;
      }
      const cv::Mat raw(msg.height, msg.width, bpp == 1 ? CV_8UC1 : CV_8UC3, const_cast<std::uint8_t*>(msg.data.data()),
                        static_cast<std::size_t>(msg.row_stride));
      if (bpp == 1) {
        m = raw;
      } else {
        cv::cvtColor(raw, m,
                     msg.pixel_format == visco::image_t::PIXEL_FORMAT_RGB8 ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY);
      }
      break;
    }
    case visco::image_t::PIXEL_FORMAT_MJPEG:
    case visco::image_t::PIXEL_FORMAT_PNG: {
      try {
        m = cv::imdecode(msg.data, cv::IMREAD_GRAYSCALE);
      } catch (const cv::Exception& e) {
        m.release();
      }
      if (m.empty()) {
        error = "corrupt compressed image";
        return false;
      }
      if (m.cols != msg.width || m.rows != msg.height) {
        error = "decoded image is " + std::to_string(m.cols) + "x" + std::to_string(m.rows) + ", message says " +
                std::to_string(msg.width) + "x" + std::to_string(msg.height);
        return false;
      }
      break;
    }
    default:
      error = "unknown pixel_format " + std::to_string(msg.pixel_format);
      return false;
  }
  return GrayFromMat(m, frame.image) || (error = "cannot convert to grey", false);
}

std::unique_ptr<FrameSource> MakeFolderSource(const std::string& folder, double fps, std::int64_t start_utime) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) throw InputError(folder, "", "image folder does not exist");
  if (!(fps > 0)) throw InputError("command line", "--fps", "must be positive");
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(folder)) {
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (e.is_regular_file() && (ext == ".pgm" || ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".ppm" ||
                                ext == ".bmp" || ext == ".tif" || ext == ".tiff")) {
      files.push_back(e.path().string());
    }
  }
  if (files.empty()) throw InputError(folder, "", "holds no image file (.pgm, .png, .jpg, .ppm, .bmp, .tif)");
  std::sort(files.begin(), files.end());
  return std::make_unique<FolderSource>(std::move(files), fps, start_utime);
}

std::unique_ptr<FrameSource> MakeVideoSource(const std::string& path, std::int64_t start_utime) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw InputError(path, "", "video file does not exist");
  cv::VideoCapture cap(path);
  if (!cap.isOpened()) throw InputError(path, "", "cannot be opened as a video");
  return std::make_unique<VideoSource>(std::move(cap), std::filesystem::path(path).filename().string(), start_utime);
}

std::unique_ptr<FrameSource> MakeLcmSource(lcm::LCM& bus, const std::string& channel) {
  return std::make_unique<LcmSource>(bus, channel);
}

VisionPipeline::VisionPipeline(const CameraModel& camera, const Eigen::Isometry3d& wMc, const ObjectModels& models,
                               const PipelineOptions& options)
    : camera_(camera),
      options_(options),
      tracker_(options.detector, WithExpectedIds(options.tracker, models)),
      features_(camera, wMc, models, options.noise, options.pose, options.contact) {
  auto cells = [](const ObjectModel& m) {
    std::vector<int> out;
    for (const auto& t : m.tags) out.push_back(MakeTagBitmap(t.family, t.id).width_at_border);
    return out;
  };
  tag_cells_.push_back(cells(models.robot));
  for (const auto& o : models.obstacles) tag_cells_.push_back(cells(o));
  last_known_wMo_.assign(tag_cells_.size(), std::nullopt);
  if (options.tracker.mode == TagTrackingMode::kModelBased) {
    model_tracker_ = std::make_unique<PrismModelTracker>(camera, models.robot, options.model_tracker);
  }
}

VisionPipeline::~VisionPipeline() = default;

void VisionPipeline::ResetModelTracking() {
  model_last_.reset();
  model_before_last_.reset();
  model_frames_without_tags_ = 0;
}

std::optional<RobotPoseMeasurement> VisionPipeline::TrackRobotModel(const GrayImageView& image,
                                                                    const ObjectEstimate& from_tags,
                                                                    PipelineOutput& out) {
  const ModelTrackerOptions& o = options_.model_tracker;
  std::optional<Eigen::Isometry3d> prediction;
  if (from_tags.valid) {
    // The tags' pose of this frame: the best start there is (sub-pixel), so the edge search can stay short.
    prediction = from_tags.cMo_measured;
    model_frames_without_tags_ = 0;
  } else if (model_last_ && model_frames_without_tags_ < o.max_frames_without_tags) {
    // No tag: the tracker goes on alone for a while, at constant velocity (camera frame).
    ++model_frames_without_tags_;
    prediction = model_before_last_ ? Eigen::Isometry3d(*model_last_ * model_before_last_->inverse() * *model_last_)
                                    : *model_last_;
  }
  if (!prediction) {
    ResetModelTracking();
    return std::nullopt;
  }
  ModelTrackResult r = model_tracker_->Track(image, *prediction);
  out.model.ran = true;
  out.model.from_tags = from_tags.valid;
  out.model.edge_features = r.edge_features;
  out.model.rms_px = r.rms_px;
  out.model.failure = r.failure;
  if (r.valid && from_tags.valid) {
    // The edges must agree with the tags: a pose whose vertices (top and base) lie off the tags' by more than the gate
    // has latched onto other edges.
    const ObjectModel& robot = features_.models().robot;
    double worst = 0;
    for (const auto& v : robot.polygon) {
      for (double z : {0.0, robot.height}) {
        const Eigen::Vector3d p(v.x(), v.y(), z);
        worst = std::max(worst,
                         (camera_.ProjectIdeal(r.cMo * p) - camera_.ProjectIdeal(from_tags.cMo_measured * p)).norm());
      }
    }
    if (worst > o.tag_gate_px) {
      r.valid = false;
      out.model.failure = "disagrees with the tags";
    }
  }
  if (!r.valid) {
    if (from_tags.valid) {
      model_before_last_ = model_last_;
      model_last_ = from_tags.cMo_measured;
    } else {
      ResetModelTracking();
    }
    return std::nullopt;
  }
  out.model.used = true;
  model_before_last_ = model_last_;
  model_last_ = r.cMo;
  return RobotPoseMeasurement{r.cMo,
                              r.cov_cMo + ModelPoseFloor(r.cMo, o.vertex_stddev_px * (1 + model_frames_without_tags_))};
}

Eigen::Matrix<double, 6, 6> VisionPipeline::ModelPoseFloor(const Eigen::Isometry3d& cMo,
                                                           double vertex_stddev_px) const {
  // The pose covariance under which the robot's vertices (top and base) scatter by vertex_stddev_px per image axis:
  // s^2 (J^T J)^-1, J the vertices' ideal-pixel Jacobian in cov_cMo's perturbation (central differences).
  const ObjectModel& robot = features_.models().robot;
  std::vector<Eigen::Vector3d> vertices;
  for (const auto& v : robot.polygon) {
    for (double z : {0.0, robot.height}) vertices.emplace_back(v.x(), v.y(), z);
  }
  Eigen::MatrixXd j(2 * static_cast<Eigen::Index>(vertices.size()), 6);
  for (int k = 0; k < 6; ++k) {
    Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
    d[k] = k < 3 ? 1e-6 : 1e-7;  // radians, metres
    const Eigen::Isometry3d plus = PerturbPose(cMo, d), minus = PerturbPose(cMo, -d);
    for (std::size_t i = 0; i < vertices.size(); ++i) {
      j.block<2, 1>(2 * static_cast<Eigen::Index>(i), k) =
          (camera_.ProjectIdeal(plus * vertices[i]) - camera_.ProjectIdeal(minus * vertices[i])) / (2 * d[k]);
    }
  }
  const Eigen::Matrix<double, 6, 6> jtj = j.transpose() * j;
  return vertex_stddev_px * vertex_stddev_px * jtj.ldlt().solve(Eigen::Matrix<double, 6, 6>::Identity());
}

std::vector<int> VisionPipeline::ExpectedTags(PipelineOutput& out) const {
  const ObjectModels& models = features_.models();
  std::vector<PlacedPrism> prisms;
  for (std::size_t k = 0; k < last_known_wMo_.size(); ++k) {
    if (last_known_wMo_[k]) prisms.push_back({k == 0 ? &models.robot : &models.obstacles[k - 1], *last_known_wMo_[k]});
  }
  std::vector<int> ids;
  for (std::size_t k = 0; k < last_known_wMo_.size(); ++k) {
    const ObjectModel& m = k == 0 ? models.robot : models.obstacles[k - 1];
    // The robot moves: its last pose predicts where its tags are only while it is tracked; lost, it is searched for
    // in every frame. Obstacles stand still: their last pose predicts their tags even when they were not seen.
    const bool predict = last_known_wMo_[k] && (k > 0 || features_.last().robot_pose.valid);
    for (std::size_t t = 0; t < m.tags.size(); ++t) {
      if (!predict) {
        ids.push_back(m.tags[t].id);
        continue;
      }
      const TagVisibility v = PredictTagVisibility(camera_, features_.wMc(), m.tags[t], tag_cells_[k][t],
                                                   *last_known_wMo_[k], prisms, options_.visibility);
      out.predicted_tags.push_back({m.tags[t].id, v});
      if (v == TagVisibility::kVisible) ids.push_back(m.tags[t].id);
    }
  }
  return ids;
}

visco::fault_t VisionPipeline::BadFrame(const Frame& frame, const std::string& error) {
  if (last_seq_ && frame.seq > *last_seq_ && (!last_utime_ || frame.utime > *last_utime_)) {
    // A frame of the sequence is missing: the tracker's prediction from the last good frame is one frame short.
    last_seq_ = frame.seq;
    tracker_.Reset();
    ResetModelTracking();
  }
  return Fault(frame.utime, visco::fault_t::CODE_BAD_MESSAGE, visco::fault_t::SEVERITY_WARNING,
               Describe(frame) + ": " + error + "; dropped");
}

PipelineOutput VisionPipeline::Process(const Frame& frame, std::int64_t arrival_utime) {
  PipelineOutput out;
  if (camera_.width > 0 && (frame.image.width != camera_.width || frame.image.height != camera_.height)) {
    out.faults.push_back(BadFrame(frame, "image is " + std::to_string(frame.image.width) + "x" +
                                             std::to_string(frame.image.height) + ", the camera's is " +
                                             std::to_string(camera_.width) + "x" + std::to_string(camera_.height)));
    return out;
  }
  if (frame.image.pixels.size() != static_cast<std::size_t>(frame.image.width) * frame.image.height ||
      frame.image.width <= 0) {
    out.faults.push_back(BadFrame(frame, "empty or inconsistent image"));
    return out;
  }
  // Frames are ordered by capture time; the frame counter tells what was lost in between.
  if (last_utime_ && frame.utime <= *last_utime_) {
    out.faults.push_back(BadFrame(frame, "out of order (previous frame seq " + std::to_string(*last_seq_) + ", utime " +
                                             std::to_string(*last_utime_) + ")"));
    return out;
  }
  if (last_seq_) {
    const std::int64_t previous = *last_seq_;
    if (frame.seq > previous + 1) {
      // Lost frames: reported with their numbers; the tracker's prediction from the last frame is void.
      ++gaps_;
      out.faults.push_back(Fault(frame.utime, visco::fault_t::CODE_VISION_STALE, visco::fault_t::SEVERITY_WARNING,
                                 "frames " + std::to_string(previous + 1) + ".." + std::to_string(frame.seq - 1) +
                                     " (" + std::to_string(frame.seq - previous - 1) + ") lost before " +
                                     Describe(frame) + ": full detection"));
      tracker_.Reset();
      ResetModelTracking();
    } else if (frame.seq == previous) {
      // A camera whose counter does not advance: frames are taken by time, and gaps cannot be seen (said once).
      if (!unsequenced_) {
        unsequenced_ = true;
        out.faults.push_back(Fault(frame.utime, visco::fault_t::CODE_BAD_MESSAGE, visco::fault_t::SEVERITY_WARNING,
                                   "the camera's frame counter does not advance (" + Describe(frame) +
                                       "): frames are ordered by time, lost frames cannot be detected"));
      }
    } else if (frame.seq < previous) {
      // The counter went back while time went on: the camera restarted. Nothing of the old stream carries over.
      ++restarts_;
      out.faults.push_back(Fault(frame.utime, visco::fault_t::CODE_BAD_MESSAGE, visco::fault_t::SEVERITY_WARNING,
                                 "stream restart: " + Describe(frame) + " after frame seq " + std::to_string(previous) +
                                     ": tracker and features reset"));
      tracker_.Reset();
      features_.Reset();
      ResetModelTracking();
      last_known_wMo_.assign(last_known_wMo_.size(), std::nullopt);
      unsequenced_ = false;
    }
  }
  last_utime_ = frame.utime;
  last_seq_ = frame.seq;
  out.processed = true;

  if (options_.expect_only_visible) tracker_.SetExpectedIds(ExpectedTags(out));
  out.expected_ids = tracker_.expected_ids();
  const auto tags = tracker_.Process(frame.image.view(), &out.full_detection);
  out.roi_windows = tracker_.last_windows();
  out.lost_tags = tracker_.lost_last();
  RobotPoseRefiner refine;
  if (model_tracker_) {
    refine = [&](const ObjectEstimate& from_tags) { return TrackRobotModel(frame.image.view(), from_tags, out); };
  }
  const FrameFeatures& f = features_.Update(tags, refine);
  if (f.robot_pose.valid) last_known_wMo_[0] = f.robot_pose.wMo;
  for (std::size_t k = 0; k < f.obstacle_poses.size(); ++k) {
    if (f.obstacle_poses[k].valid) last_known_wMo_[k + 1] = f.obstacle_poses[k].wMo;
  }
  const ObjectModels& models = features_.models();
  const std::int64_t done = options_.clock ? options_.clock() : NowUtime();

  // Detections.
  auto& d = out.detections;
  d.utime = done;
  d.frame_utime = frame.utime;
  d.frame_seq = frame.seq;
  d.camera = frame.camera.empty() ? options_.camera_name : frame.camera;
  d.processing_time_s = static_cast<double>(done - arrival_utime) * 1e-6;
  d.pixel_digest = static_cast<std::int64_t>(PixelDigest(frame.image.view()));
  for (const auto& t : tags) {
    visco::tag_detection_t td{};
    td.utime = frame.utime;
    td.family = t.family;
    td.id = t.id;
    for (int k = 0; k < 4; ++k) td.corners[k][0] = t.corners[k].x(), td.corners[k][1] = t.corners[k].y();
    td.decision_margin = t.decision_margin;
    td.hamming = t.hamming;
    td.tracked = !out.full_detection;
    // The pose of the tag as estimated by the features (same prior and rejection), if it belongs to an object.
    auto fill = [&](const ObjectEstimate& o) {
      if (!o.valid) return;
      for (const TagEstimate& te : o.tags) {
        if (te.id != t.id || te.outlier) continue;
        td.position[0] = te.cMt.translation().x(), td.position[1] = te.cMt.translation().y();
        td.position[2] = te.cMt.translation().z();
        ToQuaternion(te.cMt.linear(), td.orientation);
        td.reprojection_error = te.rms_error_px;
      }
    };
    td.orientation[0] = 1;
    td.reprojection_error = -1;  // no pose: not a tag of the models, rejected, or an outlier of its object
    fill(f.robot_pose);
    for (const auto& o : f.obstacle_poses) fill(o);
    d.detections.push_back(td);
  }
  d.num_detections = static_cast<std::int32_t>(d.detections.size());

  // Object poses.
  auto& p = out.poses;
  p.utime = done;
  p.frame_utime = frame.utime;
  auto add_pose = [&](const ObjectEstimate& o, const std::string& id) {
    if (!o.valid) return;
    visco::object_pose_t op{};
    op.utime = frame.utime;
    op.object_id = id;
    for (int k = 0; k < 3; ++k) op.position[k] = o.wMo.translation()[k];
    ToQuaternion(o.wMo.linear(), op.orientation);
    op.position_stddev = o.position_stddev;
    op.orientation_stddev = o.orientation_stddev;
    op.contact_refined = o.contact_refined;
    op.pose_decision = static_cast<std::int8_t>(o.pose_decision);
    op.ambiguous = o.ambiguous;
    op.tags_used = o.tags_used;
    op.rms_error_px = o.rms_error_px;
    op.model_tracked = o.model_tracked;
    p.poses.push_back(op);
  };
  add_pose(f.robot_pose, models.robot.id);
  for (std::size_t k = 0; k < f.obstacle_poses.size(); ++k) add_pose(f.obstacle_poses[k], models.obstacles[k].id);
  p.num_poses = static_cast<std::int32_t>(p.poses.size());

  // Robot estimate.
  auto& r = out.robot;
  r.utime = frame.utime;
  r.frame_seq = frame.seq;
  r.valid = f.robot.valid;
  r.position[0] = f.robot.position.x(), r.position[1] = f.robot.position.y();
  r.position_stddev = f.robot.position_stddev;
  r.heading = f.robot.heading;
  if (!f.robot.valid && !robot_lost_reported_) {
    robot_lost_reported_ = true;
    std::string ids;
    for (const auto& t : models.robot.tags) ids += (ids.empty() ? "" : ", ") + std::to_string(t.id);
    out.faults.push_back(Fault(frame.utime, visco::fault_t::CODE_VISION_LOST, visco::fault_t::SEVERITY_ERROR,
                               "robot lost: no usable tag (" + ids + ") in " + Describe(frame)));
  } else if (f.robot.valid && robot_lost_reported_) {
    robot_lost_reported_ = false;
    out.faults.push_back(Fault(frame.utime, visco::fault_t::CODE_VISION_LOST, visco::fault_t::SEVERITY_INFO,
                               "robot seen again in " + Describe(frame), true));
  }

  // Tags inconsistent with the other tags of their object: left out of its pose; reported once, cleared when the tag
  // agrees again.
  auto report_outliers = [&](const ObjectEstimate& o, const std::string& id) {
    if (!o.valid) return;
    std::string inliers;
    for (const TagEstimate& te : o.tags) {
      if (!te.outlier) inliers += (inliers.empty() ? "" : ", ") + std::to_string(te.id);
    }
    for (const TagEstimate& te : o.tags) {
      const auto key = std::make_pair(id, te.id);
      const bool reported = outlier_reported_.count(key) > 0;
      if (te.outlier && !reported) {
        outlier_reported_.insert(key);
        char rms[32];
        std::snprintf(rms, sizeof rms, "%.2f", te.joint_rms_px);
        out.faults.push_back(Fault(frame.utime, visco::fault_t::CODE_VISION_LOST, visco::fault_t::SEVERITY_WARNING,
                                   "tag " + std::to_string(te.id) + " of " + id + " is inconsistent with its tag(s) " +
                                       inliers + " (" + rms + " px RMS at their pose): left out of the pose in " +
                                       Describe(frame)));
      } else if (!te.outlier && reported) {
        outlier_reported_.erase(key);
        out.faults.push_back(
            Fault(frame.utime, visco::fault_t::CODE_VISION_LOST, visco::fault_t::SEVERITY_INFO,
                  "tag " + std::to_string(te.id) + " of " + id + " consistent again in " + Describe(frame), true));
      }
    }
  };
  report_outliers(f.robot_pose, models.robot.id);
  for (std::size_t k = 0; k < f.obstacle_poses.size(); ++k)
    report_outliers(f.obstacle_poses[k], models.obstacles[k].id);

  // Events.
  auto& e = out.events;
  e.frame_utime = frame.utime;
  e.frame_seq = frame.seq;
  for (std::size_t k = 0; k < f.pairs.size(); ++k) {
    const PairMeasurement& pm = f.pairs[k];
    visco::visual_event_t ve{};
    ve.utime = frame.utime;
    ve.cvc_ray = models.events[k].cvc_ray;
    ve.cm_vertex = models.events[k].cm_vertex;
    ve.signed_distance_px = pm.signed_distance_px;
    ve.distance_stddev_px = pm.stddev_px;
    ve.state = static_cast<std::int8_t>(pm.state);
    ve.crossed = pm.crossed;
    e.events.push_back(ve);
  }
  e.num_events = static_cast<std::int32_t>(e.events.size());
  const std::int64_t end = options_.clock ? options_.clock() : NowUtime();
  e.utime = end;
  e.latency_s = static_cast<double>(end - arrival_utime) * 1e-6;

  // Snapshot for the control loop.
  VisionSnapshot& s = out.snapshot;
  s.frame_utime = frame.utime;
  s.frame_seq = frame.seq;
  s.publish_utime = end;
  s.robot_valid = f.robot.valid;
  s.position[0] = f.robot.position.x(), s.position[1] = f.robot.position.y();
  s.position_stddev = f.robot.position_stddev;
  s.heading = f.robot.heading;
  s.num_events = static_cast<std::int32_t>(std::min<std::size_t>(f.pairs.size(), VisionSnapshot::kMaxEvents));
  for (int k = 0; k < s.num_events; ++k) {
    s.events[k] = {f.pairs[k].signed_distance_px, f.pairs[k].stddev_px, static_cast<std::int8_t>(f.pairs[k].state),
                   f.pairs[k].crossed};
  }
  return out;
}

PipelineThread::PipelineThread(std::unique_ptr<FrameSource> source, VisionPipeline& pipeline, lcm::LCM* bus,
                               LatestValue<VisionSnapshot>* latest,
                               std::function<void(const PipelineOutput&)> on_output)
    : source_(std::move(source)), pipeline_(pipeline), bus_(bus), latest_(latest), on_output_(std::move(on_output)) {}

PipelineThread::~PipelineThread() { Stop(); }

void PipelineThread::Start() {
  thread_ = std::thread([this] { Run(); });
}

void PipelineThread::Stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void PipelineThread::Join() {
  if (thread_.joinable()) thread_.join();
}

void PipelineThread::Run() {
  Frame frame;
  std::string error;
  while (!stop_) {
    error.clear();
    const SourceStatus st = source_->Next(frame, error, 100);
    if (st == SourceStatus::kEnd) break;
    if (st == SourceStatus::kNoFrameYet) continue;
    const std::int64_t arrival = NowUtime();
    PipelineOutput out;
    if (st == SourceStatus::kBadFrame) {
      out.faults.push_back(pipeline_.BadFrame(frame, error));
    } else {
      out = pipeline_.Process(frame, arrival);
    }
    if (out.processed) {
      ++frames_;
      if (latest_ != nullptr) latest_->Publish(out.snapshot);
    } else {
      ++bad_frames_;
    }
    if (bus_ != nullptr) {
      ForEachMessage(out, [this](const char* channel, const auto& message) { bus_->publish(channel, &message); });
    }
    if (on_output_) on_output_(out);
    if (on_frame_) on_frame_(frame, out);
  }
  finished_ = true;
}

}  // namespace visco::vision

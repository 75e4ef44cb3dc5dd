#include "vision/overlay.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "common/error.h"
#include "visco/fault_t.hpp"

namespace visco::vision {
namespace {

namespace fs = std::filesystem;
namespace oc = overlay_color;

// Lines and crosses are drawn at sub-pixel positions (OpenCV's fixed-point `shift`), in the calibration's pixel
// convention: (0, 0) is the centre of the top-left pixel.
constexpr int kShift = 4;
constexpr double kOne = 1 << kShift;
constexpr double kFontScale = 0.4;
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr int kLineHeight = 13;

cv::Scalar S(const Bgr& c) { return cv::Scalar(c.b, c.g, c.r); }
cv::Point P(const Eigen::Vector2d& p) {
  return {static_cast<int>(std::lround(p.x() * kOne)), static_cast<int>(std::lround(p.y() * kOne))};
}
cv::Point Pi(const Eigen::Vector2d& p) {
  return {static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y()))};
}
bool Finite(const Eigen::Vector2d& p) { return std::isfinite(p.x()) && std::isfinite(p.y()) && p.norm() < 1e6; }

void Line(cv::Mat& m, const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Bgr& c, int thickness = 1) {
  if (Finite(a) && Finite(b)) cv::line(m, P(a), P(b), S(c), thickness, cv::LINE_8, kShift);
}
void Cross(cv::Mat& m, const Eigen::Vector2d& p, double half, const Bgr& c, int thickness = 1) {
  Line(m, p - Eigen::Vector2d(half, 0), p + Eigen::Vector2d(half, 0), c, thickness);
  Line(m, p - Eigen::Vector2d(0, half), p + Eigen::Vector2d(0, half), c, thickness);
}
void Polygon(cv::Mat& m, const std::vector<Eigen::Vector2d>& pts, const Bgr& c, int thickness = 1) {
  for (std::size_t i = 0; i < pts.size(); ++i) Line(m, pts[i], pts[(i + 1) % pts.size()], c, thickness);
}

// Text with a black outline (readable on any background), cut to the picture's width.
void Text(cv::Mat& m, std::string s, cv::Point org, const Bgr& c) {
  int baseline = 0;
  while (s.size() > 4 && org.x + cv::getTextSize(s, kFont, kFontScale, 1, &baseline).width > m.cols - 2) {
    s = s.substr(0, s.size() - 4) + "...";
  }
  cv::putText(m, s, org, kFont, kFontScale, cv::Scalar(0, 0, 0), 3, cv::LINE_8);
  cv::putText(m, s, org, kFont, kFontScale, S(c), 1, cv::LINE_8);
}

std::string Format(const char* fmt, double a, double b = 0, double c = 0) {
  char buf[128];
  std::snprintf(buf, sizeof buf, fmt, a, b, c);
  return buf;
}

cv::Mat ToBgr(const GrayImageView& image) {
  const cv::Mat gray(image.height, image.width, CV_8UC1, const_cast<std::uint8_t*>(image.data),
                     static_cast<std::size_t>(image.stride));
  cv::Mat bgr;
  cv::cvtColor(gray, bgr, cv::COLOR_GRAY2BGR);
  return bgr;
}

ColorImage FromMat(const cv::Mat& m) {
  ColorImage out;
  out.width = m.cols;
  out.height = m.rows;
  out.bgr.resize(static_cast<std::size_t>(m.cols) * static_cast<std::size_t>(m.rows) * 3);
  for (int v = 0; v < m.rows; ++v) {
    std::copy_n(m.ptr<std::uint8_t>(v), 3 * m.cols, &out.bgr[3 * static_cast<std::size_t>(v) * m.cols]);
  }
  return out;
}

cv::Mat ToMat(const ColorImage& image) {
  return cv::Mat(image.height, image.width, CV_8UC3, const_cast<std::uint8_t*>(image.bgr.data()));
}

// Ideal (undistorted) pixels, where the features live, to the pixels of the picture (as observed).
Eigen::Vector2d IdealToPixel(const CameraModel& camera, const Eigen::Vector2d& ideal) {
  if (camera.distortion == DistortionModel::kNone) return ideal;
  return camera.NormalizedToPixel({(ideal.x() - camera.u0) / camera.px, (ideal.y() - camera.v0) / camera.py});
}

// The detector's corners put pixel centres at +0.5 (docs/vision.md, "Conventions"); the picture's at 0.
Eigen::Vector2d CornerToPixel(const Eigen::Vector2d& c) { return c - Eigen::Vector2d(0.5, 0.5); }

// A 3D segment in the camera frame, sampled so that lens distortion bends it as the camera does.
void Segment3(cv::Mat& m, const CameraModel& camera, const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Bgr& c,
              int thickness = 1) {
  constexpr int kSteps = 8;
  for (int i = 0; i < kSteps; ++i) {
    const Eigen::Vector3d p = a + (b - a) * (double(i) / kSteps), q = a + (b - a) * (double(i + 1) / kSteps);
    if (p.z() <= 1e-6 || q.z() <= 1e-6) continue;
    Line(m, camera.Project(p), camera.Project(q), c, thickness);
  }
}

// A line a u + b v + c = 0 of ideal pixels across the picture (clipped to it, with a margin), through the lens.
void IdealLine(cv::Mat& m, const CameraModel& camera, const Eigen::Vector3d& l, const Bgr& colour) {
  const double n = std::hypot(l.x(), l.y());
  if (!(n > 0)) return;
  const Eigen::Vector2d normal(l.x() / n, l.y() / n), dir(-normal.y(), normal.x());
  const Eigen::Vector2d p0 = -l.z() / n * normal;
  // Liang-Barsky against the picture grown by a margin.
  const double margin = 20, lo[2] = {-margin, -margin}, hi[2] = {m.cols + margin, m.rows + margin};
  double t0 = -1e7, t1 = 1e7;
  for (int k = 0; k < 2; ++k) {
    if (std::abs(dir[k]) < 1e-12) {
      if (p0[k] < lo[k] || p0[k] > hi[k]) return;
      continue;
    }
    double a = (lo[k] - p0[k]) / dir[k], b = (hi[k] - p0[k]) / dir[k];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a), t1 = std::min(t1, b);
  }
  if (t0 >= t1) return;
  constexpr int kSteps = 32;
  for (int i = 0; i < kSteps; ++i) {
    Line(m, IdealToPixel(camera, p0 + (t0 + (t1 - t0) * i / kSteps) * dir),
         IdealToPixel(camera, p0 + (t0 + (t1 - t0) * (i + 1) / kSteps) * dir), colour);
  }
}

std::pair<Eigen::Vector2d, Eigen::Vector2d> Bounds(const std::vector<Eigen::Vector2d>& pts) {
  Eigen::Vector2d lo = pts.front(), hi = pts.front();
  for (const auto& p : pts) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  return {lo, hi};
}

// A tag's border, a cross on corner 0, and its id above the top-left of its bounding box (as ViSP's AprilTag
// example writes it).
void DrawTag(cv::Mat& m, int id, const std::vector<Eigen::Vector2d>& corners, bool used, const std::string& suffix) {
  const Bgr& border = used ? oc::kTag : oc::kTagUnused;
  Polygon(m, corners, border);
  Cross(m, corners[0], 4, border);
  const auto [lo, hi] = Bounds(corners);
  Text(m, "id " + std::to_string(id) + suffix, Pi({lo.x(), lo.y() - 4}), used ? oc::kTagId : oc::kTagUnused);
}

const char* StateWord(SideState s) {
  switch (s) {
    case SideState::kNegative:
      return "negative";
    case SideState::kOnLine:
      return "on the line";
    case SideState::kPositive:
      return "positive";
    default:
      return "unknown";
  }
}

Bgr StateColor(SideState s) {
  switch (s) {
    case SideState::kNegative:
      return oc::kNegative;
    case SideState::kOnLine:
      return oc::kOnLine;
    case SideState::kPositive:
      return oc::kPositive;
    default:
      return {160, 160, 160};
  }
}

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  return s;
}

// The folder a file will be written into must exist and be writable.
void CheckParentFolder(const std::string& path) {
  fs::path parent = fs::path(path).parent_path();
  if (parent.empty()) parent = ".";
  std::error_code ec;
  if (!fs::is_directory(parent, ec)) {
    throw InputError(path, "", "cannot write: folder '" + parent.string() + "' does not exist");
  }
  if (::access(parent.c_str(), W_OK) != 0) {
    throw InputError(path, "", "cannot write: folder '" + parent.string() + "' is not writable");
  }
  if (fs::is_directory(path, ec)) throw InputError(path, "", "cannot write: is a folder");
}

}  // namespace

ColorImage DrawDetectOverlay(const GrayImageView& image, const CameraModel& camera, double tag_size,
                             const DetectResult& result) {
  cv::Mat m = ToBgr(image);
  int without_pose = 0;
  for (const auto& [tag, pose] : result.tags) {
    std::vector<Eigen::Vector2d> corners;
    for (const auto& c : tag.corners) corners.push_back(CornerToPixel(c));
    if (pose) {
      // The tag's frame as vpDisplay::displayFrame draws it: x red, y green, z blue.
      const Eigen::Vector3d o = pose->cMo.translation();
      const double len = tag_size / 2;
      Segment3(m, camera, o, pose->cMo * Eigen::Vector3d(len, 0, 0), {0, 0, 255}, 2);
      Segment3(m, camera, o, pose->cMo * Eigen::Vector3d(0, len, 0), {0, 255, 0}, 2);
      Segment3(m, camera, o, pose->cMo * Eigen::Vector3d(0, 0, len), {255, 0, 0}, 2);
    } else {
      ++without_pose;
    }
    DrawTag(m, tag.id, corners, pose.has_value(), pose ? "" : " (no pose)");
  }
  Text(m,
       std::to_string(result.tags.size() - without_pose) + " tag(s) with a pose, " + std::to_string(without_pose) +
           " without, " + std::to_string(result.rejected_decodes) + " decode(s) rejected",
       {4, kLineHeight}, oc::kText);
  return FromMat(m);
}

void CheckOverlayImagePath(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw InputError(path, "", "cannot write: is a folder");
  const std::string ext = Lower(fs::path(path).extension().string());
  static const char* const kKnown[] = {".png", ".jpg", ".jpeg", ".bmp", ".ppm", ".tif", ".tiff"};
  if (std::none_of(std::begin(kKnown), std::end(kKnown), [&](const char* k) { return ext == k; })) {
    throw InputError(path, "",
                     "unknown picture extension '" + ext + "': use .png (or .jpg, .jpeg, .bmp, .ppm, .tif, .tiff)");
  }
  CheckParentFolder(path);
}

void WriteOverlayImage(const ColorImage& image, const std::string& path) {
  bool ok = false;
  try {
    ok = cv::imwrite(path, ToMat(image));
  } catch (const cv::Exception& e) {
    throw InputError(path, "", std::string("cannot write picture: ") + e.err);
  }
  if (!ok) throw InputError(path, "", "cannot write picture");
}

TrackOverlay::TrackOverlay(const CameraModel& camera, const Eigen::Isometry3d& wMc, const ObjectModels& models)
    : camera_(camera), wMc_(wMc), models_(models), width_(camera.width), height_(camera.height) {}

ColorImage TrackOverlay::Draw(const Frame& frame, const PipelineOutput& out, const FrameFeatures& f) {
  cv::Mat m;
  const bool has_image = out.processed && !frame.image.pixels.empty();
  if (has_image) {
    m = ToBgr(frame.image.view());
    width_ = m.cols, height_ = m.rows;
  } else {
    m = cv::Mat(height_ > 0 ? height_ : 480, width_ > 0 ? width_ : 640, CV_8UC3, cv::Scalar(0, 0, 0));
  }
  int row = 1;
  auto line_y = [&](int r) { return r * kLineHeight; };
  std::string head = "seq " + std::to_string(frame.seq);
  if (!out.processed) {
    Text(m, head + ": frame not processed", {4, line_y(row++)}, oc::kFault);
  } else {
    // What the tracker searched.
    for (const RoiWindow& w : out.roi_windows) {
      cv::rectangle(m, cv::Point(w.x0, w.y0), cv::Point(w.x1 - 1, w.y1 - 1), S(oc::kRoi), 1, cv::LINE_8);
    }
    // The objects' prisms at their estimated poses.
    auto prism = [&](const ObjectModel& model, const ObjectEstimate& e, const Bgr& c) {
      if (!e.valid) return;
      const std::size_t n = model.polygon.size();
      for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Vector2d& a = model.polygon[i];
        const Eigen::Vector2d& b = model.polygon[(i + 1) % n];
        const Eigen::Vector3d a0 = e.cMo * Eigen::Vector3d(a.x(), a.y(), 0),
                              a1 = e.cMo * Eigen::Vector3d(a.x(), a.y(), model.height),
                              b0 = e.cMo * Eigen::Vector3d(b.x(), b.y(), 0),
                              b1 = e.cMo * Eigen::Vector3d(b.x(), b.y(), model.height);
        Segment3(m, camera_, a0, b0, c);
        Segment3(m, camera_, a1, b1, c);
        Segment3(m, camera_, a0, a1, c);
      }
    };
    prism(models_.robot, f.robot_pose, oc::kRobotModel);
    for (std::size_t k = 0; k < f.obstacle_poses.size() && k < models_.obstacles.size(); ++k) {
      prism(models_.obstacles[k], f.obstacle_poses[k], oc::kObstacleModel);
    }
    // VC lines: the line through the images of the bottom and top of each obstacle vertex's vertical edge, for every
    // vertex some event pair watches (drawn once), labelled at the top of the edge.
    std::vector<std::pair<int, int>> drawn;
    for (const EventPair& ep : models_.events) {
      if (ep.obstacle >= static_cast<int>(f.obstacle_poses.size())) continue;
      const ObjectEstimate& o = f.obstacle_poses[static_cast<std::size_t>(ep.obstacle)];
      const std::pair<int, int> key(ep.obstacle, ep.vertex);
      if (!o.valid || std::find(drawn.begin(), drawn.end(), key) != drawn.end()) continue;
      drawn.push_back(key);
      const ObjectModel& model = models_.obstacles[static_cast<std::size_t>(ep.obstacle)];
      const Eigen::Vector2d& v = model.polygon[static_cast<std::size_t>(ep.vertex)];
      const Eigen::Vector3d bottom = o.cMo * Eigen::Vector3d(v.x(), v.y(), 0),
                            top = o.cMo * Eigen::Vector3d(v.x(), v.y(), model.height);
      if (bottom.z() <= 1e-6 || top.z() <= 1e-6) continue;
      const Eigen::Vector2d ib = camera_.ProjectIdeal(bottom), it = camera_.ProjectIdeal(top);
      const Eigen::Vector3d l = Eigen::Vector3d(ib.x(), ib.y(), 1).cross(Eigen::Vector3d(it.x(), it.y(), 1));
      IdealLine(m, camera_, l, oc::kVcLine);
      Segment3(m, camera_, bottom, top, oc::kVcLine, 2);
      Text(m, model.id + ".v" + std::to_string(ep.vertex), Pi(IdealToPixel(camera_, it) + Eigen::Vector2d(6, -6)),
           oc::kVcLine);
    }
    // Tags: used (a pose) or not; lost since the last frame.
    std::map<int, std::vector<Eigen::Vector2d>> now;
    for (const auto& t : out.detections.detections) {
      std::vector<Eigen::Vector2d> corners;
      for (int k = 0; k < 4; ++k) corners.push_back(CornerToPixel({t.corners[k][0], t.corners[k][1]}));
      DrawTag(m, t.id, corners, t.reprojection_error >= 0, "");
      now[t.id] = corners;
    }
    for (int id : out.lost_tags) {
      const auto it = last_tags_.find(id);
      if (it == last_tags_.end()) continue;
      const auto& c = it->second;
      Line(m, c[0], c[2], oc::kLost, 2);
      Line(m, c[1], c[3], oc::kLost, 2);
      const auto [lo, hi] = Bounds(c);
      Text(m, "lost " + std::to_string(id), Pi({lo.x(), hi.y() + 12}), oc::kLost);
    }
    last_tags_ = std::move(now);
    // Distances to the VC lines (a segment to the line's nearest point, coloured by state), CM vertices, events.
    for (std::size_t k = 0; k < f.pairs.size() && k < models_.events.size(); ++k) {
      const PairMeasurement& pm = f.pairs[k];
      if (!pm.valid) continue;
      const Eigen::Vector2d n = pm.vc_line.head<2>();
      const double d = n.dot(pm.cm_image) + pm.vc_line.z();
      const Eigen::Vector2d foot = pm.cm_image - d * n;
      if (pm.state != SideState::kUnknown) {
        Line(m, IdealToPixel(camera_, pm.cm_image), IdealToPixel(camera_, foot), StateColor(pm.state));
      }
    }
    // The crosses over the segments and labels near them.
    for (std::size_t i = 0; i < f.cm_images.size(); ++i) {
      Text(m, "cm" + std::to_string(i), Pi(IdealToPixel(camera_, f.cm_images[i]) + Eigen::Vector2d(4, 12)),
           oc::kCmVertex);
    }
    for (const Eigen::Vector2d& cm : f.cm_images) {
      Cross(m, IdealToPixel(camera_, cm), OverlayMarks::kCmCrossHalf, oc::kCmVertex);
    }
    for (std::size_t k = 0; k < f.pairs.size() && k < models_.events.size(); ++k) {
      const PairMeasurement& pm = f.pairs[k];
      if (!pm.valid || !pm.crossed) continue;
      const Eigen::Vector2d p = IdealToPixel(camera_, pm.cm_image);
      cv::circle(m, P(p), static_cast<int>(OverlayMarks::kEventRadius * kOne), S(oc::kEvent),
                 OverlayMarks::kEventThickness, cv::LINE_8, kShift);
      Text(m, "EVENT " + models_.events[k].cvc_ray + ": " + StateWord(pm.state),
           Pi(p + Eigen::Vector2d(OverlayMarks::kEventRadius + 4, -OverlayMarks::kEventRadius)), oc::kEvent);
    }
    // Status: the frame, the robot, then one line per pair.
    head += out.full_detection ? "  full detection" : "  ROI tracking";
    head += "  tags:";
    for (const auto& t : out.detections.detections) head += " " + std::to_string(t.id);
    std::string missing;
    for (int id : out.expected_ids) {
      if (std::none_of(out.detections.detections.begin(), out.detections.detections.end(),
                       [&](const visco::tag_detection_t& t) { return t.id == id; })) {
        missing += " " + std::to_string(id);
      }
    }
    Text(m, head, {4, line_y(row++)}, oc::kText);
    if (!missing.empty()) Text(m, "expected, not seen:" + missing, {4, line_y(row++)}, oc::kLost);
    if (f.robot.valid) {
      Text(m,
           Format("robot (%.4f, %.4f) m +- %.2f mm", f.robot.position.x(), f.robot.position.y(),
                  f.robot.position_stddev * 1e3) +
               Format(", heading %.1f deg", f.robot.heading * 180 / M_PI),
           {4, line_y(row++)}, oc::kText);
    } else {
      Text(m, "robot not seen", {4, line_y(row++)}, oc::kLost);
    }
    for (std::size_t k = 0; k < f.pairs.size() && k < models_.events.size(); ++k) {
      const PairMeasurement& pm = f.pairs[k];
      std::string s = models_.events[k].cvc_ray + ": ";
      if (pm.valid) {
        s += Format("d %+.2f px (sd %.2f) ", pm.signed_distance_px, pm.stddev_px) + StateWord(pm.state);
      } else {
        s += "unknown (robot or obstacle not seen)";
      }
      if (pm.crossed) s = "EVENT " + s;
      Text(m, s, {4, line_y(row++)}, pm.crossed ? oc::kEvent : StateColor(pm.state));
    }
  }
  // Faults of this pull, at the bottom; a red border when one is not a clearing.
  bool alarm = !out.processed;
  int fault_row = 0;
  for (auto it = out.faults.rbegin(); it != out.faults.rend(); ++it) {
    const bool cleared = it->cleared != 0;
    alarm = alarm || (!cleared && it->severity >= visco::fault_t::SEVERITY_WARNING);
    Text(m, (cleared ? "cleared: " : "FAULT: ") + it->message, {4, m.rows - 6 - kLineHeight * fault_row++},
         cleared ? oc::kCleared : oc::kFault);
  }
  if (alarm) {
    cv::rectangle(m, cv::Point(0, 0), cv::Point(m.cols - 1, m.rows - 1), S(oc::kFault), OverlayMarks::kFaultBorder * 2,
                  cv::LINE_8);
  }
  return FromMat(m);
}

struct OverlayWriter::Impl {
  std::string path;
  bool folder = false;
  int fourcc = 0;
  int api = cv::CAP_ANY;
  double fps = 30;
  cv::VideoWriter video;
  cv::Size size;
  std::int64_t frames = 0;
};

OverlayWriter::OverlayWriter(const std::string& path, double fps) : impl_(std::make_unique<Impl>()) {
  Impl& w = *impl_;
  w.path = path;
  w.fps = fps > 0 ? fps : 30;
  std::error_code ec;
  const std::string ext = Lower(fs::path(path).extension().string());
  const bool trailing_slash = !path.empty() && path.back() == '/';
  if (path.empty()) throw InputError("command line", "--overlay", "needs a file or folder name");
  if (trailing_slash || fs::is_directory(path, ec) || ext.empty()) {
    w.folder = true;
    if (fs::exists(path, ec) && !fs::is_directory(path, ec)) {
      throw InputError(path, "", "cannot write overlay pictures: exists and is not a folder");
    }
    fs::create_directories(path, ec);
    if (ec) throw InputError(path, "", "cannot create overlay folder: " + ec.message());
    if (::access(path.c_str(), W_OK) != 0) throw InputError(path, "", "overlay folder is not writable");
    return;
  }
  if (ext == ".avi" || ext == ".mkv") {
    w.fourcc = cv::VideoWriter::fourcc('M', 'J', 'P', 'G');
    w.api = ext == ".avi" ? cv::CAP_OPENCV_MJPEG : cv::CAP_FFMPEG;
  } else if (ext == ".mp4") {
    w.fourcc = cv::VideoWriter::fourcc('m', 'p', '4', 'v');
    w.api = cv::CAP_FFMPEG;
  } else {
    throw InputError(path, "",
                     "unknown overlay extension '" + ext +
                         "': a video (.avi, .mp4, .mkv) or a folder (no extension) for PNG pictures");
  }
  CheckParentFolder(path);
}

OverlayWriter::~OverlayWriter() { Close(); }

void OverlayWriter::Open(int width, int height) {
  Impl& w = *impl_;
  if (w.folder || w.video.isOpened()) return;
  bool ok = false;
  try {
    ok = w.video.open(w.path, w.api, w.fourcc, w.fps, cv::Size(width, height), true);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok) throw InputError(w.path, "", "OpenCV cannot write this video (no encoder for it, or not writable)");
  w.size = cv::Size(width, height);
}

void OverlayWriter::Write(const ColorImage& image) {
  Impl& w = *impl_;
  const cv::Mat m = ToMat(image);
  if (w.folder) {
    char name[32];
    std::snprintf(name, sizeof name, "%06lld.png", static_cast<long long>(w.frames));
    const std::string file = (fs::path(w.path) / name).string();
    bool ok = false;
    try {
      ok = cv::imwrite(file, m);
    } catch (const cv::Exception&) {
      ok = false;
    }
    if (!ok) throw InputError(file, "", "cannot write overlay picture");
  } else {
    if (!w.video.isOpened()) Open(image.width, image.height);
    if (m.size() == w.size) {
      w.video.write(m);
    } else {
      cv::Mat resized;
      cv::resize(m, resized, w.size);
      w.video.write(resized);
    }
  }
  ++w.frames;
}

void OverlayWriter::Close() {
  if (impl_ && impl_->video.isOpened()) impl_->video.release();
}

std::int64_t OverlayWriter::frames() const { return impl_->frames; }
bool OverlayWriter::is_folder() const { return impl_->folder; }

}  // namespace visco::vision

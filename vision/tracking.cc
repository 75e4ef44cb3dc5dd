#include "vision/tracking.h"

#include <visp3/blob/vpDot2.h>
#include <visp3/core/vpImage.h>
#include <visp3/core/vpTrackingException.h>
#include <visp3/klt/vpKltOpencv.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace visco::vision {
namespace {

void ToViSP(const GrayImageView& in, vpImage<unsigned char>& out) {
  if (static_cast<int>(out.getWidth()) != in.width || static_cast<int>(out.getHeight()) != in.height) {
    out.resize(static_cast<unsigned>(in.height), static_cast<unsigned>(in.width));
  }
  for (int v = 0; v < in.height; ++v) {
    std::memcpy(out[v], in.data + static_cast<std::ptrdiff_t>(v) * in.stride, static_cast<std::size_t>(in.width));
  }
}

cv::Mat ToMat(const GrayImageView& in) {
  return cv::Mat(in.height, in.width, CV_8UC1, const_cast<std::uint8_t*>(in.data), static_cast<std::size_t>(in.stride));
}

}  // namespace

std::vector<Eigen::Vector2d> FindBlobs(const GrayImageView& image, bool bright, double min_area, double max_area,
                                       double min_circularity) {
  std::vector<Eigen::Vector2d> out;
  if (image.empty()) return out;
  cv::Mat bin;
  cv::threshold(ToMat(image), bin, 0, 255, (bright ? cv::THRESH_BINARY : cv::THRESH_BINARY_INV) | cv::THRESH_OTSU);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(bin, contours, cv::RETR_LIST, cv::CHAIN_APPROX_NONE);
  for (const auto& c : contours) {
    const double area = cv::contourArea(c);
    if (area < min_area || area > max_area) continue;
    const double perimeter = cv::arcLength(c, true);
    if (perimeter <= 0 || 4 * M_PI * area / (perimeter * perimeter) < min_circularity) continue;
    const cv::Moments m = cv::moments(c);
    out.emplace_back(m.m10 / m.m00, m.m01 / m.m00);
  }
  return out;
}

struct DotTracker::Impl {
  vpImage<unsigned char> image;
  std::vector<vpDot2> dots;
};

DotTracker::DotTracker() : impl_(std::make_unique<Impl>()) {}
DotTracker::~DotTracker() = default;

void DotTracker::Init(const GrayImageView& image, const std::vector<Eigen::Vector2d>& seeds) {
  ToViSP(image, impl_->image);
  impl_->dots.assign(seeds.size(), vpDot2());
  centers_.assign(seeds.size(), Eigen::Vector2d::Zero());
  alive_.assign(seeds.size(), false);
  for (std::size_t i = 0; i < seeds.size(); ++i) {
    vpDot2& d = impl_->dots[i];
    d.setGraphics(false);
    d.setGrayLevelPrecision(0.8);
    d.setEllipsoidShapePrecision(0.6);
    try {
      d.initTracking(impl_->image, vpImagePoint(seeds[i].y(), seeds[i].x()));
      centers_[i] = {d.getCog().get_u(), d.getCog().get_v()};
      alive_[i] = true;
    } catch (const vpException&) {
      alive_[i] = false;
    }
  }
}

int DotTracker::Track(const GrayImageView& image) {
  ToViSP(image, impl_->image);
  int n = 0;
  for (std::size_t i = 0; i < impl_->dots.size(); ++i) {
    if (!alive_[i]) continue;
    try {
      impl_->dots[i].track(impl_->image);
      centers_[i] = {impl_->dots[i].getCog().get_u(), impl_->dots[i].getCog().get_v()};
      ++n;
    } catch (const vpException&) {
      alive_[i] = false;
    }
  }
  return n;
}

struct KltTracker::Impl {
  vpKltOpencv klt;
};

KltTracker::KltTracker() : KltTracker(Options{}) {}

KltTracker::KltTracker(const Options& o) : impl_(std::make_unique<Impl>()) {
  impl_->klt.setMaxFeatures(o.max_features);
  impl_->klt.setWindowSize(o.window_size);
  impl_->klt.setPyramidLevels(o.pyramid_levels);
  impl_->klt.setQuality(o.quality);
  impl_->klt.setMinDistance(o.min_distance);
  impl_->klt.setHarrisFreeParameter(0.04);
  impl_->klt.setBlockSize(7);
  impl_->klt.setUseHarris(0);
}

KltTracker::~KltTracker() = default;

void KltTracker::InitAuto(const GrayImageView& image) { impl_->klt.initTracking(ToMat(image)); }

void KltTracker::Init(const GrayImageView& image, const std::vector<Eigen::Vector2d>& points) {
  std::vector<cv::Point2f> pts;
  std::vector<long> ids;
  for (std::size_t i = 0; i < points.size(); ++i) {
    pts.emplace_back(static_cast<float>(points[i].x()), static_cast<float>(points[i].y()));
    ids.push_back(static_cast<long>(i));
  }
  impl_->klt.initTracking(ToMat(image), pts, ids);
}

int KltTracker::Track(const GrayImageView& image) {
  if (impl_->klt.getNbFeatures() == 0) return 0;
  impl_->klt.track(ToMat(image));
  return impl_->klt.getNbFeatures();
}

std::vector<Eigen::Vector2d> KltTracker::points() const {
  std::vector<Eigen::Vector2d> out;
  for (const auto& p : impl_->klt.getFeatures()) out.emplace_back(p.x, p.y);
  return out;
}

std::vector<long> KltTracker::ids() const { return impl_->klt.getFeaturesId(); }

struct TagTracker::Impl {
  explicit Impl(const DetectorOptions& d) : detector(d) {
    KltTracker::Options o;
    o.window_size = 9;
    klt = std::make_unique<KltTracker>(o);
  }
  TagDetector detector;
  std::unique_ptr<KltTracker> klt;
  std::vector<TagObservation> klt_tags;  // the tags whose corners KLT follows, in id order
};

TagTracker::TagTracker(const DetectorOptions& detector, const TagTrackerOptions& options)
    : impl_(std::make_unique<Impl>(detector)), options_(options) {}

TagTracker::~TagTracker() = default;

namespace {

struct Window {
  int x0, y0, x1, y1;  // [x0, x1) x [y0, y1), clipped to the image
  double min_side_px;  // smallest predicted tag side inside
  long Area() const { return static_cast<long>(x1 - x0) * (y1 - y0); }
};

Window Union(const Window& a, const Window& b) {
  return {std::min(a.x0, b.x0), std::min(a.y0, b.y0), std::max(a.x1, b.x1), std::max(a.y1, b.y1),
          std::min(a.min_side_px, b.min_side_px)};
}

bool Overlap(const Window& a, const Window& b) { return a.x0 < b.x1 && b.x0 < a.x1 && a.y0 < b.y1 && b.y0 < a.y1; }

}  // namespace

std::vector<TagObservation> TagTracker::DetectInWindows(const GrayImageView& image) {
  std::vector<Window> windows;
  for (const auto& prev : last_) {
    // Constant-velocity prediction: the tag's mean corner motion between the last two frames.
    Eigen::Vector2d motion = Eigen::Vector2d::Zero();
    for (const auto& before : before_last_) {
      if (before.id != prev.id) continue;
      for (int k = 0; k < 4; ++k) motion += (prev.corners[k] - before.corners[k]) / 4;
    }
    double umin = 1e18, umax = -1e18, vmin = 1e18, vmax = -1e18, side = 1e18;
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector2d c = prev.corners[k] + motion;
      umin = std::min(umin, c.x()), umax = std::max(umax, c.x());
      vmin = std::min(vmin, c.y()), vmax = std::max(vmax, c.y());
      side = std::min(side, (prev.corners[(k + 1) % 4] - prev.corners[k]).norm());
    }
    const double mu = options_.roi_margin * (umax - umin) + 8, mv = options_.roi_margin * (vmax - vmin) + 8;
    Window w{static_cast<int>(std::floor(umin - mu)), static_cast<int>(std::floor(vmin - mv)),
             static_cast<int>(std::ceil(umax + mu)), static_cast<int>(std::ceil(vmax + mv)), side};
    w.x0 = std::clamp(w.x0, 0, image.width), w.x1 = std::clamp(w.x1, 0, image.width);
    w.y0 = std::clamp(w.y0, 0, image.height), w.y1 = std::clamp(w.y1, 0, image.height);
    if (w.x1 > w.x0 && w.y1 > w.y0) windows.push_back(w);
  }
  // Merge overlapping windows while the merged one costs no more pixels than the two it replaces.
  for (bool merged = options_.merge_windows; merged;) {
    merged = false;
    for (std::size_t i = 0; i < windows.size() && !merged; ++i) {
      for (std::size_t j = i + 1; j < windows.size() && !merged; ++j) {
        const Window u = Union(windows[i], windows[j]);
        if (Overlap(windows[i], windows[j]) && u.Area() <= windows[i].Area() + windows[j].Area()) {
          windows[i] = u;
          windows.erase(windows.begin() + static_cast<std::ptrdiff_t>(j));
          merged = true;
        }
      }
    }
  }
  std::vector<TagObservation> now;
  for (const Window& w : windows) {
    const float decimate =
        options_.decimate_min_side_px > 0 && w.min_side_px >= options_.decimate_min_side_px ? 2.0f : 1.0f;
    windows_.push_back({w.x0, w.y0, w.x1, w.y1, decimate > 1.0f});
    for (auto& t : impl_->detector.DetectInRegion(image, w.x0, w.y0, w.x1 - w.x0, w.y1 - w.y0, decimate)) {
      // Only the tracked tags (new ones are found by the next full detection); a tag seen in two windows once. A tag
      // cut by the window's edge (not the image's) can decode with wrong corners (measured: 4.3 px off on
      // AprilTag.pgm with one window per tag): it is taken from the window that holds it whole.
      const bool tracked =
          std::any_of(last_.begin(), last_.end(), [&](const TagObservation& p) { return p.id == t.id; });
      const bool seen = std::any_of(now.begin(), now.end(), [&](const TagObservation& p) { return p.id == t.id; });
      constexpr double kClearance = 2.0;
      const bool whole = std::all_of(t.corners.begin(), t.corners.end(), [&](const Eigen::Vector2d& c) {
        return (w.x0 == 0 || c.x() >= w.x0 + kClearance) && (w.y0 == 0 || c.y() >= w.y0 + kClearance) &&
               (w.x1 == image.width || c.x() <= w.x1 - kClearance) &&
               (w.y1 == image.height || c.y() <= w.y1 - kClearance);
      });
      if (tracked && !seen && whole) now.push_back(std::move(t));
    }
  }
  return now;
}

std::vector<TagObservation> TagTracker::Process(const GrayImageView& image, bool* full_detection) {
  lost_.clear();
  windows_.clear();
  bool missing = false;
  for (int id : options_.expected_ids) {
    missing = missing || std::none_of(last_.begin(), last_.end(), [&](const TagObservation& t) { return t.id == id; });
  }
  const bool full = options_.mode == TagTrackingMode::kDetectEveryFrame || since_full_ < 0 || last_.empty() ||
                    missing || since_full_ + 1 >= std::max(1, options_.full_detection_every);
  std::vector<TagObservation> now;
  if (full) {
    now = impl_->detector.Detect(image);
    since_full_ = 0;
    if (options_.mode == TagTrackingMode::kKltCorners) {
      std::vector<Eigen::Vector2d> pts;
      for (const auto& t : now) {
        for (const auto& c : t.corners) pts.push_back(c - Eigen::Vector2d(0.5, 0.5));  // to OpenCV's convention
      }
      impl_->klt->Init(image, pts);
      impl_->klt_tags = now;
    }
  } else {
    ++since_full_;
    if (options_.mode == TagTrackingMode::kRoiDetection || options_.mode == TagTrackingMode::kModelBased) {
      now = DetectInWindows(image);
    } else {
      impl_->klt->Track(image);
      const auto pts = impl_->klt->points();
      const auto ids = impl_->klt->ids();
      std::map<long, Eigen::Vector2d> by_id;
      for (std::size_t i = 0; i < ids.size(); ++i) by_id[ids[i]] = pts[i] + Eigen::Vector2d(0.5, 0.5);
      for (std::size_t t = 0; t < impl_->klt_tags.size(); ++t) {
        TagObservation o = impl_->klt_tags[t];
        bool all = true;
        for (int k = 0; k < 4; ++k) {
          const auto it = by_id.find(static_cast<long>(4 * t + k));
          if (it == by_id.end()) {
            all = false;
            break;
          }
          o.corners[k] = it->second;
        }
        if (!all) continue;
        o.decision_margin = 0;
        // A tracked quad must stay a convex, counter-clockwise-consistent quadrilateral; otherwise KLT slipped.
        double sign = 0;
        bool convex = true;
        for (int k = 0; k < 4; ++k) {
          const Eigen::Vector2d a = o.corners[(k + 1) % 4] - o.corners[k],
                                b = o.corners[(k + 2) % 4] - o.corners[(k + 1) % 4];
          const double cr = a.x() * b.y() - a.y() * b.x();
          if (sign == 0) sign = cr;
          convex = convex && cr * sign > 0;
        }
        if (convex) now.push_back(std::move(o));
      }
    }
  }
  std::sort(now.begin(), now.end(), [](const TagObservation& a, const TagObservation& b) { return a.id < b.id; });
  for (const auto& prev : last_) {
    if (std::none_of(now.begin(), now.end(), [&](const TagObservation& t) { return t.id == prev.id; })) {
      lost_.push_back(prev.id);
    }
  }
  if (!lost_.empty()) since_full_ = -1;  // look for lost tags in the whole next frame
  if (full_detection != nullptr) *full_detection = full;
  before_last_ = std::move(last_);
  last_ = now;
  return now;
}

}  // namespace visco::vision

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

std::vector<TagObservation> TagTracker::Process(const GrayImageView& image, bool* full_detection) {
  lost_.clear();
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
    if (options_.mode == TagTrackingMode::kRoiDetection) {
      for (const auto& prev : last_) {
        double umin = 1e18, umax = -1e18, vmin = 1e18, vmax = -1e18;
        for (const auto& c : prev.corners) {
          umin = std::min(umin, c.x()), umax = std::max(umax, c.x());
          vmin = std::min(vmin, c.y()), vmax = std::max(vmax, c.y());
        }
        const double mu = options_.roi_margin * (umax - umin) + 8, mv = options_.roi_margin * (vmax - vmin) + 8;
        const int x0 = static_cast<int>(std::floor(umin - mu)), y0 = static_cast<int>(std::floor(vmin - mv));
        const int x1 = static_cast<int>(std::ceil(umax + mu)), y1 = static_cast<int>(std::ceil(vmax + mv));
        for (auto& t : impl_->detector.DetectInRegion(image, x0, y0, x1 - x0, y1 - y0)) {
          if (t.id == prev.id) {
            now.push_back(std::move(t));
            break;
          }
        }
      }
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
  last_ = now;
  return now;
}

}  // namespace visco::vision

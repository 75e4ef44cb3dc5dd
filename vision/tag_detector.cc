#include "vision/tag_detector.h"

#include <apriltag/apriltag.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagStandard41h12.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "common/error.h"
#include "vision/contact_refinement.h"
#include "vision/tag_renderer.h"

namespace visco::vision {
namespace {

struct FamilyEntry {
  const char* name;
  apriltag_family_t* (*create)();
  void (*destroy)(apriltag_family_t*);
};

constexpr FamilyEntry kFamilies[] = {
    {"tag36h11", tag36h11_create, tag36h11_destroy},
    {"tag25h9", tag25h9_create, tag25h9_destroy},
    {"tag16h5", tag16h5_create, tag16h5_destroy},
    {"tagStandard41h12", tagStandard41h12_create, tagStandard41h12_destroy},
    {"tagCircle21h7", tagCircle21h7_create, tagCircle21h7_destroy},
};

const FamilyEntry* FindFamily(const std::string& name) {
  for (const auto& f : kFamilies) {
    if (name == f.name) return &f;
  }
  return nullptr;
}

Eigen::Matrix3d ExpSo3(const Eigen::Vector3d& w) {
  const double a = w.norm();
  if (a < 1e-12) return Eigen::Matrix3d::Identity() + Skew(w);
  return Eigen::AngleAxisd(a, w / a).toRotationMatrix();
}

using Vec8 = Eigen::Matrix<double, 8, 1>;
using Mat86 = Eigen::Matrix<double, 8, 6>;

// Residuals (projected minus observed, ideal pixels) and their Jacobian for a left perturbation (dw, dt).
void Residuals(const CameraModel& cam, const std::array<Eigen::Vector3d, 4>& obj,
               const std::array<Eigen::Vector2d, 4>& ideal, const Eigen::Isometry3d& cMo, Vec8& r, Mat86* jac) {
  for (int i = 0; i < 4; ++i) {
    Eigen::Vector2d ri;
    Eigen::Matrix<double, 2, 6> ji;
    ReprojectPoint(cam, cMo, obj[i], ideal[i], ri, jac != nullptr ? &ji : nullptr);
    r.segment<2>(2 * i) = ri;
    if (jac != nullptr) jac->block<2, 6>(2 * i, 0) = ji;
  }
}

// Levenberg-Marquardt on the reprojection error; returns the RMS error in pixels.
double Refine(const CameraModel& cam, const std::array<Eigen::Vector3d, 4>& obj,
              const std::array<Eigen::Vector2d, 4>& ideal, Eigen::Isometry3d& cMo) {
  Vec8 r;
  Mat86 j;
  Residuals(cam, obj, ideal, cMo, r, &j);
  double cost = r.squaredNorm();
  double lambda = 1e-3;
  for (int it = 0; it < 50; ++it) {
    const Eigen::Matrix<double, 6, 6> jtj = j.transpose() * j;
    const Eigen::Matrix<double, 6, 1> g = j.transpose() * r;
    Eigen::Matrix<double, 6, 6> a = jtj;
    a.diagonal() += lambda * jtj.diagonal().cwiseMax(1e-12);
    const Eigen::Matrix<double, 6, 1> step = -a.ldlt().solve(g);
    Eigen::Isometry3d next = cMo;
    next.linear() = ExpSo3(step.head<3>()) * cMo.linear();
    next.translation() += step.tail<3>();
    Vec8 rn;
    Residuals(cam, obj, ideal, next, rn, nullptr);
    const double next_cost = rn.squaredNorm();
    if (next_cost < cost && std::isfinite(next_cost) && next.translation().z() > 0) {
      const double gain = cost - next_cost;
      cMo = next;
      cost = next_cost;
      Residuals(cam, obj, ideal, cMo, r, &j);
      lambda = std::max(lambda * 0.3, 1e-9);
      if (gain < 1e-14 * (1 + cost) || step.norm() < 1e-13) break;
    } else {
      lambda *= 10;
      if (lambda > 1e8) break;
    }
  }
  // Re-orthonormalise the rotation (exp keeps it orthonormal, this removes accumulated rounding).
  Eigen::Quaterniond q(cMo.linear());
  cMo.linear() = q.normalized().toRotationMatrix();
  return std::sqrt(cost / 4);
}

double RotationDistance(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle();
}

}  // namespace

TagBitmap MakeTagBitmap(const std::string& family_name, int id) {
  CheckFamilyName(family_name);
  const FamilyEntry* entry = FindFamily(family_name);
  apriltag_family_t* fam = entry->create();
  if (id < 0 || static_cast<std::uint32_t>(id) >= fam->ncodes) {
    const int n = static_cast<int>(fam->ncodes);
    entry->destroy(fam);
    throw InputError("tag", family_name + " id " + std::to_string(id),
                     "not in the family (ids 0.." + std::to_string(n - 1) + ")");
  }
  TagBitmap b;
  b.total_width = fam->total_width;
  b.width_at_border = fam->width_at_border;
  b.cells.assign(static_cast<std::size_t>(b.total_width) * b.total_width, 0);
  // The white ring just outside the black border (inside it for reversed-border families), then the code bits at
  // the family's bit positions, counted from the black border's outer corner; the most significant bit is bit 0.
  const int white_width = fam->width_at_border + (fam->reversed_border ? 0 : 2);
  const int white_start = (fam->total_width - white_width) / 2;
  for (int i = 0; i < white_width - 1; ++i) {
    const int lo = white_start, hi = white_start + white_width - 1;
    b.cells[static_cast<std::size_t>(lo) * b.total_width + lo + i] = 255;
    b.cells[static_cast<std::size_t>(lo + i) * b.total_width + hi] = 255;
    b.cells[static_cast<std::size_t>(hi) * b.total_width + hi - i] = 255;
    b.cells[static_cast<std::size_t>(hi - i) * b.total_width + lo] = 255;
  }
  const int border_start = (fam->total_width - fam->width_at_border) / 2;
  const std::uint64_t code = fam->codes[id];
  for (std::uint32_t i = 0; i < fam->nbits; ++i) {
    if ((code >> (fam->nbits - i - 1)) & 1u) {
      b.cells[static_cast<std::size_t>(fam->bit_y[i] + border_start) * b.total_width + fam->bit_x[i] + border_start] =
          255;
    }
  }
  entry->destroy(fam);
  return b;
}

void CheckFamilyName(const std::string& family) {
  if (FindFamily(family) == nullptr) {
    std::string names;
    for (const auto& f : kFamilies) names += std::string(names.empty() ? "" : ", ") + f.name;
    throw InputError("command line", "--family", "unknown tag family '" + family + "' (known: " + names + ")");
  }
}

struct TagDetector::Impl {
  const FamilyEntry* entry = nullptr;
  apriltag_family_t* family = nullptr;
  apriltag_detector_t* detector = nullptr;
  int rejected = 0;
  std::vector<std::uint8_t> scratch;
  ~Impl() {
    if (detector != nullptr) apriltag_detector_destroy(detector);
    if (family != nullptr) entry->destroy(family);
  }
};

TagDetector::TagDetector(const DetectorOptions& options) : options_(options), impl_(std::make_unique<Impl>()) {
  CheckFamilyName(options.family);
  if (options.quad_decimate < 1.0f) throw InputError("command line", "quad_decimate", "must be >= 1");
  if (options.threads < 1) throw InputError("command line", "threads", "must be >= 1");
  impl_->entry = FindFamily(options.family);
  impl_->family = impl_->entry->create();
  impl_->detector = apriltag_detector_create();
  // Hamming corrections beyond max_hamming are rejected anyway; decoding fewer bits also saves memory and time.
  apriltag_detector_add_family_bits(impl_->detector, impl_->family, std::max(0, std::min(options.max_hamming, 2)));
  impl_->detector->quad_decimate = options.quad_decimate;
  impl_->detector->quad_sigma = options.quad_sigma;
  impl_->detector->nthreads = options.threads;
  impl_->detector->decode_sharpening = options.decode_sharpening;
  impl_->detector->refine_edges = true;
}

TagDetector::~TagDetector() = default;

int TagDetector::rejected_last() const { return impl_->rejected; }

std::vector<TagObservation> TagDetector::Detect(const GrayImageView& image) {
  return DetectInRegion(image, 0, 0, image.width, image.height);
}

std::vector<TagObservation> TagDetector::DetectInRegion(const GrayImageView& image, int x0, int y0, int w, int h,
                                                        float quad_decimate) {
  impl_->rejected = 0;
  const float decimate = quad_decimate > 0.0f ? std::max(1.0f, quad_decimate) : options_.quad_decimate;
  impl_->detector->quad_decimate = decimate;
  std::vector<TagObservation> out;
  if (image.empty()) return out;
  const int xa = std::clamp(x0, 0, image.width), ya = std::clamp(y0, 0, image.height);
  const int xb = std::clamp(x0 + w, 0, image.width), yb = std::clamp(y0 + h, 0, image.height);
  if (xb - xa < 8 || yb - ya < 8) return out;
  // Zero-copy wrap of the region. The library blurs its input in place when quad_sigma != 0 at full resolution
  // (measured: repeated detections on one image degraded it until no tag was found), so then the region is copied
  // into a scratch buffer owned by the detector.
  const int rw = xb - xa, rh = yb - ya;
  const std::uint8_t* origin = image.data + static_cast<std::ptrdiff_t>(ya) * image.stride + xa;
  const bool copy = options_.quad_sigma != 0.0f && decimate <= 1.0f;
  if (copy) {
    impl_->scratch.resize(static_cast<std::size_t>(rw) * static_cast<std::size_t>(rh));
    for (int v = 0; v < rh; ++v) {
      std::copy_n(origin + static_cast<std::ptrdiff_t>(v) * image.stride, rw,
                  impl_->scratch.data() + std::size_t(v) * rw);
    }
  }
  image_u8_t im{rw, rh, copy ? rw : image.stride, copy ? impl_->scratch.data() : const_cast<std::uint8_t*>(origin)};
  zarray_t* dets = apriltag_detector_detect(impl_->detector, &im);
  for (int i = 0; i < zarray_size(dets); ++i) {
    apriltag_detection_t* d = nullptr;
    zarray_get(dets, i, &d);
    if (d->decision_margin < options_.min_decision_margin || d->hamming > options_.max_hamming) {
      ++impl_->rejected;
      continue;
    }
    TagObservation o;
    o.family = options_.family;
    o.id = d->id;
    o.decision_margin = d->decision_margin;
    o.hamming = d->hamming;
    for (int k = 0; k < 4; ++k) o.corners[k] = {d->p[k][0] + xa, d->p[k][1] + ya};
    if (decimate > 1.0f) RefineCorners(image, o.corners, decimate, 2);
    out.push_back(std::move(o));
  }
  apriltag_detections_destroy(dets);
  std::sort(out.begin(), out.end(), [](const TagObservation& a, const TagObservation& b) { return a.id < b.id; });
  return out;
}

namespace {

// Grey level at a continuous point, bilinear, pixel centres at +0.5 (the AprilTag library's convention). False outside.
bool Sample(const GrayImageView& im, const Eigen::Vector2d& p, double* value) {
  const double fx = p.x() - 0.5, fy = p.y() - 0.5;
  const double x0 = std::floor(fx), y0 = std::floor(fy);
  if (!(x0 >= 0 && y0 >= 0 && x0 + 1 < im.width && y0 + 1 < im.height)) return false;
  const double ax = fx - x0, ay = fy - y0;
  const std::uint8_t* r0 = im.data + static_cast<std::ptrdiff_t>(y0) * im.stride + static_cast<std::ptrdiff_t>(x0);
  const std::uint8_t* r1 = r0 + im.stride;
  *value = (1 - ay) * ((1 - ax) * r0[0] + ax * r0[1]) + ay * ((1 - ax) * r1[0] + ax * r1[1]);
  return true;
}

// Locates the edge from corner a to corner b; returns the fitted line as (point, unit direction).
bool FitEdge(const GrayImageView& im, const Eigen::Vector2d& a, const Eigen::Vector2d& b, double range,
             Eigen::Vector2d* point, Eigen::Vector2d* dir) {
  constexpr double kStep = 0.25;  // profile resolution along the normal, pixels
  constexpr int kHalf = 4;        // gradient = I(t + 1 px) - I(t - 1 px)
  constexpr int kMaxProfile = 128;
  const double len = (b - a).norm();
  const int nt = static_cast<int>(std::floor(range / kStep));
  const int np = 2 * (nt + kHalf) + 1;  // profile samples
  if (!(len > 4 * range) || np > kMaxProfile) return false;
  const Eigen::Vector2d d = (b - a) / len, n(d.y(), -d.x());
  // Samples about two pixels apart, away from the corners (the other edges' contrast is within `range` of them).
  const double margin = range + 1;
  const int ns = std::max(8, static_cast<int>((len - 2 * margin) / 2));
  double profile[kMaxProfile];
  double sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0, sw = 0;
  double sign = 0;
  for (int pass = 0; pass < 2; ++pass) {  // pass 0: the border's contrast sign; pass 1: the edge points
    for (int s = 0; s < ns; ++s) {
      const Eigen::Vector2d p0 = a + d * (margin + (len - 2 * margin) * (s + 0.5) / ns);
      bool ok = true;
      for (int i = 0; i < np && ok; ++i) ok = Sample(im, p0 + ((i - nt - kHalf) * kStep) * n, &profile[i]);
      if (!ok) continue;
      double wsum = 0, tsum = 0;
      for (int t = -nt; t <= nt; ++t) {
        const double g = profile[t + nt + 2 * kHalf] - profile[t + nt];
        if (pass == 0) {
          sign += g;
          continue;
        }
        // The border's contrast has one sign along the whole edge (dark inside for most families); inner bit edges
        // and clutter of the other sign are ignored.
        const double v = sign >= 0 ? g : -g;
        if (v <= 0) continue;
        wsum += v * v;
        tsum += v * v * t * kStep;
      }
      if (pass == 0 || wsum <= 0) continue;
      const Eigen::Vector2d p = p0 + (tsum / wsum) * n;
      sx += p.x(), sy += p.y(), sxx += p.x() * p.x(), sxy += p.x() * p.y(), syy += p.y() * p.y(), sw += 1;
    }
  }
  if (sw < 4) return false;
  const Eigen::Vector2d mean(sx / sw, sy / sw);
  Eigen::Matrix2d cov;
  cov << sxx / sw - mean.x() * mean.x(), sxy / sw - mean.x() * mean.y(), sxy / sw - mean.x() * mean.y(),
      syy / sw - mean.y() * mean.y();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
  *point = mean;
  *dir = eig.eigenvectors().col(1);
  return true;
}

}  // namespace

bool RefineCorners(const GrayImageView& image, Corners& corners, double range_px, int passes) {
  if (image.empty()) return false;
  Corners c = corners;
  double range = std::max(1.0, range_px);
  for (int pass = 0; pass < passes; ++pass, range = std::max(1.0, range / 2)) {
    std::array<Eigen::Vector2d, 4> p, d;
    for (int k = 0; k < 4; ++k) {
      if (!FitEdge(image, c[k], c[(k + 1) % 4], range, &p[k], &d[k])) return false;
    }
    // Corner k is where edge k-1 (corner k-1 to k) meets edge k (corner k to k+1).
    for (int k = 0; k < 4; ++k) {
      const int e = (k + 3) % 4;
      Eigen::Matrix2d m;
      m.col(0) = d[e];
      m.col(1) = -d[k];
      if (std::abs(m.determinant()) < 1e-3) return false;
      const Eigen::Vector2d st = m.inverse() * (p[k] - p[e]);
      c[k] = p[e] + st.x() * d[e];
    }
  }
  for (const auto& q : c) {
    if (!q.allFinite()) return false;
  }
  corners = c;
  return true;
}

bool ReprojectPoint(const CameraModel& camera, const Eigen::Isometry3d& cMo, const Eigen::Vector3d& point_o,
                    const Eigen::Vector2d& ideal, Eigen::Vector2d& residual, Eigen::Matrix<double, 2, 6>* jacobian) {
  const Eigen::Vector3d rx = cMo.linear() * point_o;
  const Eigen::Vector3d c = rx + cMo.translation();
  const double iz = 1.0 / c.z();
  residual =
      Eigen::Vector2d(camera.u0 + camera.px * c.x() * iz - ideal.x(), camera.v0 + camera.py * c.y() * iz - ideal.y());
  if (jacobian != nullptr) {
    Eigen::Matrix<double, 2, 3> dproj;
    dproj << camera.px * iz, 0, -camera.px * c.x() * iz * iz, 0, camera.py * iz, -camera.py * c.y() * iz * iz;
    Eigen::Matrix<double, 3, 6> dp;
    dp.leftCols<3>() = -Skew(rx);
    dp.rightCols<3>() = Eigen::Matrix3d::Identity();
    *jacobian = dproj * dp;
  }
  return c.z() > 0;
}

std::array<Eigen::Vector3d, 4> TagCornersInTagFrame(double s) {
  const double h = s / 2;
  return {Eigen::Vector3d(-h, -h, 0), Eigen::Vector3d(h, -h, 0), Eigen::Vector3d(h, h, 0), Eigen::Vector3d(-h, h, 0)};
}

double ReprojectionRms(const CameraModel& camera, const Corners& corners, double tag_size, const Eigen::Isometry3d& cMo,
                       double corner_offset_px) {
  std::array<Eigen::Vector2d, 4> ideal;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d c = corners[i] - Eigen::Vector2d::Constant(corner_offset_px);
    ideal[i] = camera.NormalizedToIdealPixel(camera.PixelToNormalized(c));
  }
  Vec8 r;
  Residuals(camera, TagCornersInTagFrame(tag_size), ideal, cMo, r, nullptr);
  return std::sqrt(r.squaredNorm() / 4);
}

std::optional<TagPose> EstimateTagPose(const CameraModel& camera, const Corners& corners, double tag_size,
                                       const PoseOptions& options, const std::optional<Eigen::Isometry3d>& prior_cMo,
                                       const std::optional<Eigen::Vector3d>& expected_normal_c) {
  if (!(tag_size > 0)) return std::nullopt;
  std::array<Eigen::Vector2d, 4> ideal;
  for (int i = 0; i < 4; ++i) {
    if (!corners[i].allFinite()) return std::nullopt;
    const Eigen::Vector2d c = corners[i] - Eigen::Vector2d::Constant(options.corner_offset_px);
    ideal[i] = camera.NormalizedToIdealPixel(camera.PixelToNormalized(c));
  }
  // Degenerate quad (collinear or tiny): no pose.
  double area = 0;
  for (int i = 0; i < 4; ++i) {
    const auto& a = ideal[i];
    const auto& b = ideal[(i + 1) % 4];
    area += a.x() * b.y() - a.y() * b.x();
  }
  if (std::abs(area) / 2 < 4.0) return std::nullopt;

  // IPPE for squares wants the points in its own order and frame: (-h, h), (h, h), (h, -h), (-h, -h), which is the
  // AprilTag library's tag frame (y down, z into the tag). ViSP's frame is that frame turned by Rx(pi).
  const double h = tag_size / 2;
  const std::vector<cv::Point3d> obj{{-h, h, 0}, {h, h, 0}, {h, -h, 0}, {-h, -h, 0}};
  std::vector<cv::Point2d> img;
  for (const auto& p : ideal) img.emplace_back(p.x(), p.y());
  const cv::Matx33d k(camera.px, 0, camera.u0, 0, camera.py, camera.v0, 0, 0, 1);
  std::vector<cv::Mat> rvecs, tvecs;
  try {
    cv::solvePnPGeneric(obj, img, k, cv::noArray(), rvecs, tvecs, false, cv::SOLVEPNP_IPPE_SQUARE);
  } catch (const cv::Exception&) {
    return std::nullopt;
  }
  const auto obj_visp = TagCornersInTagFrame(tag_size);
  Eigen::Matrix3d rx_pi = Eigen::Matrix3d::Identity();
  rx_pi(1, 1) = rx_pi(2, 2) = -1;
  std::vector<PoseCandidate> cands;
  for (std::size_t s = 0; s < rvecs.size(); ++s) {
    cv::Matx33d rcv;
    cv::Rodrigues(rvecs[s], rcv);
    Eigen::Isometry3d cMo = Eigen::Isometry3d::Identity();
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) cMo.linear()(a, b) = rcv(a, b);
      cMo.translation()[a] = tvecs[s].at<double>(a);
    }
    cMo.linear() = cMo.linear() * rx_pi;
    if (!cMo.matrix().allFinite() || cMo.translation().z() <= 0) continue;
    PoseCandidate c;
    c.cMo = cMo;
    c.rms_error_px = Refine(camera, obj_visp, ideal, c.cMo);
    // Both starts may converge to the same minimum: keep distinct solutions only.
    bool same = false;
    for (const auto& o : cands) {
      same = same || (RotationDistance(o.cMo.linear(), c.cMo.linear()) < 1e-6 &&
                      (o.cMo.translation() - c.cMo.translation()).norm() < 1e-9);
    }
    if (!same) cands.push_back(c);
  }
  if (cands.empty()) return std::nullopt;
  std::sort(cands.begin(), cands.end(),
            [](const PoseCandidate& a, const PoseCandidate& b) { return a.rms_error_px < b.rms_error_px; });
  if (cands[0].rms_error_px > options.max_rms_error_px) return std::nullopt;

  std::size_t chosen = 0;
  TagPose out;
  if (cands.size() > 1) {
    const double ssr_excess =
        4 * (cands[1].rms_error_px * cands[1].rms_error_px - cands[0].rms_error_px * cands[0].rms_error_px);
    const bool ambiguous =
        ssr_excess < 2 * std::log(1 / options.ambiguity_alpha) * options.corner_noise_px * options.corner_noise_px;
    out.ambiguous = ambiguous;
    if (ambiguous && prior_cMo) {
      chosen = RotationDistance(cands[1].cMo.linear(), prior_cMo->linear()) <
                       RotationDistance(cands[0].cMo.linear(), prior_cMo->linear())
                   ? 1
                   : 0;
    } else if (ambiguous && expected_normal_c) {
      const Eigen::Vector3d n = expected_normal_c->normalized();
      chosen = cands[1].cMo.linear().col(2).dot(n) > cands[0].cMo.linear().col(2).dot(n) ? 1 : 0;
    }
    out.alternative = cands[1 - chosen];
  }
  out.cMo = cands[chosen].cMo;
  out.rms_error_px = cands[chosen].rms_error_px;
  Vec8 r;
  Mat86 j;
  Residuals(camera, obj_visp, ideal, out.cMo, r, &j);
  const Eigen::Matrix<double, 6, 6> jtj = j.transpose() * j;
  out.unit_covariance = jtj.ldlt().solve(Eigen::Matrix<double, 6, 6>::Identity());
  return out;
}

}  // namespace visco::vision

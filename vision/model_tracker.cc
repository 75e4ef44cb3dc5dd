#include "vision/model_tracker.h"

#include <unistd.h>
#include <visp3/core/vpCameraParameters.h>
#include <visp3/core/vpException.h>
#include <visp3/core/vpHomogeneousMatrix.h>
#include <visp3/core/vpImage.h>
#include <visp3/mbt/vpMbGenericTracker.h>
#include <visp3/me/vpMe.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "common/error.h"
#include "vision/contact_refinement.h"

namespace visco::vision {
namespace {

vpHomogeneousMatrix ToViSP(const Eigen::Isometry3d& m) {
  vpHomogeneousMatrix out;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out[r][c] = m.linear()(r, c);
    out[r][3] = m.translation()(r);
  }
  return out;
}

Eigen::Isometry3d FromViSP(const vpHomogeneousMatrix& m) {
  Eigen::Matrix4d a;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) a(r, c) = m[r][c];
  }
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  // Re-orthonormalised: ViSP's exponential-map updates leave rounding in the rotation.
  const Eigen::Quaterniond q(Eigen::Matrix3d(a.topLeftCorner<3, 3>()));
  out.linear() = q.normalized().toRotationMatrix();
  out.translation() = a.topRightCorner<3, 1>();
  return out;
}

double SignedArea(const std::vector<Eigen::Vector2d>& p) {
  double a = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Eigen::Vector2d& u = p[i];
    const Eigen::Vector2d& v = p[(i + 1) % p.size()];
    a += u.x() * v.y() - v.x() * u.y();
  }
  return 0.5 * a;
}

}  // namespace

std::string PrismCao(const ObjectModel& prism) {
  std::vector<Eigen::Vector2d> poly = prism.polygon;
  if (SignedArea(poly) < 0) std::reverse(poly.begin(), poly.end());  // counter-clockwise seen from above
  const std::size_t n = poly.size();
  std::ostringstream s;
  s.precision(17);
  s << "V1\n# 3D Points\n" << 2 * n << "\n";
  for (const auto& p : poly) s << p.x() << " " << p.y() << " 0\n";                       // bottom: 0 .. n-1
  for (const auto& p : poly) s << p.x() << " " << p.y() << " " << prism.height << "\n";  // top: n .. 2n-1
  s << "# 3D Lines\n0\n# Faces from 3D lines\n0\n# Faces from 3D points\n" << n + 2 << "\n";
  // ViSP's face normal is (p1 - p0) x (p2 - p1): counter-clockwise seen from outside.
  s << n;
  for (std::size_t i = 0; i < n; ++i) s << " " << n + i;  // top, seen from above
  s << "\n" << n;
  for (std::size_t i = n; i-- > 0;) s << " " << i;  // base, seen from below
  s << "\n";
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t j = (i + 1) % n;
    s << "4 " << i << " " << j << " " << n + j << " " << n + i << "\n";
  }
  s << "# 3D cylinders\n0\n# 3D circles\n0\n";
  return s.str();
}

struct PrismModelTracker::Impl {
  vpMbGenericTracker tracker{1, vpMbGenericTracker::EDGE_TRACKER};
  vpCameraParameters cam;
  vpImage<unsigned char> image;
  bool started = false;
  bool undistort = false;
  cv::Mat map_x, map_y, ideal;
  double px = 1;
};

PrismModelTracker::PrismModelTracker(const CameraModel& camera, const ObjectModel& prism,
                                     const ModelTrackerOptions& options)
    : impl_(std::make_unique<Impl>()), options_(options) {
  Impl& m = *impl_;
  m.cam.initPersProjWithoutDistortion(camera.px, camera.py, camera.u0, camera.v0);
  m.px = camera.px;
  m.tracker.setCameraParameters(m.cam);
  vpMe me;
  me.setMaskSize(static_cast<unsigned>(options.me_mask_size));
  me.setMaskNumber(180);
  me.setRange(static_cast<unsigned>(options.me_range));
  me.setThreshold(options.me_threshold);
  me.setMu1(0.5);
  me.setMu2(0.5);
  me.setSampleStep(options.me_sample_step);
  m.tracker.setMovingEdge(me);
  m.tracker.setAngleAppear(vpMath::rad(options.angle_appear_deg));
  m.tracker.setAngleDisappear(vpMath::rad(options.angle_disappear_deg));
  m.tracker.setNearClippingDistance(0.01);
  m.tracker.setFarClippingDistance(100);
  m.tracker.setCovarianceComputation(options.covariance);
  if (options.planar) {
    vpColVector dof(6, 0.0);  // object frame: tx, ty, tz, rx, ry, rz
    dof[0] = dof[1] = dof[5] = 1;
    m.tracker.setEstimatedDoF(dof);
  }
  m.tracker.setDisplayFeatures(false);
  // The generated model goes through a temporary file: ViSP 3.5 builds its faces and lines only in loadModel.
  static std::atomic<int> counter{0};
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() /
      ("visco_prism_" + std::to_string(::getpid()) + "_" + std::to_string(counter.fetch_add(1)) + ".cao");
  {
    std::ofstream f(path);
    f << PrismCao(prism);
    if (!f) throw JobFailed("cannot write the model-based tracker's CAD model " + path.string());
  }
  try {
    // loadModel prints what it read to std::cout whatever its verbose flag: silenced.
    std::ostringstream quiet;
    std::streambuf* const cout_buf = std::cout.rdbuf(quiet.rdbuf());
    try {
      m.tracker.loadModel(path.string());
    } catch (...) {
      std::cout.rdbuf(cout_buf);
      throw;
    }
    std::cout.rdbuf(cout_buf);
  } catch (const vpException& e) {
    std::error_code ec;
    std::filesystem::remove(path, ec);
    throw JobFailed("ViSP cannot load the generated CAD model of '" + prism.id + "': " + e.getStringMessage());
  }
  std::error_code ec;
  std::filesystem::remove(path, ec);
  if (camera.distortion != DistortionModel::kNone && camera.width > 0 && camera.height > 0) {
    // Ideal pixel -> where the lens puts it: the tracker's straight edges are straight only in ideal pixels.
    m.undistort = true;
    m.map_x.create(camera.height, camera.width, CV_32FC1);
    m.map_y.create(camera.height, camera.width, CV_32FC1);
    for (int v = 0; v < camera.height; ++v) {
      for (int u = 0; u < camera.width; ++u) {
        const Eigen::Vector2d d = camera.NormalizedToPixel({(u - camera.u0) / camera.px, (v - camera.v0) / camera.py});
        m.map_x.at<float>(v, u) = static_cast<float>(d.x());
        m.map_y.at<float>(v, u) = static_cast<float>(d.y());
      }
    }
  }
}

PrismModelTracker::~PrismModelTracker() = default;

ModelTrackResult PrismModelTracker::Track(const GrayImageView& image, const Eigen::Isometry3d& prediction) {
  Impl& m = *impl_;
  ModelTrackResult r;
  const cv::Mat raw(image.height, image.width, CV_8UC1, const_cast<std::uint8_t*>(image.data),
                    static_cast<std::size_t>(image.stride));
  const cv::Mat* src = &raw;
  if (m.undistort && raw.cols == m.map_x.cols && raw.rows == m.map_x.rows) {
    cv::remap(raw, m.ideal, m.map_x, m.map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    src = &m.ideal;
  }
  if (static_cast<int>(m.image.getWidth()) != src->cols || static_cast<int>(m.image.getHeight()) != src->rows) {
    m.image.resize(static_cast<unsigned>(src->rows), static_cast<unsigned>(src->cols));
  }
  for (int v = 0; v < src->rows; ++v)
    std::memcpy(m.image[v], src->ptr<std::uint8_t>(v), static_cast<std::size_t>(src->cols));
  const vpHomogeneousMatrix cMo = ToViSP(prediction);
  try {
    if (!m.started) {
      m.tracker.initFromPose(m.image, cMo);
      m.started = true;
    } else {
      m.tracker.setPose(m.image, cMo);
    }
    m.tracker.track(m.image);
  } catch (const vpException&) {
    r.failure = "too few moving edges";
    return r;
  }
  vpHomogeneousMatrix out;
  m.tracker.getPose(out);
  r.cMo = FromViSP(out);
  r.edge_features = static_cast<int>(m.tracker.getNbFeaturesEdge());
  const vpColVector e = m.tracker.getError(), w = m.tracker.getRobustWeights();
  double sw = 0, swe = 0;
  for (unsigned i = 0; i < e.size() && i < w.size(); ++i) sw += w[i], swe += w[i] * e[i] * e[i];
  r.rms_px = sw > 0 ? m.px * std::sqrt(swe / sw) : 0;
  if (options_.covariance) {
    // ViSP's covariance is that of the camera twist [v; w] of its update; to the left perturbation of cMo in the
    // camera frame (rotation, then translation): dw = -w, dt = -v + [t]x w (the sign of the twist does not matter).
    const vpMatrix c = m.tracker.getCovarianceMatrix();
    Eigen::Matrix<double, 6, 6> cv;
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j) cv(i, j) = c[i][j];
    }
    Eigen::Matrix<double, 6, 6> a = Eigen::Matrix<double, 6, 6>::Zero();
    a.topRightCorner<3, 3>() = -Eigen::Matrix3d::Identity();
    a.bottomLeftCorner<3, 3>() = -Eigen::Matrix3d::Identity();
    a.bottomRightCorner<3, 3>() = Skew(r.cMo.translation());
    r.cov_cMo = a * cv * a.transpose();
  }
  if (!r.cMo.matrix().allFinite()) {
    r.failure = "diverged";
  } else if (r.edge_features < options_.min_edge_features) {
    r.failure = "too few moving edges";
  } else if (r.rms_px > options_.max_rms_px) {
    r.failure = "edges too far from the model";
  } else {
    r.valid = true;
  }
  return r;
}

}  // namespace visco::vision

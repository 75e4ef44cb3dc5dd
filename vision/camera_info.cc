#include "vision/camera_info.h"

#include <charconv>
#include <cmath>

#include "common/error.h"

namespace visco::vision {
namespace {

// The shortest text that reads back as the same double.
std::string Num(double x) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, x);
  return std::string(buffer, result.ptr);
}

}  // namespace

visco::camera_info_t EncodeCameraInfo(const CameraCalibration& calibration, std::int64_t utime) {
  const CameraModel& c = calibration.camera;
  visco::camera_info_t m{};
  m.utime = utime;
  m.camera = c.name;
  m.source = calibration.source;
  m.width = c.width;
  m.height = c.height;
  m.px = c.px;
  m.py = c.py;
  m.u0 = c.u0;
  m.v0 = c.v0;
  switch (c.distortion) {
    case DistortionModel::kNone:
      m.distortion_model = visco::camera_info_t::DISTORTION_NONE;
      break;
    case DistortionModel::kViSP:
      m.distortion_model = visco::camera_info_t::DISTORTION_VISP;
      m.distortion = {c.kud, c.kdu};
      break;
    case DistortionModel::kOpenCV:
      m.distortion_model = visco::camera_info_t::DISTORTION_OPENCV;
      m.distortion = c.dist;
      break;
  }
  m.num_distortion = static_cast<std::int32_t>(m.distortion.size());
  m.has_extrinsics = calibration.extrinsics.has_value();
  for (int r = 0; r < 3; ++r) {
    m.position[r] = 0;
    for (int k = 0; k < 3; ++k) m.rotation[r][k] = 0;
  }
  for (int r = 0; r < 6; ++r) {
    for (int k = 0; k < 6; ++k) m.extrinsics_covariance[r][k] = 0;
  }
  if (calibration.extrinsics) {
    const Eigen::Isometry3d& wMc = calibration.extrinsics->wMc;
    for (int r = 0; r < 3; ++r) {
      m.position[r] = wMc.translation()(r);
      for (int k = 0; k < 3; ++k) m.rotation[r][k] = wMc.linear()(r, k);
    }
    for (int r = 0; r < 6; ++r) {
      for (int k = 0; k < 6; ++k) m.extrinsics_covariance[r][k] = calibration.extrinsics->covariance(r, k);
    }
  }
  return m;
}

CameraCalibration DecodeCameraInfo(const visco::camera_info_t& m, const std::string& where) {
  const std::string object = "camera_info '" + m.camera + "'";
  auto fail = [&](const std::string& what) { throw InputError(where, object, what); };
  auto finite = [&](double x, const char* field) {
    if (!std::isfinite(x)) fail(std::string(field) + " is not finite");
  };
  CameraCalibration out;
  CameraModel& c = out.camera;
  out.source = m.source;
  c.name = m.camera;
  if (m.width < 0 || m.height < 0) {
    fail("image size must not be negative (" + std::to_string(m.width) + "x" + std::to_string(m.height) + ")");
  }
  c.width = m.width;
  c.height = m.height;
  finite(m.px, "px");
  finite(m.py, "py");
  finite(m.u0, "u0");
  finite(m.v0, "v0");
  if (m.px <= 0 || m.py <= 0) fail("focal lengths must be positive (px = " + Num(m.px) + ", py = " + Num(m.py) + ")");
  c.px = m.px;
  c.py = m.py;
  c.u0 = m.u0;
  c.v0 = m.v0;
  if (m.num_distortion != static_cast<std::int32_t>(m.distortion.size())) {
    fail("num_distortion is " + std::to_string(m.num_distortion) + " but " + std::to_string(m.distortion.size()) +
         " coefficients follow");
  }
  for (double d : m.distortion) finite(d, "a distortion coefficient");
  const std::size_t n = m.distortion.size();
  switch (m.distortion_model) {
    case visco::camera_info_t::DISTORTION_NONE:
      if (n != 0) fail("distortion model NONE with " + std::to_string(n) + " coefficients");
      c.distortion = DistortionModel::kNone;
      break;
    case visco::camera_info_t::DISTORTION_VISP:
      if (n != 2) fail("distortion model VISP needs 2 coefficients (kud, kdu), got " + std::to_string(n));
      c.distortion = DistortionModel::kViSP;
      c.kud = m.distortion[0];
      c.kdu = m.distortion[1];
      break;
    case visco::camera_info_t::DISTORTION_OPENCV:
      if (n != 4 && n != 5 && n != 8) {
        fail("distortion model OPENCV needs 4, 5 or 8 coefficients (k1 k2 p1 p2 [k3 [k4 k5 k6]]), got " +
             std::to_string(n));
      }
      c.distortion = DistortionModel::kOpenCV;
      c.dist = m.distortion;
      break;
    default:
      fail("unknown distortion_model " + std::to_string(m.distortion_model));
  }
  if (!m.has_extrinsics) return out;
  Extrinsics e;
  Eigen::Matrix3d r;
  for (int i = 0; i < 3; ++i) {
    finite(m.position[i], "position");
    e.wMc.translation()(i) = m.position[i];
    for (int k = 0; k < 3; ++k) {
      finite(m.rotation[i][k], "rotation");
      r(i, k) = m.rotation[i][k];
    }
  }
  // The same tolerance as the extrinsics file's check (common/extrinsics.h).
  if (!((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() <= 1e-6) ||
      !(std::abs(r.determinant() - 1) <= 1e-6)) {
    fail("rotation is not a rotation matrix (orthonormal, determinant +1)");
  }
  e.wMc.linear() = r;
  for (int i = 0; i < 6; ++i) {
    for (int k = 0; k < 6; ++k) {
      finite(m.extrinsics_covariance[i][k], "extrinsics_covariance");
      e.covariance(i, k) = m.extrinsics_covariance[i][k];
    }
    if (e.covariance(i, i) < 0) fail("extrinsics_covariance has a negative variance");
  }
  if (!(e.covariance - e.covariance.transpose()).isZero(0)) fail("extrinsics_covariance is not symmetric");
  out.extrinsics = e;
  return out;
}

std::vector<std::string> CalibrationDifferences(const CameraCalibration& given, const std::string& a_label,
                                                const CameraCalibration& other, const std::string& b_label) {
  std::vector<std::string> out;
  const CameraModel &a = given.camera, &b = other.camera;
  auto differ = [&](const std::string& what, const std::string& x, const std::string& y) {
    out.push_back(what + ": " + x + " (" + a_label + ") vs " + y + " (" + b_label + ")");
  };
  auto number = [&](const std::string& what, double x, double y) {
    if (x != y) differ(what, Num(x), Num(y));
  };
  if (!a.name.empty() && !b.name.empty() && a.name != b.name) differ("camera name", a.name, b.name);
  if (a.width != b.width || a.height != b.height) {
    differ("image size", std::to_string(a.width) + "x" + std::to_string(a.height),
           std::to_string(b.width) + "x" + std::to_string(b.height));
  }
  number("px", a.px, b.px);
  number("py", a.py, b.py);
  number("u0", a.u0, b.u0);
  number("v0", a.v0, b.v0);
  static const char* const kModels[] = {"none", "ViSP", "OpenCV"};
  if (a.distortion != b.distortion) {
    differ("distortion model", kModels[static_cast<int>(a.distortion)], kModels[static_cast<int>(b.distortion)]);
  } else if (a.distortion == DistortionModel::kViSP) {
    number("kud", a.kud, b.kud);
    number("kdu", a.kdu, b.kdu);
  } else if (a.distortion == DistortionModel::kOpenCV) {
    if (a.dist.size() != b.dist.size()) {
      differ("number of distortion coefficients", std::to_string(a.dist.size()), std::to_string(b.dist.size()));
    } else {
      for (std::size_t i = 0; i < a.dist.size(); ++i) {
        number("distortion[" + std::to_string(i) + "]", a.dist[i], b.dist[i]);
      }
    }
  }
  if (given.extrinsics.has_value() != other.extrinsics.has_value()) {
    out.push_back("extrinsics: only in " + (given.extrinsics ? a_label : b_label));
  } else if (given.extrinsics) {
    const Extrinsics &x = *given.extrinsics, &y = *other.extrinsics;
    if (!(x.wMc.matrix() == y.wMc.matrix())) {
      const double apart = (x.wMc.translation() - y.wMc.translation()).norm();
      const double angle = Eigen::AngleAxisd(x.wMc.linear().transpose() * y.wMc.linear()).angle();
      out.push_back("extrinsics: camera centres " + Num(apart) + " m apart, orientations " + Num(angle * 180 / M_PI) +
                    " deg apart (" + a_label + " vs " + b_label + ")");
    }
    if (!(x.covariance == y.covariance)) {
      out.push_back("extrinsics uncertainty: covariances differ (" + a_label + " vs " + b_label + ")");
    }
  }
  return out;
}

}  // namespace visco::vision

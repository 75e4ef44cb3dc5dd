#include "vision/camera.h"

#include <visp3/core/vpCameraParameters.h>
#include <visp3/core/vpXmlParserCamera.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <sstream>

#include "common/error.h"
#include "vision/ros_camera_info.h"

namespace visco::vision {
namespace {

bool Finite(double x) { return std::isfinite(x); }

void Validate(const CameraModel& c, const std::string& file) {
  if (!Finite(c.px) || !Finite(c.py) || c.px <= 0 || c.py <= 0) {
    throw InputError(file, "camera '" + c.name + "'",
                     "focal lengths must be positive and finite (px = " + std::to_string(c.px) +
                         ", py = " + std::to_string(c.py) + ")");
  }
  if (!Finite(c.u0) || !Finite(c.v0)) {
    throw InputError(file, "camera '" + c.name + "'", "principal point is not finite");
  }
  if (c.width < 0 || c.height < 0) {
    throw InputError(file, "camera '" + c.name + "'", "image size must not be negative");
  }
  if (c.distortion == DistortionModel::kViSP && (!Finite(c.kud) || !Finite(c.kdu))) {
    throw InputError(file, "camera '" + c.name + "'", "distortion coefficients kud/kdu are not finite");
  }
  if (c.distortion == DistortionModel::kOpenCV) {
    const std::size_t n = c.dist.size();
    if (n != 4 && n != 5 && n != 8) {
      throw InputError(file, "distortion_coefficients",
                       "expected 4, 5 or 8 coefficients (k1 k2 p1 p2 [k3 [k4 k5 k6]]), got " + std::to_string(n));
    }
    for (double d : c.dist) {
      if (!Finite(d)) throw InputError(file, "distortion_coefficients", "a coefficient is not finite");
    }
  }
}

// vpXmlParserCamera reports on std::cout ("Found camera with name ..."); keep stdout clean for JSON output.
class SilenceCout {
 public:
  SilenceCout() : saved_(std::cout.rdbuf(null_.rdbuf())) {}
  ~SilenceCout() { std::cout.rdbuf(saved_); }
  SilenceCout(const SilenceCout&) = delete;
  SilenceCout& operator=(const SilenceCout&) = delete;

 private:
  std::ostringstream null_;
  std::streambuf* saved_;
};

// vpXmlParserCamera matches cameras by name (an empty name matches none): the first <camera>'s <name>.
std::string FirstViSPCameraName(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  const std::size_t cam = text.find("<camera>");
  if (cam == std::string::npos) return "";
  const std::size_t a = text.find("<name>", cam), end = text.find("</camera>", cam);
  if (a == std::string::npos || a > end) return "";
  const std::size_t b = text.find("</name>", a);
  if (b == std::string::npos) return "";
  std::string name = text.substr(a + 6, b - a - 6);
  const auto first = name.find_first_not_of(" \t\r\n"), last = name.find_last_not_of(" \t\r\n");
  return first == std::string::npos ? "" : name.substr(first, last - first + 1);
}

CameraModel LoadViSPXml(const std::string& path, const std::string& requested_name) {
  const std::string camera_name = requested_name.empty() ? FirstViSPCameraName(path) : requested_name;
  // A parser instance per attempt: a failed parse leaves state behind.
  vpXmlParserCamera with_distortion, without_distortion;
  vpXmlParserCamera* parser = &with_distortion;
  vpCameraParameters cam;
  CameraModel out;
  int status = vpXmlParserCamera::SEQUENCE_ERROR;
  try {
    SilenceCout silence;
    status = with_distortion.parse(cam, path, camera_name, vpCameraParameters::perspectiveProjWithDistortion);
    if (status == vpXmlParserCamera::SEQUENCE_OK) {
      out.distortion = DistortionModel::kViSP;
    } else {
      parser = &without_distortion;
      cam = vpCameraParameters();
      status = without_distortion.parse(cam, path, camera_name, vpCameraParameters::perspectiveProjWithoutDistortion);
    }
  } catch (const std::exception& e) {
    throw InputError(path, "", std::string("not a readable ViSP camera XML file: ") + e.what());
  }
  if (status != vpXmlParserCamera::SEQUENCE_OK) {
    throw InputError(path, camera_name.empty() ? "camera" : "camera '" + camera_name + "'",
                     "no <camera> with a perspective <model> (px, py, u0, v0) found");
  }
  out.name = parser->getCameraName();
  out.width = static_cast<int>(parser->getWidth());
  out.height = static_cast<int>(parser->getHeight());
  out.px = cam.get_px();
  out.py = cam.get_py();
  out.u0 = cam.get_u0();
  out.v0 = cam.get_v0();
  if (out.distortion == DistortionModel::kViSP) {
    out.kud = cam.get_kud();
    out.kdu = cam.get_kdu();
    if (out.kud == 0 && out.kdu == 0) out.distortion = DistortionModel::kNone;
  }
  return out;
}

CameraModel LoadOpenCV(const std::string& path) {
  cv::FileStorage fs;
  try {
    if (!fs.open(path, cv::FileStorage::READ)) throw InputError(path, "", "cannot be opened as OpenCV FileStorage");
  } catch (const cv::Exception& e) {
    throw InputError(path, "", std::string("not a readable OpenCV calibration file: ") + e.err);
  }
  CameraModel out;
  cv::Mat k, d;
  try {
    fs["camera_matrix"] >> k;
    fs["distortion_coefficients"] >> d;
    if (!fs["image_width"].empty()) out.width = static_cast<int>(fs["image_width"]);
    if (!fs["image_height"].empty()) out.height = static_cast<int>(fs["image_height"]);
    if (!fs["camera_name"].empty()) out.name = static_cast<std::string>(fs["camera_name"]);
  } catch (const cv::Exception& e) {
    throw InputError(path, "", std::string("malformed entry: ") + e.err);
  }
  if (k.empty()) throw InputError(path, "camera_matrix", "missing (a 3x3 matrix is required)");
  if (k.rows != 3 || k.cols != 3) {
    throw InputError(path, "camera_matrix",
                     "must be 3x3, got " + std::to_string(k.rows) + "x" + std::to_string(k.cols));
  }
  k.convertTo(k, CV_64F);
  out.px = k.at<double>(0, 0);
  out.py = k.at<double>(1, 1);
  out.u0 = k.at<double>(0, 2);
  out.v0 = k.at<double>(1, 2);
  if (std::abs(k.at<double>(0, 1)) > 1e-9 || std::abs(k.at<double>(1, 0)) > 1e-9 ||
      std::abs(k.at<double>(2, 0)) > 1e-9 || std::abs(k.at<double>(2, 1)) > 1e-9 ||
      std::abs(k.at<double>(2, 2) - 1) > 1e-9) {
    throw InputError(path, "camera_matrix", "must be [fx 0 cx; 0 fy cy; 0 0 1] (no skew)");
  }
  if (!d.empty()) {
    d.convertTo(d, CV_64F);
    d = d.reshape(1, 1);
    out.dist.assign(d.begin<double>(), d.end<double>());
    bool any = false;
    for (double x : out.dist) any = any || x != 0;
    out.distortion = DistortionModel::kOpenCV;
    Validate(out, path);
    if (!any) {
      out.distortion = DistortionModel::kNone;
      out.dist.clear();
    }
  }
  return out;
}

std::string ReadHead(const std::string& path) {
  std::ifstream in(path);
  std::string head(512, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  return head;
}

}  // namespace

CameraModel CameraModel::Pinhole(double px, double py, double u0, double v0, int width, int height) {
  CameraModel c;
  c.name = "pinhole";
  c.px = px;
  c.py = py;
  c.u0 = u0;
  c.v0 = v0;
  c.width = width;
  c.height = height;
  Validate(c, "camera");
  return c;
}

Eigen::Vector2d CameraModel::PixelToNormalized(const Eigen::Vector2d& uv) const {
  switch (distortion) {
    case DistortionModel::kNone:
      return {(uv.x() - u0) / px, (uv.y() - v0) / py};
    case DistortionModel::kViSP: {
      // ViSP's vpPixelMeterConversion with distortion: x = (u - u0)(1 + kdu r^2) / px, r from the distorted pixel.
      const double xd = (uv.x() - u0) / px, yd = (uv.y() - v0) / py;
      const double s = 1 + kdu * (xd * xd + yd * yd);
      return {xd * s, yd * s};
    }
    case DistortionModel::kOpenCV: {
      const cv::Matx33d k(px, 0, u0, 0, py, v0, 0, 0, 1);
      std::vector<cv::Point2d> src{{uv.x(), uv.y()}}, dst;
      cv::undistortPoints(src, dst, k, dist, cv::noArray(), cv::noArray(),
                          cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-12));
      return {dst[0].x, dst[0].y};
    }
  }
  return {};
}

Eigen::Vector2d CameraModel::NormalizedToPixel(const Eigen::Vector2d& xy) const {
  const double x = xy.x(), y = xy.y();
  switch (distortion) {
    case DistortionModel::kNone:
      return {u0 + px * x, v0 + py * y};
    case DistortionModel::kViSP: {
      const double s = 1 + kud * (x * x + y * y);
      return {u0 + px * x * s, v0 + py * y * s};
    }
    case DistortionModel::kOpenCV: {
      const double k1 = dist[0], k2 = dist[1], p1 = dist[2], p2 = dist[3];
      const double k3 = dist.size() > 4 ? dist[4] : 0;
      const double k4 = dist.size() > 5 ? dist[5] : 0, k5 = dist.size() > 6 ? dist[6] : 0,
                   k6 = dist.size() > 7 ? dist[7] : 0;
      const double r2 = x * x + y * y, r4 = r2 * r2, r6 = r4 * r2;
      const double radial = (1 + k1 * r2 + k2 * r4 + k3 * r6) / (1 + k4 * r2 + k5 * r4 + k6 * r6);
      const double xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
      const double yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
      return {u0 + px * xd, v0 + py * yd};
    }
  }
  return {};
}

CameraModel LoadCamera(const std::string& path, const std::string& camera_name) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError(path, "", "calibration file does not exist");
  std::string ext = fs::path(path).extension().string();
  for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  CameraModel cam;
  if (ext == ".xml") {
    const std::string head = ReadHead(path);
    if (head.find("<opencv_storage>") != std::string::npos) {
      cam = LoadOpenCV(path);
    } else {
      cam = LoadViSPXml(path, camera_name);
    }
  } else if (ext == ".yaml" || ext == ".yml") {
    cam = IsRosCameraInfo(path) ? LoadRosCameraInfo(path) : LoadOpenCV(path);
  } else if (ext == ".json") {
    cam = LoadOpenCV(path);
  } else {
    throw InputError(path, "",
                     "unknown calibration format (expected .xml for ViSP, .yaml/.yml for OpenCV or ROS camera_info)");
  }
  Validate(cam, path);
  return cam;
}

void SaveCameraViSP(const CameraModel& camera, const std::string& path) {
  vpCameraParameters cam;
  if (camera.distortion == DistortionModel::kViSP) {
    cam.initPersProjWithDistortion(camera.px, camera.py, camera.u0, camera.v0, camera.kud, camera.kdu);
  } else if (camera.distortion == DistortionModel::kNone) {
    cam.initPersProjWithoutDistortion(camera.px, camera.py, camera.u0, camera.v0);
  } else {
    throw JobFailed("ViSP XML cannot hold OpenCV distortion coefficients");
  }
  std::error_code ec;
  std::filesystem::remove(path, ec);  // vpXmlParserCamera::save appends to an existing file
  vpXmlParserCamera parser;
  const std::string name = camera.name.empty() ? "camera" : camera.name;
  {
    SilenceCout silence;
    parser.save(cam, path, name, static_cast<unsigned>(camera.width), static_cast<unsigned>(camera.height));
  }
  // save() reports an error code even when it wrote the file (it re-parses it); check the file instead.
  if (!std::filesystem::is_regular_file(path, ec)) throw JobFailed("cannot write camera calibration " + path);
}

void SaveCameraOpenCV(const CameraModel& camera, const std::string& path) {
  cv::FileStorage fs(path, cv::FileStorage::WRITE);
  if (!fs.isOpened()) throw JobFailed("cannot write camera calibration " + path);
  fs << "camera_name" << camera.name;
  fs << "image_width" << camera.width << "image_height" << camera.height;
  fs << "camera_matrix" << cv::Mat(cv::Matx33d(camera.px, 0, camera.u0, 0, camera.py, camera.v0, 0, 0, 1));
  cv::Mat d = camera.dist.empty() ? cv::Mat::zeros(1, 5, CV_64F) : cv::Mat(camera.dist, true).reshape(1, 1);
  if (camera.distortion == DistortionModel::kViSP) throw JobFailed("OpenCV YAML cannot hold ViSP's kud/kdu model");
  fs << "distortion_coefficients" << d;
}

void SaveExtrinsics(const Eigen::Isometry3d& wMc, const std::string& path) {
  nlohmann::json j;
  const Eigen::Vector3d t = wMc.translation();
  const Eigen::Matrix3d r = wMc.rotation();
  j["wMc"]["t"] = {t.x(), t.y(), t.z()};
  j["wMc"]["R"] = {{r(0, 0), r(0, 1), r(0, 2)}, {r(1, 0), r(1, 1), r(1, 2)}, {r(2, 0), r(2, 1), r(2, 2)}};
  std::ofstream out(path);
  if (!out) throw JobFailed("cannot write extrinsics " + path);
  out << j.dump(2) << "\n";
}

}  // namespace visco::vision

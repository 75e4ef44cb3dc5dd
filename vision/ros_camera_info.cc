#include "vision/ros_camera_info.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>
#include <vector>

#include "common/error.h"

namespace visco::vision {
namespace {

// " (line N)" for a node that has a position in the file.
std::string At(const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  return mark.is_null() ? "" : " (line " + std::to_string(mark.line + 1) + ")";
}

double Number(const YAML::Node& node, const std::string& path, const std::string& field) {
  double v = 0;
  if (!node.IsScalar() || !YAML::convert<double>::decode(node, v)) {
    throw InputError(path, field, "must be a number" + At(node));
  }
  if (!std::isfinite(v)) throw InputError(path, field, "must be finite" + At(node));
  return v;
}

int Integer(const YAML::Node& node, const std::string& path, const std::string& field) {
  long long v = 0;
  if (!node.IsScalar() || !YAML::convert<long long>::decode(node, v) || v < 0 || v > 1000000) {
    throw InputError(path, field, "must be a whole number >= 0" + At(node));
  }
  return static_cast<int>(v);
}

struct Matrix {
  int rows = 0, cols = 0;
  std::vector<double> data;  // row-major
  double at(int r, int c) const { return data[static_cast<std::size_t>(r * cols + c)]; }
};

// `key: {rows: R, cols: C, data: [R*C numbers]}`; `rows`/`cols` must be `want_rows`/`want_cols` unless negative.
Matrix ReadMatrix(const YAML::Node& root, const std::string& path, const std::string& key, int want_rows,
                  int want_cols) {
  const YAML::Node node = root[key];
  const std::string shape = "{rows: " + (want_rows < 0 ? std::string("R") : std::to_string(want_rows)) +
                            ", cols: " + (want_cols < 0 ? std::string("C") : std::to_string(want_cols)) +
                            ", data: [numbers, row by row]}";
  if (!node.IsMap()) throw InputError(path, key, "must be a map " + shape + At(node));
  for (auto it = node.begin(); it != node.end(); ++it) {
    const std::string k = it->first.as<std::string>();
    if (k != "rows" && k != "cols" && k != "data") {
      throw InputError(path, key + "." + k, "unknown field (expected rows, cols, data)" + At(it->first));
    }
  }
  for (const char* k : {"rows", "cols", "data"}) {
    if (!node[k]) throw InputError(path, key + "." + k, "missing (expected " + shape + ")" + At(node));
  }
  Matrix m;
  m.rows = Integer(node["rows"], path, key + ".rows");
  m.cols = Integer(node["cols"], path, key + ".cols");
  if ((want_rows >= 0 && m.rows != want_rows) || (want_cols >= 0 && m.cols != want_cols)) {
    throw InputError(path, key,
                     "must be " + std::to_string(want_rows < 0 ? m.rows : want_rows) + "x" +
                         std::to_string(want_cols < 0 ? m.cols : want_cols) + ", got rows: " + std::to_string(m.rows) +
                         ", cols: " + std::to_string(m.cols));
  }
  const YAML::Node data = node["data"];
  if (!data.IsSequence()) throw InputError(path, key + ".data", "must be a list of numbers" + At(data));
  if (data.size() != static_cast<std::size_t>(m.rows) * static_cast<std::size_t>(m.cols)) {
    throw InputError(path, key + ".data",
                     "holds " + std::to_string(data.size()) + " numbers, rows x cols = " + std::to_string(m.rows) +
                         " x " + std::to_string(m.cols) + " needs " + std::to_string(m.rows * m.cols) + At(data));
  }
  for (std::size_t i = 0; i < data.size(); ++i) {
    m.data.push_back(Number(data[i], path, key + ".data[" + std::to_string(i) + "]"));
  }
  return m;
}

const std::set<std::string> kKeys = {"image_width",          "image_height",     "camera_name",
                                     "camera_matrix",        "distortion_model", "distortion_coefficients",
                                     "rectification_matrix", "projection_matrix"};

}  // namespace

bool IsRosCameraInfo(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  const std::string s = text.str();
  const std::size_t first = s.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && s.compare(first, 6, "%YAML:") == 0) return false;
  return s.find("opencv-matrix") == std::string::npos;
}

CameraModel LoadRosCameraInfo(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw InputError(path, "", "cannot be read");
  } catch (const YAML::Exception& e) {
    throw InputError(path, "", "not valid YAML (line " + std::to_string(e.mark.line + 1) + "): " + e.msg);
  }
  if (!root.IsMap()) {
    throw InputError(path, "", "not a ROS camera_info file: expected a map with image_width, camera_matrix, ...");
  }
  for (auto it = root.begin(); it != root.end(); ++it) {
    const std::string k = it->first.IsScalar() ? it->first.as<std::string>() : "?";
    if (kKeys.count(k) == 0) {
      throw InputError(path, k,
                       "unknown field" + At(it->first) +
                           " (a ROS camera_info file has image_width, image_height, camera_name, camera_matrix, "
                           "distortion_model, distortion_coefficients, rectification_matrix, projection_matrix)");
    }
  }
  CameraModel out;
  for (const char* k : {"image_width", "image_height", "camera_matrix"}) {
    if (!root[k]) throw InputError(path, k, "missing (required in a ROS camera_info file)");
  }
  out.width = Integer(root["image_width"], path, "image_width");
  out.height = Integer(root["image_height"], path, "image_height");
  if (root["camera_name"]) {
    if (!root["camera_name"].IsScalar()) throw InputError(path, "camera_name", "must be a string");
    out.name = root["camera_name"].as<std::string>();
  }
  const Matrix k = ReadMatrix(root, path, "camera_matrix", 3, 3);
  if (std::abs(k.at(0, 1)) > 1e-9 || std::abs(k.at(1, 0)) > 1e-9 || std::abs(k.at(2, 0)) > 1e-9 ||
      std::abs(k.at(2, 1)) > 1e-9 || std::abs(k.at(2, 2) - 1) > 1e-9) {
    throw InputError(path, "camera_matrix", "must be [fx 0 cx; 0 fy cy; 0 0 1] (no skew)");
  }
  out.px = k.at(0, 0);
  out.py = k.at(1, 1);
  out.u0 = k.at(0, 2);
  out.v0 = k.at(1, 2);

  std::vector<double> d;
  if (root["distortion_coefficients"]) d = ReadMatrix(root, path, "distortion_coefficients", 1, -1).data;
  std::string model;
  if (root["distortion_model"]) {
    if (!root["distortion_model"].IsScalar()) throw InputError(path, "distortion_model", "must be a name");
    model = root["distortion_model"].as<std::string>();
  } else if (!d.empty()) {
    throw InputError(path, "distortion_model", "missing (plumb_bob or rational_polynomial) beside coefficients");
  }
  if (model == "plumb_bob") {
    if (d.size() != 0 && d.size() != 4 && d.size() != 5) {
      throw InputError(path, "distortion_coefficients",
                       "plumb_bob has 5 coefficients (k1 k2 t1 t2 k3; 4 without k3), got " + std::to_string(d.size()));
    }
  } else if (model == "rational_polynomial") {
    if (d.size() != 8) {
      throw InputError(
          path, "distortion_coefficients",
          "rational_polynomial has 8 coefficients (k1 k2 t1 t2 k3 k4 k5 k6), got " + std::to_string(d.size()));
    }
  } else if (model == "equidistant" || model == "fisheye") {
    throw InputError(path, "distortion_model",
                     "'" + model +
                         "' (fisheye) is not supported: visco's camera model has the plumb_bob and "
                         "rational_polynomial lens models; calibrate with one of them");
  } else if (!model.empty()) {
    throw InputError(path, "distortion_model",
                     "unknown model '" + model + "' (expected plumb_bob or rational_polynomial)");
  }
  bool any = false;
  for (double x : d) any = any || x != 0;
  if (any) {
    out.distortion = DistortionModel::kOpenCV;  // ROS's models are OpenCV's, coefficient for coefficient
    out.dist = d;
  }

  if (root["rectification_matrix"]) {
    const Matrix r = ReadMatrix(root, path, "rectification_matrix", 3, 3);
    Eigen::Matrix3d rm;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) rm(i, j) = r.at(i, j);
    }
    // camera_calibration prints R with 8 decimals: a rotation to within that.
    if (!(rm * rm.transpose()).isApprox(Eigen::Matrix3d::Identity(), 1e-5) || std::abs(rm.determinant() - 1) > 1e-5) {
      throw InputError(path, "rectification_matrix", "is not a rotation matrix (orthonormal, determinant +1)");
    }
  }
  if (root["projection_matrix"]) ReadMatrix(root, path, "projection_matrix", 3, 4);
  return out;
}

void SaveCameraRos(const CameraModel& camera, const std::string& path) {
  if (camera.distortion == DistortionModel::kViSP) throw JobFailed("ROS camera_info cannot hold ViSP's kud/kdu model");
  std::ofstream out(path);
  if (!out) throw JobFailed("cannot write camera calibration " + path);
  const std::vector<double> d = camera.dist.empty() ? std::vector<double>(5, 0.0) : camera.dist;
  auto list = [&](const std::vector<double>& v) {
    std::ostringstream s;
    s << std::setprecision(17) << "[";
    for (std::size_t i = 0; i < v.size(); ++i) s << (i ? ", " : "") << v[i];
    return s.str() + "]";
  };
  out << "image_width: " << camera.width << "\nimage_height: " << camera.height
      << "\ncamera_name: " << (camera.name.empty() ? "camera" : camera.name)
      << "\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
      << "  data: " << list({camera.px, 0, camera.u0, 0, camera.py, camera.v0, 0, 0, 1})
      << "\ndistortion_model: " << (d.size() == 8 ? "rational_polynomial" : "plumb_bob")
      << "\ndistortion_coefficients:\n  rows: 1\n  cols: " << d.size() << "\n  data: " << list(d)
      << "\nrectification_matrix:\n  rows: 3\n  cols: 3\n  data: " << list({1, 0, 0, 0, 1, 0, 0, 0, 1})
      << "\nprojection_matrix:\n  rows: 3\n  cols: 4\n  data: "
      << list({camera.px, 0, camera.u0, 0, 0, camera.py, camera.v0, 0, 0, 0, 1, 0}) << "\n";
  if (!out) throw JobFailed("cannot write camera calibration " + path);
}

}  // namespace visco::vision

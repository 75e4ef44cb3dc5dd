#include "control/servo_camera.h"

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "common/error.h"
#include "common/extrinsics.h"

namespace visco::control {
namespace {

std::string ReadText(const std::string& path, const char* what) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "", std::string(what) + " file does not exist or cannot be read");
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

nlohmann::json ParseJson(const std::string& path, const char* what) {
  try {
    return nlohmann::json::parse(ReadText(path, what));
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path, "", std::string("not valid JSON: ") + e.what());
  }
}

bool EndsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

// The text between <tag> and </tag> in [begin, end), or npos-marked empty.
bool Element(const std::string& text, std::size_t begin, std::size_t end, const std::string& tag, std::string& out,
             std::size_t* after = nullptr) {
  const std::size_t a = text.find("<" + tag + ">", begin);
  if (a == std::string::npos || a >= end) return false;
  const std::size_t b = text.find("</" + tag + ">", a);
  if (b == std::string::npos || b > end) return false;
  out = text.substr(a + tag.size() + 2, b - a - tag.size() - 2);
  if (after != nullptr) *after = b + tag.size() + 3;
  return true;
}

double XmlNumber(const std::string& path, const std::string& text, std::size_t begin, std::size_t end,
                 const std::string& tag) {
  std::string value;
  if (!Element(text, begin, end, tag, value)) throw InputError(path, "camera.model." + tag, "missing");
  try {
    std::size_t used = 0;
    const double x = std::stod(value, &used);
    if (value.find_first_not_of(" \t\r\n", used) != std::string::npos) throw std::invalid_argument(value);
    return x;
  } catch (const std::exception&) {
    throw InputError(path, "camera.model." + tag, "not a number: '" + value + "'");
  }
}

void ViSPIntrinsics(const std::string& path, double (&k)[4]) {
  const std::string text = ReadText(path, "calibration");
  const std::size_t cam = text.find("<camera>");
  if (cam == std::string::npos) throw InputError(path, "camera", "no <camera> in the ViSP XML calibration");
  const std::size_t cam_end = text.find("</camera>", cam);
  if (cam_end == std::string::npos) throw InputError(path, "camera", "<camera> is not closed");
  // Its models: the one with distortion is preferred (vision::LoadCamera), its px, py give ideal pixels.
  std::size_t chosen = std::string::npos, chosen_end = 0, at = cam;
  bool chosen_distorted = false;
  std::string model;
  while (true) {
    const std::size_t a = text.find("<model>", at);
    if (a == std::string::npos || a >= cam_end) break;
    std::size_t after = 0;
    if (!Element(text, a, cam_end, "model", model, &after)) throw InputError(path, "camera.model", "not closed");
    std::string type;
    Element(text, a, after, "type", type);
    const bool distorted = type.find("perspectiveProjWithDistortion") != std::string::npos;
    const bool plain = type.find("perspectiveProjWithoutDistortion") != std::string::npos;
    if ((distorted || plain) && (chosen == std::string::npos || (distorted && !chosen_distorted))) {
      chosen = a, chosen_end = after, chosen_distorted = distorted;
    }
    at = after;
  }
  if (chosen == std::string::npos) {
    throw InputError(path, "camera.model",
                     "no perspectiveProjWithDistortion or perspectiveProjWithoutDistortion model");
  }
  k[0] = XmlNumber(path, text, chosen, chosen_end, "px");
  k[1] = XmlNumber(path, text, chosen, chosen_end, "py");
  k[2] = XmlNumber(path, text, chosen, chosen_end, "u0");
  k[3] = XmlNumber(path, text, chosen, chosen_end, "v0");
}

void OpenCVJsonIntrinsics(const std::string& path, double (&k)[4]) {
  const nlohmann::json j = ParseJson(path, "calibration");
  if (!j.is_object() || !j.contains("camera_matrix") || !j["camera_matrix"].is_object() ||
      !j["camera_matrix"].contains("data") || !j["camera_matrix"]["data"].is_array() ||
      j["camera_matrix"]["data"].size() != 9) {
    throw InputError(path, "camera_matrix", "missing or not a 3x3 matrix (OpenCV FileStorage JSON)");
  }
  const auto& d = j["camera_matrix"]["data"];
  for (const auto& x : d) {
    if (!x.is_number()) throw InputError(path, "camera_matrix", "must hold numbers");
  }
  k[0] = d[0].get<double>(), k[1] = d[4].get<double>(), k[2] = d[2].get<double>(), k[3] = d[5].get<double>();
}

double RobotHeight(const std::string& path) {
  const nlohmann::json j = ParseJson(path, "object models");
  if (!j.is_object() || !j.contains("robot") || !j["robot"].is_object() || !j["robot"].contains("height") ||
      !j["robot"]["height"].is_number()) {
    throw InputError(path, "robot.height", "missing (the robot prism's height in metres)");
  }
  const double h = j["robot"]["height"].get<double>();
  if (!(h > 0) || !std::isfinite(h)) throw InputError(path, "robot.height", "must be positive");
  return h;
}

}  // namespace

ServoCamera LoadServoCamera(const std::string& calibration_path, const std::string& extrinsics_path,
                            const std::string& objects_path) {
  double k[4] = {};
  if (EndsWith(calibration_path, ".json")) {
    OpenCVJsonIntrinsics(calibration_path, k);
  } else if (EndsWith(calibration_path, ".xml") &&
             ReadText(calibration_path, "calibration").find("opencv_storage") == std::string::npos) {
    ViSPIntrinsics(calibration_path, k);
  } else {
    throw InputError(
        calibration_path, "",
        "visco run reads ViSP XML or OpenCV JSON calibrations (it links no OpenCV): convert this one, e.g. "
        "with OpenCV's FileStorage to a .json file");
  }
  if (!(k[0] > 0) || !(k[1] > 0) || !std::isfinite(k[0]) || !std::isfinite(k[1])) {
    throw InputError(calibration_path, "px", "focal lengths must be positive and finite");
  }
  if (!std::isfinite(k[2]) || !std::isfinite(k[3])) {
    throw InputError(calibration_path, "u0", "principal point is not finite");
  }
  const Eigen::Isometry3d wMc = LoadExtrinsics(extrinsics_path);
  double r[3][3] = {}, t[3] = {};
  for (int i = 0; i < 3; ++i) {
    t[i] = wMc.translation()[i];
    for (int j = 0; j < 3; ++j) r[i][j] = wMc.linear()(i, j);
  }
  return MakeServoCamera(k[0], k[1], k[2], k[3], r, t, RobotHeight(objects_path));
}

}  // namespace visco::control

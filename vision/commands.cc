#include "vision/commands.h"

#include <CLI/CLI.hpp>
#include <cstdio>
#include <fstream>
#include <memory>

#include "common/error.h"
#include "vision/camera.h"
#include "vision/detect_json.h"
#include "vision/image.h"
#include "vision/tag_detector.h"

namespace visco::vision {
namespace {

struct DetectArgs {
  std::string image;
  std::string camera;
  std::string camera_name;
  double tag_size = 0;
  std::string family = "tag36h11";
  std::string out;
  DetectorOptions detector;
  PoseOptions pose;
};

void WriteOutput(const std::string& text, const std::string& out) {
  if (out.empty()) {
    std::fwrite(text.data(), 1, text.size(), stdout);
    std::fputc('\n', stdout);
    return;
  }
  std::ofstream f(out);
  if (!f) throw InputError(out, "", "cannot write output file");
  f << text << "\n";
}

void RunDetect(const DetectArgs& a) {
  if (!(a.tag_size > 0)) throw InputError("command line", "--tag-size", "must be a positive length in metres");
  const CameraModel camera = LoadCamera(a.camera, a.camera_name);
  const GrayImage image = ReadGrayImage(a.image);
  if (camera.width > 0 && camera.height > 0 && (camera.width != image.width || camera.height != image.height)) {
    throw InputError(a.image, "",
                     "image is " + std::to_string(image.width) + "x" + std::to_string(image.height) +
                         " but calibration " + a.camera + " is for " + std::to_string(camera.width) + "x" +
                         std::to_string(camera.height));
  }
  DetectorOptions d = a.detector;
  d.family = a.family;
  WriteOutput(DetectToJson(image.view(), camera, a.tag_size, d, a.pose), a.out);
}

}  // namespace

void RegisterCommands(CLI::App& app) {
  auto args = std::make_shared<DetectArgs>();
  CLI::App* detect = app.add_subcommand(
      "detect",
      "Detect AprilTags in one image and estimate their poses. Prints JSON: {\"image\": {\"width\", \"height\"}, "
      "\"detections\": [{\"id\", \"family\", \"corners\" (pixels, AprilTag order: corner 0 bottom-left of the printed "
      "tag, then counter-clockwise), \"pose\": {\"t\" (m), \"R\"} (tag in the camera frame, ViSP convention: x right, "
      "y up as printed, z out of the tag face), \"decision_margin\", \"hamming\", \"reprojection_error_px\", "
      "\"ambiguous\"}], \"rejected\"}.");
  detect->add_option("IMAGE", args->image, "image file (PGM, PNG, JPEG, ...)")->required();
  detect->add_option("--camera", args->camera, "calibration: ViSP XML (.xml) or OpenCV YAML (.yaml/.yml)")->required();
  detect->add_option("--camera-name", args->camera_name, "camera to use in a multi-camera ViSP XML file");
  detect->add_option("--tag-size", args->tag_size, "tag size in metres: the black border's outer edge")->required();
  detect->add_option("--family", args->family, "tag family")->capture_default_str();
  detect->add_option("--out", args->out, "write the JSON to this file instead of stdout");
  detect->add_option("--decimate", args->detector.quad_decimate, "quad decimation (1: full resolution)")
      ->capture_default_str();
  detect->add_option("--min-margin", args->detector.min_decision_margin, "reject decodes below this decision margin")
      ->capture_default_str();
  detect->add_option("--max-hamming", args->detector.max_hamming, "reject decodes with more corrected bits")
      ->capture_default_str();
  detect
      ->add_option("--max-reprojection-error", args->pose.max_rms_error_px,
                   "reject poses whose RMS reprojection error (pixels) exceeds this")
      ->capture_default_str();
  detect->callback([args] { RunDetect(*args); });
}

}  // namespace visco::vision

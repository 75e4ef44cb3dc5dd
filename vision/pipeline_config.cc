#include "vision/pipeline_config.h"

#include <CLI/CLI.hpp>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "common/error.h"
#include "vision/tag_detector.h"

namespace visco::vision {
namespace {

using Json = nlohmann::json;

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "", "object-model file does not exist or cannot be read");
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void BuildOptions(LoadedPipeline& p, const Extrinsics& extrinsics) {
  const PipelineConfig& c = p.config;
  PipelineOptions& po = p.options;
  po.camera_name = p.camera.name.empty() ? "camera" : p.camera.name;
  po.detector.quad_sigma = c.quad_sigma;
  po.noise.corner_sigma_px = c.corner_sigma;
  po.noise.extrinsics_covariance = extrinsics.covariance;  // zero without `wMc.stddev`: exact
  po.tracker.full_detection_every = c.full_every;
  if (!(c.decimate >= 1)) throw InputError("command line", "--decimate", "must be >= 1 (1: full resolution)");
  po.detector.quad_decimate = c.decimate;
  if (c.mode == "roi") {
    po.tracker.mode = TagTrackingMode::kRoiDetection;
  } else if (c.mode == "klt") {
    po.tracker.mode = TagTrackingMode::kKltCorners;
  } else if (c.mode == "mbt") {
    po.tracker.mode = TagTrackingMode::kModelBased;
  } else if (c.mode == "detect") {
    po.tracker.mode = TagTrackingMode::kDetectEveryFrame;
  } else {
    throw InputError("command line", "--mode", "must be roi, mbt, klt or detect, not '" + c.mode + "'");
  }
  for (const auto& t : p.models.robot.tags) CheckFamilyName(t.family);
}

}  // namespace

void AddPipelineConfigOptions(CLI::App& cmd, PipelineConfig& c, ConfigDefaults defaults) {
  const std::string calibration = defaults == ConfigDefaults::kLog   ? " (default: the log's VISCO_CAMERA_INFO)"
                                  : defaults == ConfigDefaults::kBus ? " (with --lcm, default: VISCO_CAMERA_INFO's)"
                                                                     : "";
  const std::string objects_from = defaults == ConfigDefaults::kLog ? " (default: the log's VISCO_VISION_CONFIG)" : "";
  CLI::Option* camera =
      cmd.add_option("--camera", c.camera, "calibration: ViSP XML, OpenCV YAML or ROS YAML" + calibration);
  cmd.add_option("--camera-name", c.camera_name, "camera in a multi-camera ViSP XML file");
  CLI::Option* extrinsics =
      cmd.add_option("--extrinsics", c.extrinsics, "camera pose in the world (JSON, wMc)" + calibration);
  CLI::Option* objects = cmd.add_option("--objects", c.objects,
                                        "object models: robot, obstacles, tags, event pairs (JSON)" + objects_from);
  if (defaults == ConfigDefaults::kNone) {
    camera->required();
    extrinsics->required();
  }
  if (defaults != ConfigDefaults::kLog) objects->required();
  auto given = [&c](const char* name) { return [&c, name](const std::string&) { c.given.insert(name); }; };
  cmd.add_option("--mode", c.mode,
                 "tag tracking between full detections: roi, klt or detect; mbt: roi, and the robot's pose from ViSP's "
                 "model-based tracker on its edges")
      ->capture_default_str()
      ->each(given("mode"));
  cmd.add_option("--full-every", c.full_every, "frames between full detections")
      ->capture_default_str()
      ->each(given("full_every"));
  cmd.add_option("--decimate", c.decimate,
                 "full detections find the tags' quads in an image this many times smaller (AprilTag's quad "
                 "decimation; the corners refined at full resolution): about 3x faster at 2, for tags of 40 px and "
                 "more (1: full resolution)")
      ->capture_default_str()
      ->each(given("decimate"));
  cmd.add_option("--quad-sigma", c.quad_sigma, "AprilTag segmentation blur (0.8 for noisy images)")
      ->capture_default_str()
      ->each(given("quad_sigma"));
  cmd.add_option("--corner-sigma", c.corner_sigma, "initial corner noise, pixels (then estimated online)")
      ->capture_default_str()
      ->each(given("corner_sigma"));
}

LoadedPipeline LoadPipelineConfig(const PipelineConfig& c) {
  std::vector<std::string> mismatches, from_log;
  return ResolvePipelineConfig(c, "", std::nullopt, "command line", mismatches, from_log);
}

std::string VisionConfigToJson(const LoadedPipeline& p) {
  Json j;
  try {
    j["objects"] = Json::parse(p.objects_json);
  } catch (const Json::exception&) {
    j["objects"] = p.objects_json;  // not reached: the text was parsed when loaded
  }
  j["options"] = {{"mode", p.config.mode},
                  {"full_every", p.config.full_every},
                  {"decimate", p.config.decimate},
                  {"quad_sigma", p.config.quad_sigma},
                  {"corner_sigma", p.config.corner_sigma}};
  j["files"] = {{"camera", p.config.camera}, {"extrinsics", p.config.extrinsics}, {"objects", p.config.objects}};
  j["calibration_source"] = p.calibration.source;
  return j.dump();
}

std::string VisionConfigCalibrationSource(const std::string& json) {
  try {
    const Json j = Json::parse(json);
    return j.is_object() && j.contains("calibration_source") && j["calibration_source"].is_string()
               ? j["calibration_source"].get<std::string>()
               : "";
  } catch (const Json::exception&) {
    return "";
  }
}

LoadedPipeline ResolvePipelineConfig(const PipelineConfig& c, const std::string& recorded_json,
                                     const std::optional<CameraCalibration>& recorded_calibration,
                                     const std::string& source, std::vector<std::string>& mismatches,
                                     std::vector<std::string>& from_log) {
  Json rec;
  const bool have = !recorded_json.empty();
  if (have) {
    try {
      rec = Json::parse(recorded_json);
    } catch (const Json::exception& e) {
      throw InputError(source, "vision configuration", std::string("not JSON: ") + e.what());
    }
    for (const char* key : {"objects", "options"}) {
      if (!rec.is_object() || !rec.contains(key)) {
        throw InputError(source, "vision configuration", std::string("no ") + key);
      }
    }
  }
  auto missing = [&](const char* option, const char* what) {
    return InputError("command line", option,
                      std::string("not given, and ") + source + " holds no " + what +
                          ": give --camera, --extrinsics and --objects as the live run had them");
  };
  LoadedPipeline p;
  p.config = c;
  // Calibration and the camera's pose: the files given, else VISCO_CAMERA_INFO's.
  Extrinsics extrinsics;
  if (!c.camera.empty()) {
    p.camera = LoadCamera(c.camera, c.camera_name);
  } else if (recorded_calibration) {
    p.camera = recorded_calibration->camera;
    from_log.push_back("camera");
  } else {
    throw missing("--camera", "calibration (VISCO_CAMERA_INFO)");
  }
  if (!c.extrinsics.empty()) {
    extrinsics = LoadExtrinsicsWithUncertainty(c.extrinsics);
  } else if (recorded_calibration && recorded_calibration->extrinsics) {
    extrinsics = *recorded_calibration->extrinsics;
    from_log.push_back("extrinsics");
  } else {
    throw missing("--extrinsics", "camera pose (VISCO_CAMERA_INFO with extrinsics)");
  }
  p.wMc = extrinsics.wMc;
  p.calibration.camera = p.camera;
  p.calibration.extrinsics = extrinsics;
  p.calibration_from_files = !c.camera.empty() || !c.extrinsics.empty();
  if (recorded_calibration && c.camera.empty() && c.extrinsics.empty()) {
    p.calibration.source = recorded_calibration->source;
  } else {
    p.calibration.source = "files: " + (c.camera.empty() ? std::string("(bus)") : c.camera) + ", " +
                           (c.extrinsics.empty() ? std::string("(bus)") : c.extrinsics);
  }
  if (recorded_calibration && p.calibration_from_files) {
    for (const std::string& d : CalibrationDifferences(p.calibration, "files", *recorded_calibration, source)) {
      mismatches.push_back("calibration: " + d);
    }
  }
  // Object models.
  if (!c.objects.empty()) {
    p.objects_json = ReadText(c.objects);
    p.models = ParseObjectModels(p.objects_json, c.objects);
    if (have) {
      Json given;
      try {
        given = Json::parse(p.objects_json);
      } catch (const Json::exception&) {
      }
      if (given != rec["objects"]) {
        mismatches.push_back("--objects " + c.objects + " differs from the live run's object models");
      }
    }
  } else if (have) {
    p.objects_json = rec["objects"].dump();
    p.models = ParseObjectModels(p.objects_json, source + ": vision configuration: objects");
    from_log.push_back("objects");
  } else {
    throw missing("--objects", "vision configuration (VISCO_VISION_CONFIG)");
  }
  // Options: given on the command line, else the recorded ones, else the defaults.
  if (have) {
    const Json& o = rec["options"];
    auto take = [&](const char* key, auto& value, const char* option) {
      if (!o.contains(key)) return;
      using T = std::decay_t<decltype(value)>;
      T recorded{};
      try {
        recorded = o[key].get<T>();
      } catch (const Json::exception& e) {
        throw InputError(source, std::string("vision configuration: options.") + key, e.what());
      }
      if (c.given.count(key) == 0) {
        if (!(value == recorded)) from_log.push_back(option);
        value = recorded;
      } else if (!(value == recorded)) {
        mismatches.push_back(std::string(option) + " " + Json(value).dump() + " differs from the live run's " +
                             Json(recorded).dump());
      }
    };
    take("mode", p.config.mode, "--mode");
    take("full_every", p.config.full_every, "--full-every");
    take("decimate", p.config.decimate, "--decimate");  // a log without it: full resolution, as vision had then
    take("quad_sigma", p.config.quad_sigma, "--quad-sigma");
    take("corner_sigma", p.config.corner_sigma, "--corner-sigma");
  }
  BuildOptions(p, extrinsics);
  return p;
}

}  // namespace visco::vision

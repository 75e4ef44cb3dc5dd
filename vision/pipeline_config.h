#pragma once
// The vision pipeline's configuration as the command line gives it: the files (calibration, extrinsics, object
// models) and the tracking options. `visco track` and `visco replay` take the same options through this, so that a
// replay runs the pipeline exactly as the live process did.

#include <optional>
#include <set>
#include <string>
#include <vector>

#include "vision/camera.h"
#include "vision/camera_info.h"
#include "vision/object_model.h"
#include "vision/pipeline.h"

namespace CLI {
class App;
}

namespace visco::vision {

struct PipelineConfig {
  std::string camera, camera_name, extrinsics, objects;
  std::string mode = "roi";
  int full_every = 30;
  float decimate = 1;  ///< full detections' quad decimation (AprilTag quad_decimate; corners refined at full size)
  float quad_sigma = 0;
  double corner_sigma = 0.3;
  std::set<std::string> given;  ///< the options of --mode, --full-every, --decimate, --quad-sigma, --corner-sigma given
};

/// Where the files' contents come from when they are not given.
enum class ConfigDefaults {
  kNone,  ///< --camera, --extrinsics and --objects are required
  kBus,   ///< `visco track --lcm`: the calibration and pose from VISCO_CAMERA_INFO (the objects are required)
  kLog,   ///< `visco replay`: all three from the log (VISCO_CAMERA_INFO, VISCO_VISION_CONFIG)
};

/// Adds --camera, --camera-name, --extrinsics, --objects, --mode, --full-every, --decimate, --quad-sigma and
/// --corner-sigma to
/// `command`. Not real-time safe.
void AddPipelineConfigOptions(CLI::App& command, PipelineConfig& config,
                              ConfigDefaults defaults = ConfigDefaults::kNone);

struct LoadedPipeline {
  CameraModel camera;
  Eigen::Isometry3d wMc = Eigen::Isometry3d::Identity();
  ObjectModels models;
  PipelineOptions options;   ///< options.noise.extrinsics_covariance: the extrinsics file's `wMc.stddev`
  std::string objects_json;  ///< the object models as their file had them (JSON text), to record in logs
  PipelineConfig config;     ///< the options and file names it was built from
  /// The calibration (camera and extrinsics) as it travels on VISCO_CAMERA_INFO; `calibration.source` names where
  /// it came from ("files: CAMERA, EXTRINSICS", or the camera process's own source).
  CameraCalibration calibration;
  bool calibration_from_files = true;
};

/// Loads the files and builds the pipeline options. @throws InputError naming the file and what is wrong.
LoadedPipeline LoadPipelineConfig(const PipelineConfig& config);

/// The channel and log_annotation_t kind of the vision configuration that `visco track` publishes beside its output
/// (at start and every second, so that a log cut anywhere holds it), for `visco replay` to run the same pipeline.
inline constexpr char kVisionConfigChannel[] = "VISCO_VISION_CONFIG";
inline constexpr char kVisionConfigKind[] = "vision_config";

/// The configuration but the calibration (which travels as camera_info_t on VISCO_CAMERA_INFO) as JSON text:
/// {"objects": (the object-model file's JSON), "options": {"mode", "full_every", "decimate", "quad_sigma",
/// "corner_sigma"},
/// "files": {"camera", "extrinsics", "objects"}, "calibration_source": the camera_info_t.source of the calibration
/// vision ran with}. Numbers are written so that they read back exactly.
std::string VisionConfigToJson(const LoadedPipeline& pipeline);

/// The `calibration_source` of a VisionConfigToJson text ("" if it has none or is not JSON).
std::string VisionConfigCalibrationSource(const std::string& json);

/// What a replay (or `visco track --lcm` without files) runs with: the files and options given in `config` win;
/// what is not given comes from the recorded configuration `recorded_json` (VisionConfigToJson's text; empty: none)
/// and the recorded calibration `recorded_calibration` (from VISCO_CAMERA_INFO; the camera's pose too, when it has
/// one). `mismatches` receives one line per thing given that differs from the recorded, `from_log` the names of what
/// was taken from the record.
/// @throws InputError(`source`, ...) when something is neither given nor recorded, or the record is malformed.
LoadedPipeline ResolvePipelineConfig(const PipelineConfig& config, const std::string& recorded_json,
                                     const std::optional<CameraCalibration>& recorded_calibration,
                                     const std::string& source, std::vector<std::string>& mismatches,
                                     std::vector<std::string>& from_log);

}  // namespace visco::vision

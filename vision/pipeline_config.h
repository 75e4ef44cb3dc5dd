#pragma once
// The vision pipeline's configuration as the command line gives it: the files (calibration, extrinsics, object
// models) and the tracking options. `visco track` and `visco replay` take the same options through this, so that a
// replay runs the pipeline exactly as the live process did.

#include <string>

#include "vision/camera.h"
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
  float quad_sigma = 0;
  double corner_sigma = 0.3;
};

/// Adds --camera, --camera-name, --extrinsics, --objects (required), --mode, --full-every, --quad-sigma and
/// --corner-sigma to `command`. Not real-time safe.
void AddPipelineConfigOptions(CLI::App& command, PipelineConfig& config);

struct LoadedPipeline {
  CameraModel camera;
  Eigen::Isometry3d wMc = Eigen::Isometry3d::Identity();
  ObjectModels models;
  PipelineOptions options;  ///< options.noise.extrinsics_covariance: the extrinsics file's `wMc.stddev`
};

/// Loads the files and builds the pipeline options. @throws InputError naming the file and what is wrong.
LoadedPipeline LoadPipelineConfig(const PipelineConfig& config);

}  // namespace visco::vision

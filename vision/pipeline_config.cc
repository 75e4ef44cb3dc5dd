#include "vision/pipeline_config.h"

#include <CLI/CLI.hpp>

#include "common/error.h"
#include "vision/tag_detector.h"

namespace visco::vision {

void AddPipelineConfigOptions(CLI::App& cmd, PipelineConfig& c) {
  cmd.add_option("--camera", c.camera, "calibration: ViSP XML or OpenCV YAML")->required();
  cmd.add_option("--camera-name", c.camera_name, "camera in a multi-camera ViSP XML file");
  cmd.add_option("--extrinsics", c.extrinsics, "camera pose in the world (JSON, wMc)")->required();
  cmd.add_option("--objects", c.objects, "object models: robot, obstacles, tags, event pairs (JSON)")->required();
  cmd.add_option("--mode", c.mode,
                 "tag tracking between full detections: roi, klt or detect; mbt: roi, and the robot's pose from ViSP's "
                 "model-based tracker on its edges")
      ->capture_default_str();
  cmd.add_option("--full-every", c.full_every, "frames between full detections")->capture_default_str();
  cmd.add_option("--quad-sigma", c.quad_sigma, "AprilTag segmentation blur (0.8 for noisy images)")
      ->capture_default_str();
  cmd.add_option("--corner-sigma", c.corner_sigma, "initial corner noise, pixels (then estimated online)")
      ->capture_default_str();
}

LoadedPipeline LoadPipelineConfig(const PipelineConfig& c) {
  LoadedPipeline p;
  p.camera = LoadCamera(c.camera, c.camera_name);
  const Extrinsics extrinsics = LoadExtrinsicsWithUncertainty(c.extrinsics);
  p.wMc = extrinsics.wMc;
  p.models = LoadObjectModels(c.objects);
  PipelineOptions& po = p.options;
  po.camera_name = p.camera.name.empty() ? "camera" : p.camera.name;
  po.detector.quad_sigma = c.quad_sigma;
  po.noise.corner_sigma_px = c.corner_sigma;
  po.noise.extrinsics_covariance = extrinsics.covariance;  // zero without `wMc.stddev`: exact
  po.tracker.full_detection_every = c.full_every;
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
  return p;
}

}  // namespace visco::vision

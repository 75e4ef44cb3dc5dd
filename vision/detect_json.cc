#include "vision/detect_json.h"

#include <nlohmann/json.hpp>

namespace visco::vision {

DetectResult DetectTags(const GrayImageView& image, const CameraModel& camera, double tag_size,
                        const DetectorOptions& detector_options, const PoseOptions& pose_options) {
  TagDetector detector(detector_options);
  DetectResult r;
  r.width = image.width;
  r.height = image.height;
  for (auto& tag : detector.Detect(image)) {
    auto pose = EstimateTagPose(camera, tag.corners, tag_size, pose_options);
    r.tags.push_back({std::move(tag), std::move(pose)});
  }
  r.rejected_decodes = detector.rejected_last();
  return r;
}

std::string DetectResultToJson(const DetectResult& result) {
  nlohmann::json out;
  out["image"] = {{"width", result.width}, {"height", result.height}};
  out["detections"] = nlohmann::json::array();
  int rejected = result.rejected_decodes;
  for (const auto& [tag, pose] : result.tags) {
    if (!pose) {
      ++rejected;
      continue;
    }
    nlohmann::json d;
    d["id"] = tag.id;
    d["family"] = tag.family;
    d["corners"] = nlohmann::json::array();
    for (const auto& c : tag.corners) d["corners"].push_back({c.x(), c.y()});
    const Eigen::Vector3d t = pose->cMo.translation();
    const Eigen::Matrix3d r = pose->cMo.linear();
    d["pose"]["t"] = {t.x(), t.y(), t.z()};
    d["pose"]["R"] = {{r(0, 0), r(0, 1), r(0, 2)}, {r(1, 0), r(1, 1), r(1, 2)}, {r(2, 0), r(2, 1), r(2, 2)}};
    d["decision_margin"] = tag.decision_margin;
    d["hamming"] = tag.hamming;
    d["reprojection_error_px"] = pose->rms_error_px;
    d["ambiguous"] = pose->ambiguous;
    out["detections"].push_back(std::move(d));
  }
  out["rejected"] = rejected;
  return out.dump(2);
}

std::string DetectToJson(const GrayImageView& image, const CameraModel& camera, double tag_size,
                         const DetectorOptions& detector_options, const PoseOptions& pose_options) {
  return DetectResultToJson(DetectTags(image, camera, tag_size, detector_options, pose_options));
}

}  // namespace visco::vision

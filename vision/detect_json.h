#pragma once
// `visco detect`: detections and poses of one image as the JSON of docs/formats.md.

#include <optional>
#include <string>
#include <vector>

#include "vision/camera.h"
#include "vision/image.h"
#include "vision/tag_detector.h"

namespace visco::vision {

/// One decoded tag of `visco detect` and its pose; no pose: rejected by the pose stage (reprojection error above the
/// limit, degenerate corners).
struct DetectedTag {
  TagObservation tag;
  std::optional<TagPose> pose;
};

/// Everything `visco detect` found in one image.
struct DetectResult {
  int width = 0, height = 0;
  std::vector<DetectedTag> tags;  ///< sorted by id
  int rejected_decodes = 0;       ///< decodes rejected by the detector (margin, hamming)
};

/// Runs detection and pose estimation on `image`.
DetectResult DetectTags(const GrayImageView& image, const CameraModel& camera, double tag_size,
                        const DetectorOptions& detector_options, const PoseOptions& pose_options);

/// The docs/formats.md JSON text (pretty-printed) of a result: {"image": {"width", "height"}, "detections": [{"id",
/// "family", "corners", "pose": {"t", "R"}, "decision_margin", "hamming", "reprojection_error_px", "ambiguous"}],
/// "rejected"}. Tags without a pose are left out and counted in "rejected" with the detector's rejections.
std::string DetectResultToJson(const DetectResult& result);

/// DetectTags then DetectResultToJson.
std::string DetectToJson(const GrayImageView& image, const CameraModel& camera, double tag_size,
                         const DetectorOptions& detector_options, const PoseOptions& pose_options);

}  // namespace visco::vision

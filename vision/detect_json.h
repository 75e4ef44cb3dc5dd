#pragma once
// `visco detect`: detections and poses of one image as the JSON of docs/formats.md.

#include <string>

#include "vision/camera.h"
#include "vision/image.h"
#include "vision/tag_detector.h"

namespace visco::vision {

/// Runs detection and pose estimation on `image` and returns the docs/formats.md JSON text (pretty-printed):
/// {"image": {"width", "height"}, "detections": [{"id", "family", "corners", "pose": {"t", "R"},
/// "decision_margin", "hamming", "reprojection_error_px", "ambiguous"}]}. Detections whose pose is rejected
/// (reprojection error above the limit, degenerate corners) are left out and counted in "rejected".
std::string DetectToJson(const GrayImageView& image, const CameraModel& camera, double tag_size,
                         const DetectorOptions& detector_options, const PoseOptions& pose_options);

}  // namespace visco::vision

#pragma once
// The calibration channel (VISCO_CAMERA_INFO, visco::camera_info_t): the one codec between the message and vision's
// CameraModel and Extrinsics, and the comparison that reports where a calibration given in files differs from the one
// on the bus or in a log.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "visco/camera_info_t.hpp"
#include "vision/camera.h"

namespace visco::vision {

/// A camera's calibration as it travels beside its images.
struct CameraCalibration {
  CameraModel camera;
  std::optional<Extrinsics> extrinsics;  ///< the camera's pose in the world, when known
  std::string source;                    ///< where it was loaded from (file names), for messages
};

/// The message for `calibration`, published at `utime` (microseconds since the epoch). The pose and the numbers
/// travel bit for bit: DecodeCameraInfo gives back the same doubles.
visco::camera_info_t EncodeCameraInfo(const CameraCalibration& calibration, std::int64_t utime);

/// The calibration in `message`. `where` names its origin in errors (a channel, or a log file and its event).
/// @throws InputError(where, "camera_info 'NAME'", ...) for an unusable message: a focal length that is not positive,
///         a distortion model or number of coefficients that do not match, a negative image size, a rotation that is
///         not one, a non-finite number, a covariance that is not symmetric with a non-negative diagonal.
CameraCalibration DecodeCameraInfo(const visco::camera_info_t& message, const std::string& where);

/// Where calibrations `a` and `b` differ, one line each, naming them by `a_label` and `b_label` (e.g. "files",
/// "VISCO_CAMERA_INFO"): "px: 600 (files) vs 601 (VISCO_CAMERA_INFO)"; empty when they are the same. Numbers are
/// compared exactly (the channel carries them bit for bit). Names are compared only when both are set; extrinsics
/// that only one has give "extrinsics: only in ...".
std::vector<std::string> CalibrationDifferences(const CameraCalibration& a, const std::string& a_label,
                                                const CameraCalibration& b, const std::string& b_label);

}  // namespace visco::vision

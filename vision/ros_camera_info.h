#pragma once
// ROS camera_info YAML: the calibration file ROS's camera_calibration writes (ost.yaml) and usb_cam and other ROS
// camera drivers read (camera_info_url). OpenCV's FileStorage refuses it (no `%YAML:1.0` header, plain `rows`/`cols`/
// `data` maps instead of `!!opencv-matrix`), so it is read with yaml-cpp, which stays inside the .cc file.

#include <string>

#include "vision/camera.h"

namespace visco::vision {

/// Whether the YAML file at `path` is ROS camera_info rather than OpenCV FileStorage: it is unless it starts with
/// OpenCV's `%YAML:` directive or holds an `!!opencv-matrix`.
bool IsRosCameraInfo(const std::string& path);

/// Reads a ROS camera_info YAML file: `image_width`, `image_height` (required), `camera_name` (optional),
/// `camera_matrix` (required, {rows: 3, cols: 3, data: [9 numbers]}, no skew), `distortion_model` (`plumb_bob`
/// with 0, 4 or 5 coefficients, or `rational_polynomial` with 8; `equidistant` (fisheye) is refused: the camera
/// model has no fisheye lens), `distortion_coefficients` ({rows: 1, cols: n, data: [n numbers]}),
/// `rectification_matrix` (3x3 rotation) and `projection_matrix` (3x4), both optional and checked for shape only:
/// vision works on the raw images, which K and D describe. Unknown keys are refused (a misspelt key is an error,
/// not a camera without distortion).
/// @throws InputError naming the file, the field and what is wrong.
CameraModel LoadRosCameraInfo(const std::string& path);

/// Writes `camera` as ROS camera_info YAML (identity rectification, P = [K 0]), as camera_calibration does.
/// @throws JobFailed if the file cannot be written or the camera has ViSP's distortion model.
void SaveCameraRos(const CameraModel& camera, const std::string& path);

}  // namespace visco::vision

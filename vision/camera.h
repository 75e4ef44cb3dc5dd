#pragma once
// The calibrated pinhole camera of the runtime: intrinsics, lens distortion and the camera pose in the world.
// Loaded from ViSP's XML (vpXmlParserCamera), OpenCV's YAML or ROS's camera_info YAML calibration files; no OpenCV or
// ViSP type appears here. Frames follow ViSP: cMo is the pose of frame o in frame c; the camera frame has x right, y
// down, z along the optical axis; the world has z up, the motion plane (the table) is z = 0.

#include <Eigen/Geometry>
#include <array>
#include <string>
#include <vector>

#include "common/extrinsics.h"

namespace visco::vision {

/// Lens distortion model of a calibration.
enum class DistortionModel {
  kNone,    ///< ideal pinhole
  kViSP,    ///< ViSP's one-coefficient radial model: kud (undistorted to distorted) and kdu (distorted to undistorted)
  kOpenCV,  ///< OpenCV's Brown-Conrady model: k1, k2, p1, p2[, k3[, k4, k5, k6]]
};

/// Intrinsics and distortion of one camera. Pixels: u to the right, v down, (0, 0) the centre of the top-left pixel
/// (the convention of ViSP, OpenCV and the AprilTag library).
struct CameraModel {
  std::string name;       ///< camera name from the calibration file (may be empty)
  int width = 0;          ///< image width in pixels (0: not given in the file)
  int height = 0;         ///< image height in pixels (0: not given in the file)
  double px = 0, py = 0;  ///< focal lengths in pixels (ViSP's px, py; OpenCV's fx, fy)
  double u0 = 0, v0 = 0;  ///< principal point in pixels
  DistortionModel distortion = DistortionModel::kNone;
  double kud = 0, kdu = 0;   ///< ViSP model coefficients
  std::vector<double> dist;  ///< OpenCV model coefficients (4, 5 or 8 values)

  /// A camera without distortion. @throws InputError("camera", ...) if a focal length is not positive.
  static CameraModel Pinhole(double px, double py, double u0, double v0, int width = 0, int height = 0);

  /// Pixel (distorted, as observed) to normalized image coordinates (x = X/Z, y = Y/Z, undistorted).
  Eigen::Vector2d PixelToNormalized(const Eigen::Vector2d& uv) const;
  /// Normalized image coordinates to the pixel where a real (distorted) camera observes them.
  Eigen::Vector2d NormalizedToPixel(const Eigen::Vector2d& xy) const;
  /// Normalized coordinates to ideal (undistorted) pixels: u = u0 + px x, v = v0 + py y.
  Eigen::Vector2d NormalizedToIdealPixel(const Eigen::Vector2d& xy) const {
    return {u0 + px * xy.x(), v0 + py * xy.y()};
  }
  /// Projects a point given in the camera frame (metres, Z > 0) to observed pixels.
  Eigen::Vector2d Project(const Eigen::Vector3d& c_p) const {
    return NormalizedToPixel({c_p.x() / c_p.z(), c_p.y() / c_p.z()});
  }
  /// Projects a point in the camera frame to ideal (undistorted) pixels.
  Eigen::Vector2d ProjectIdeal(const Eigen::Vector3d& c_p) const {
    return NormalizedToIdealPixel({c_p.x() / c_p.z(), c_p.y() / c_p.z()});
  }
};

/// Loads a calibration: ViSP XML (`.xml`), OpenCV YAML/XML FileStorage (`.yaml`, `.yml`, `.json`, or an XML file
/// whose root is `opencv_storage`) or ROS camera_info YAML (`.yaml`, `.yml` without OpenCV's `%YAML:` header or
/// `!!opencv-matrix`: vision/ros_camera_info.h). For ViSP XML, the model with distortion is preferred when both are
/// present; `camera_name` selects a camera in a multi-camera file (empty: the first).
/// @throws InputError naming the file, the missing or bad entry and what is wrong (missing file, unparsable file,
///         no camera, non-positive focal length, wrong number of distortion coefficients, non-finite values).
CameraModel LoadCamera(const std::string& path, const std::string& camera_name = "");

/// Writes `camera` as a ViSP XML calibration (for tools and tests). @throws JobFailed if the file cannot be written.
void SaveCameraViSP(const CameraModel& camera, const std::string& path);
/// Writes `camera` as an OpenCV YAML calibration (camera_matrix, distortion_coefficients, image_width,
/// image_height). @throws JobFailed if the file cannot be written.
void SaveCameraOpenCV(const CameraModel& camera, const std::string& path);

/// Camera extrinsics (common/extrinsics.h: the file format, one reader for vision and control).
using visco::Extrinsics;
using visco::LoadExtrinsics;
using visco::LoadExtrinsicsWithUncertainty;
using visco::RotationFromRpy;

/// Writes extrinsics in the format LoadExtrinsics reads. @throws JobFailed if the file cannot be written.
void SaveExtrinsics(const Eigen::Isometry3d& wMc, const std::string& path);

/// Camera pose in the world from one observation of a tag whose world pose is known (a tag lying on the work table):
/// wMc = wMt * cMt^-1.
inline Eigen::Isometry3d ExtrinsicsFromTableTag(const Eigen::Isometry3d& wMt, const Eigen::Isometry3d& cMt) {
  return wMt * cMt.inverse();
}

}  // namespace visco::vision

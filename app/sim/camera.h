#pragma once
// The rendered camera of `visco sim`: draws the scene's AprilTag-carrying objects (the robot at its true position,
// the obstacles fixed) through a calibrated camera with vision's tag renderer (real tag36h11 code bitmaps, OpenCV
// blur and noise) and packs the picture into an LCM image_t, the message a real camera publishes on
// VISCO_CAMERA_IMAGE. The object models, calibration and extrinsics are the very files `visco track` reads, so the
// real vision pipeline sees what it would see from a camera. Not real-time code (allocates). The table and the
// obstacles are rendered once (vision::CachedRenderer); a frame re-renders only around the robot, then blur and noise
// (a few ms per 640x480 frame; tests/bench/vision/render_benchmark.cc).
// No OpenCV or vision type appears here.

#include <cstdint>
#include <memory>
#include <string>

#include "control/servo_law.h"
#include "control/types.h"
#include "visco/image_t.hpp"

namespace visco::sim {

struct RenderedCameraConfig {
  std::string calibration_path;  // ViSP XML or OpenCV YAML (vision::LoadCamera), with the image size
  std::string camera_name;       // camera in a multi-camera calibration file ("" = the first)
  std::string extrinsics_path;   // JSON wMc (vision::LoadExtrinsics)
  std::string objects_path;      // vision's object models: robot and obstacles with their tags
  double blur_sigma_px = 0.0;    // Gaussian blur after rendering
  double noise_gray = 0.0;       // 1-sigma additive Gaussian noise, grey levels
  int supersample = 2;           // sub-samples per pixel side (anti-aliasing)
  std::uint64_t seed = 1;        // image noise seed (frame k uses seed + k: deterministic per frame)
  int png_level = -1;            // >= 0: publish PNG (lossless, zlib level 0..9) instead of raw grey
};

/// Frame-by-frame conditions the simulation can impose.
struct CaptureConditions {
  bool robot_occluded = false;  // something hides the robot: neither its body nor its tags are drawn
};

/// The servo law's calibrated camera (servo_law.h) from the rendered camera's files, through vision's loaders (any
/// calibration format vision reads): what `visco run --camera --extrinsics --objects` derives. @throws InputError.
control::ServoCamera ServoCameraFromFiles(const RenderedCameraConfig& config);

class RenderedCamera {
 public:
  /// Loads the calibration, extrinsics and object models. The robot's object frame is the scene's robot frame
  /// (origin = reference point, no rotation); the obstacles' object frames are the world frame (their polygons are
  /// world coordinates, as in the scene file).
  /// @throws InputError naming the file and object (missing image size, bad models, unknown tag family or id).
  explicit RenderedCamera(const RenderedCameraConfig& config);
  ~RenderedCamera();
  RenderedCamera(const RenderedCamera&) = delete;
  RenderedCamera& operator=(const RenderedCamera&) = delete;

  /// Renders the scene with the robot's reference point at `q` (metres) and fills `image` (GRAY8, or PNG with
  /// png_level >= 0; row_stride =
  /// width). `utime`/`seq` go into the message unchanged. Not thread-safe (the renderer's cache).
  void Capture(control::Vec2 q, std::int64_t utime, std::int64_t seq, const CaptureConditions& conditions,
               image_t& image);

  int width() const;
  int height() const;
  const std::string& camera_name() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace visco::sim

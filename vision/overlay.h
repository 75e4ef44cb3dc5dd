#pragma once
// Pictures of what vision saw, so that a user sees at once why an event fired or did not: the input image with the
// detections and their ids, the windows the tracker searched, the objects' prisms at their estimated poses, the
// robot's CM vertices, the VC lines, the signed distances, the events as they fire and the faults drawn over it, the
// way ViSP's displays show a tracker (coloured crosses, lines, text). `visco detect --overlay PNG` and `visco track
// --overlay OUT`; what each colour and mark means: docs/vision.md, "Overlays". Drawn with OpenCV inside overlay.cc;
// no OpenCV or ViSP type appears here.

#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "vision/camera.h"
#include "vision/detect_json.h"
#include "vision/features.h"
#include "vision/image.h"
#include "vision/object_model.h"
#include "vision/pipeline.h"

namespace visco::vision {

/// An 8-bit colour, blue, green, red (OpenCV's order).
struct Bgr {
  std::uint8_t b = 0, g = 0, r = 0;
  friend bool operator==(const Bgr& x, const Bgr& y) { return x.b == y.b && x.g == y.g && x.r == y.r; }
  friend bool operator!=(const Bgr& x, const Bgr& y) { return !(x == y); }
};

/// What each colour means (docs/vision.md, "Overlays").
namespace overlay_color {
inline constexpr Bgr kTag{0, 255, 0};              ///< green: a tag's border (it gave a pose); a cross on corner 0
inline constexpr Bgr kTagId{0, 0, 255};            ///< red: the tag's id, above its top-left
inline constexpr Bgr kTagUnused{0, 165, 255};      ///< orange: decoded but no pose (rejected, no model tag, outlier)
inline constexpr Bgr kLost{0, 0, 255};             ///< red: a tag lost since the last frame (X at its last place)
inline constexpr Bgr kRoi{255, 0, 0};              ///< blue: a window the tracker searched (ROI detection)
inline constexpr Bgr kRobotModel{255, 255, 0};     ///< cyan: the robot's prism at its estimated pose
inline constexpr Bgr kObstacleModel{255, 0, 128};  ///< purple: an obstacle's prism at its estimated pose
inline constexpr Bgr kCmVertex{255, 0, 255};       ///< magenta: a CM vertex (cross, label cm<i>)
inline constexpr Bgr kVcLine{0, 255, 255};         ///< yellow: a VC line (label <obstacle>.v<j>)
inline constexpr Bgr kPositive{0, 255, 128};       ///< chartreuse: distance segment, state positive
inline constexpr Bgr kNegative{128, 0, 255};       ///< rose: distance segment, state negative
inline constexpr Bgr kOnLine{255, 255, 255};       ///< white: distance segment, state on the line
inline constexpr Bgr kEvent{0, 69, 255};           ///< orange-red: an event fired in this frame (ring, label)
inline constexpr Bgr kFault{0, 0, 255};            ///< red: a fault (text, and a border around the frame)
inline constexpr Bgr kCleared{0, 255, 0};          ///< green: a fault cleared (text)
inline constexpr Bgr kText{255, 255, 255};         ///< white: status text
}  // namespace overlay_color

/// Sizes of the marks, pixels.
struct OverlayMarks {
  static constexpr int kCmCrossHalf = 6;  ///< a CM vertex cross spans 2 * 6 + 1 pixels
  static constexpr int kEventRadius = 16;
  static constexpr int kEventThickness = 3;
  static constexpr int kFaultBorder = 4;
};

/// A colour picture, 3 bytes per pixel (blue, green, red), row-major.
struct ColorImage {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> bgr;
  Bgr at(int u, int v) const {
    const std::size_t i = 3 * (static_cast<std::size_t>(v) * static_cast<std::size_t>(width) + u);
    return {bgr[i], bgr[i + 1], bgr[i + 2]};
  }
};

/// `visco detect`'s picture: each tag's border (green, a cross on corner 0; orange without a pose) and id, and its
/// pose as a frame (x red, y green, z blue, half the tag size long), as vpDisplay::displayFrame draws it.
ColorImage DrawDetectOverlay(const GrayImageView& image, const CameraModel& camera, double tag_size,
                             const DetectResult& result);

/// Checks a `visco detect --overlay` path before any work: a picture extension OpenCV writes (.png, .jpg, .jpeg,
/// .bmp, .ppm, .tif, .tiff) in a folder that exists. @throws InputError(path, "", what is wrong).
void CheckOverlayImagePath(const std::string& path);
/// Writes a picture (format from the extension). @throws InputError(path, "", ...) if it cannot be written.
void WriteOverlayImage(const ColorImage& image, const std::string& path);

/// `visco track`'s pictures, one per frame. Keeps what it needs from frame to frame (the last tags' corners, to mark
/// a lost tag where it was). Not thread-safe; call it on the pipeline thread (PipelineThread::SetFrameCallback).
class TrackOverlay {
 public:
  TrackOverlay(const CameraModel& camera, const Eigen::Isometry3d& wMc, const ObjectModels& models);
  /// The picture of one pull: a processed frame with everything the pipeline found in it (`features`: the
  /// pipeline's FeatureEstimator::last() for this frame), or, when `out.processed` is false, a black frame of the
  /// stream's size with the faults that say why (a frame that could not be read has no picture).
  ColorImage Draw(const Frame& frame, const PipelineOutput& out, const FrameFeatures& features);

 private:
  CameraModel camera_;
  Eigen::Isometry3d wMc_;
  ObjectModels models_;
  int width_ = 0, height_ = 0;                             // of the last picture
  std::map<int, std::vector<Eigen::Vector2d>> last_tags_;  // id -> corners (pixels) in the last processed frame
};

/// Where `visco track --overlay` pictures go: a video file (.avi and .mkv: Motion JPEG; .mp4: MPEG-4 part 2, OpenCV's
/// FFmpeg back-end) or a folder of PNG files named by their position in the stream (000000.png, 000001.png, ...;
/// a path without extension or an existing folder; created if missing).
class OverlayWriter {
 public:
  /// Checks the path (known extension, its folder exists and is writable) before the stream starts.
  /// @throws InputError(path, "", what is wrong).
  OverlayWriter(const std::string& path, double fps);
  ~OverlayWriter();
  OverlayWriter(const OverlayWriter&) = delete;
  OverlayWriter& operator=(const OverlayWriter&) = delete;
  /// Opens a video for pictures of this size (done by the first Write otherwise). @throws InputError.
  void Open(int width, int height);
  /// Appends one picture (a video resizes it to its size if it differs). @throws InputError if it cannot be written.
  void Write(const ColorImage& image);
  /// Finishes the video (also done by the destructor).
  void Close();
  std::int64_t frames() const;
  bool is_folder() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace visco::vision

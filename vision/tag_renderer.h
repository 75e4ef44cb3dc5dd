#pragma once
// A synthetic camera: renders AprilTags (real code bitmaps from the AprilTag library's family tables) and flat
// polygons (table, prism faces of the robot and the obstacles) at known poses through a calibrated camera, with
// optional blur and noise. Used by the tests as ground truth and by the simulated camera of the real-time loop.
// Plain types only (Eigen, std); no OpenCV or AprilTag type leaks out.
//
// Pixel convention: pixel (u, v) covers [u - 0.5, u + 0.5) x [v - 0.5, v + 0.5), its centre at integer coordinates
// (as ViSP, OpenCV and the AprilTag library assume).

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "vision/camera.h"
#include "vision/image.h"

namespace visco::vision {

/// A tag's code as an image: `total_width` x `total_width` cells, row-major, 0 black / 255 white, as printed (row 0 at
/// the top). The black border is `width_at_border` cells wide; the tag size of poses is that border's outer edge.
struct TagBitmap {
  int total_width = 0;
  int width_at_border = 0;
  std::vector<std::uint8_t> cells;
  std::uint8_t at(int col, int row) const { return cells[static_cast<std::size_t>(row) * total_width + col]; }
};

/// The bitmap of tag `id` of `family`, built from the family's code table (bit positions and code bits).
/// @throws InputError for an unknown family or an id outside the family.
TagBitmap MakeTagBitmap(const std::string& family, int id);

/// A tag to draw: family, id, size (metres, black border's outer edge) and the tag frame in the world (ViSP
/// convention: x right, y up as printed, z out of the face).
struct RenderTag {
  std::string family = "tag36h11";
  int id = 0;
  double size = 0.05;
  Eigen::Isometry3d wMt = Eigen::Isometry3d::Identity();
};

/// A flat, convex or simple planar polygon in the world with a uniform grey level.
struct RenderPolygon {
  std::vector<Eigen::Vector3d> vertices;  ///< world frame, metres, coplanar, in order
  std::uint8_t gray = 128;
};

/// Everything in view.
struct RenderScene {
  std::vector<RenderPolygon> polygons;
  std::vector<RenderTag> tags;
};

/// Appends the faces of a vertical prism: `polygon` (object frame, metres, z = 0 base) extruded to `height`, placed
/// at wMo. Top face `top_gray`, sides `side_gray`.
void AddPrism(RenderScene& scene, const std::vector<Eigen::Vector2d>& polygon, double height,
              const Eigen::Isometry3d& wMo, std::uint8_t top_gray, std::uint8_t side_gray);

/// Rendering settings.
struct RenderOptions {
  std::uint8_t background = 90;  ///< grey where no surface is hit
  std::uint8_t black = 25;       ///< grey of the tags' black cells
  std::uint8_t white = 230;      ///< grey of the tags' white cells
  int supersample = 4;           ///< sub-samples per pixel side (anti-aliasing)
  double blur_sigma = 0;         ///< Gaussian blur (pixels) applied after rendering; 0 = none
  double noise_stddev = 0;       ///< additive Gaussian noise (grey levels) applied last
  std::uint32_t seed = 1;        ///< seed of the noise
};

/// Renders `scene` seen by `camera` (with its distortion) placed at wMc. The image size is camera.width x
/// camera.height. Deterministic for a given seed. Not real-time safe (allocates); ~10-40 ms for 640x480.
/// @throws InputError if the camera has no image size or a tag's family/id is unknown.
GrayImage Render(const CameraModel& camera, const Eigen::Isometry3d& wMc, const RenderScene& scene,
                 const RenderOptions& options = {});

/// Renders frame after frame a scene made of a fixed part (table, obstacles) and a moving part (the robot): byte for
/// byte what Render() draws of their union (the fixed polygons then the moving ones, the fixed tags then the moving
/// ones), noise and blur included, but faster. The fixed part alone is rendered once per camera pose and options;
/// each frame then casts rays only in the box of pixels the moving items can cover (plus the one-pixel ring of the
/// edge test) and re-blurs only the rows around it. The noise is drawn over the whole frame, as Render() draws it.
/// A change of wMc or of the options' background, black, white, supersample or blur_sigma re-renders the fixed part
/// (as slow as Render()); noise_stddev and seed may change every frame at no cost. Not thread-safe (the cache).
class CachedRenderer {
 public:
  /// @throws InputError if the camera has no image size or a tag's family/id in `fixed` is unknown.
  CachedRenderer(const CameraModel& camera, const RenderScene& fixed);
  ~CachedRenderer();
  CachedRenderer(const CachedRenderer&) = delete;
  CachedRenderer& operator=(const CachedRenderer&) = delete;

  /// The fixed part with `moving` seen by the camera placed at wMc. @throws InputError for an unknown tag in `moving`.
  GrayImage Render(const Eigen::Isometry3d& wMc, const RenderScene& moving, const RenderOptions& options = {});

  const CameraModel& camera() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace visco::vision

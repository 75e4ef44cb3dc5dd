#pragma once
// Which tags the camera should see: a tag of an object at a predicted pose is expected in the image only if it faces
// the camera, lies inside the image, is large enough to decode and is not hidden behind one of the scene's prisms
// (the object models' vertical prisms at their last poses, its own included). The tag tracker runs a full detection
// in every frame while an expected tag is missing, so a tag that cannot be seen must not be expected: a box's tag
// turned away from the camera, or one hidden behind a taller obstacle, would otherwise disable ROI tracking for good.

#include <Eigen/Geometry>
#include <vector>

#include "vision/camera.h"
#include "vision/object_model.h"

namespace visco::vision {

/// Why a tag is (not) expected in the image.
enum class TagVisibility {
  kVisible,
  kBehindCamera,  ///< a corner at or behind the camera's plane
  kTurnedAway,    ///< its face looks away from the camera (the camera is behind the tag's plane)
  kOutsideImage,  ///< a corner (with one cell of the white quiet zone around the black border) outside the image
  kTooSmall,      ///< its shortest side spans fewer than VisibilityOptions::min_cell_px per cell
  kOccluded,      ///< a corner or its centre is hidden behind a prism
};
const char* TagVisibilityName(TagVisibility v);

struct VisibilityOptions {
  /// A tag whose shortest projected side spans fewer pixels per cell (cells across the black border: 8 for
  /// tag36h11) is not expected to decode. At a grazing angle the side shrinks as the cosine of the angle. The value
  /// is measured: rendered tag36h11 tags from face-on to 70 degrees, blurred and noisy, are all detected from 1.45 px
  /// per cell (tests/vision/tag_size_limit_test.cc).
  double min_cell_px = 1.5;
  /// Points on a tag are moved this far (metres) along its normal before the line of sight to the camera is tested
  /// against the prisms, so that the face the tag is glued on does not hide it.
  double surface_offset = 1e-3;
};

/// A prism of the scene at a pose: `model`'s polygon extruded from z = 0 to its height, placed at wMo.
struct PlacedPrism {
  const ObjectModel* model = nullptr;
  Eigen::Isometry3d wMo = Eigen::Isometry3d::Identity();
};

/// True if the segment from `a_w` to `b_w` (world frame) passes through the inside or boundary of the prism.
bool SegmentHitsPrism(const Eigen::Vector3d& a_w, const Eigen::Vector3d& b_w, const PlacedPrism& prism);

/// Whether `tag` of an object at wMo is expected in the image of `camera` at wMc. `cells` is the number of cells
/// across the tag's black border (TagBitmap::width_at_border). Not real-time safe.
TagVisibility PredictTagVisibility(const CameraModel& camera, const Eigen::Isometry3d& wMc, const TagMount& tag,
                                   int cells, const Eigen::Isometry3d& wMo, const std::vector<PlacedPrism>& prisms,
                                   const VisibilityOptions& options = {});

}  // namespace visco::vision

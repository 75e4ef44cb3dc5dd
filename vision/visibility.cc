#include "vision/visibility.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "vision/tag_detector.h"

namespace visco::vision {
namespace {

double Cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

// Crossing number; points on the boundary may go either way (the segment test below catches them).
bool InsidePolygon(const Eigen::Vector2d& p, const std::vector<Eigen::Vector2d>& poly) {
  bool inside = false;
  for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const Eigen::Vector2d& a = poly[i];
    const Eigen::Vector2d& b = poly[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) && p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      inside = !inside;
    }
  }
  return inside;
}

bool OnSegment(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& p) {
  return std::min(a.x(), b.x()) <= p.x() && p.x() <= std::max(a.x(), b.x()) && std::min(a.y(), b.y()) <= p.y() &&
         p.y() <= std::max(a.y(), b.y());
}

bool SegmentsIntersect(const Eigen::Vector2d& p1, const Eigen::Vector2d& p2, const Eigen::Vector2d& q1,
                       const Eigen::Vector2d& q2) {
  const double d1 = Cross(q2 - q1, p1 - q1), d2 = Cross(q2 - q1, p2 - q1);
  const double d3 = Cross(p2 - p1, q1 - p1), d4 = Cross(p2 - p1, q2 - p1);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) return true;
  return (d1 == 0 && OnSegment(q1, q2, p1)) || (d2 == 0 && OnSegment(q1, q2, p2)) ||
         (d3 == 0 && OnSegment(p1, p2, q1)) || (d4 == 0 && OnSegment(p1, p2, q2));
}

}  // namespace

const char* TagVisibilityName(TagVisibility v) {
  switch (v) {
    case TagVisibility::kVisible:
      return "visible";
    case TagVisibility::kBehindCamera:
      return "behind_camera";
    case TagVisibility::kTurnedAway:
      return "turned_away";
    case TagVisibility::kOutsideImage:
      return "outside_image";
    case TagVisibility::kTooSmall:
      return "too_small";
    case TagVisibility::kOccluded:
      return "occluded";
  }
  return "unknown";
}

bool SegmentHitsPrism(const Eigen::Vector3d& a_w, const Eigen::Vector3d& b_w, const PlacedPrism& prism) {
  if (prism.model == nullptr || prism.model->polygon.size() < 3) return false;
  const Eigen::Isometry3d oMw = prism.wMo.inverse();
  const Eigen::Vector3d a = oMw * a_w, b = oMw * b_w;
  // The part of the segment between the prism's base (z = 0) and top (z = height).
  double t0 = 0, t1 = 1;
  const double dz = b.z() - a.z(), h = prism.model->height;
  if (dz == 0) {
    if (a.z() < 0 || a.z() > h) return false;
  } else {
    double ta = (0 - a.z()) / dz, tb = (h - a.z()) / dz;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta), t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  const Eigen::Vector2d p = (a + t0 * (b - a)).head<2>(), q = (a + t1 * (b - a)).head<2>();
  const auto& poly = prism.model->polygon;
  if (InsidePolygon(p, poly) || InsidePolygon(q, poly)) return true;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    if (SegmentsIntersect(p, q, poly[i], poly[(i + 1) % poly.size()])) return true;
  }
  return false;
}

TagVisibility PredictTagVisibility(const CameraModel& camera, const Eigen::Isometry3d& wMc, const TagMount& tag,
                                   int cells, const Eigen::Isometry3d& wMo, const std::vector<PlacedPrism>& prisms,
                                   const VisibilityOptions& options) {
  const Eigen::Isometry3d wMt = wMo * tag.oMt;
  const Eigen::Isometry3d cMt = wMc.inverse() * wMt;
  const std::array<Eigen::Vector3d, 4> corners = TagCornersInTagFrame(tag.size);
  std::array<Eigen::Vector3d, 4> c_corners;
  for (int k = 0; k < 4; ++k) {
    c_corners[k] = cMt * corners[k];
    if (!(c_corners[k].z() > 0)) return TagVisibility::kBehindCamera;
  }
  // Facing: the camera centre on the side of the tag's plane its face looks to.
  const Eigen::Vector3d normal_c = cMt.linear().col(2);
  if (normal_c.dot(-cMt.translation()) <= 0) return TagVisibility::kTurnedAway;
  // Inside the image with the quiet zone (one cell beyond the black border) and large enough to decode.
  const int n = std::max(cells, 1);
  const double cell = tag.size / n;
  std::array<Eigen::Vector2d, 4> uv;
  for (int k = 0; k < 4; ++k) {
    uv[k] = camera.Project(c_corners[k]);
    if (camera.width > 0 && camera.height > 0) {
      // The quiet zone's outer corner: one cell further out along the tag's diagonal.
      const Eigen::Vector2d o = camera.Project(cMt * (corners[k] * (1 + 2 * cell / tag.size)));
      const double m = 0.5;  // pixel (u, v) covers [u - 0.5, u + 0.5)
      if (o.x() < -m || o.y() < -m || o.x() > camera.width - 1 + m || o.y() > camera.height - 1 + m || uv[k].x() < -m ||
          uv[k].y() < -m || uv[k].x() > camera.width - 1 + m || uv[k].y() > camera.height - 1 + m) {
        return TagVisibility::kOutsideImage;
      }
    }
  }
  double side = 1e300;
  for (int k = 0; k < 4; ++k) side = std::min(side, (uv[(k + 1) % 4] - uv[k]).norm());
  if (side / n < options.min_cell_px) return TagVisibility::kTooSmall;
  // Not hidden: the lines of sight from the camera centre to the corners and the centre, just off the tag's face.
  const Eigen::Vector3d camera_w = wMc.translation();
  const Eigen::Vector3d offset = wMt.linear().col(2) * options.surface_offset;
  std::array<Eigen::Vector3d, 5> points;
  for (int k = 0; k < 4; ++k) points[k] = wMt * corners[k] + offset;
  points[4] = wMt.translation() + offset;
  for (const Eigen::Vector3d& p : points) {
    for (const PlacedPrism& prism : prisms) {
      if (SegmentHitsPrism(camera_w, p, prism)) return TagVisibility::kOccluded;
    }
  }
  return TagVisibility::kVisible;
}

}  // namespace visco::vision

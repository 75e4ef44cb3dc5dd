#include "planning/scene.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "common/error.h"

namespace visco::planning {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegree = kPi / 180.0;

// A unit direction from an angle in degrees, exact at multiples of 90 degrees (so that a field-of-view limit of
// 270 degrees is exactly straight down, as a user expects).
Vector DirectionFromDegrees(double degrees) {
  double r = std::fmod(degrees, 360.0);
  if (r < 0) r += 360.0;
  if (r == 0) return {1, 0};
  if (r == 90) return {0, 1};
  if (r == 180) return {-1, 0};
  if (r == 270) return {0, -1};
  return {std::cos(r * kDegree), std::sin(r * kDegree)};
}

}  // namespace

Camera MakePlanarCamera(const Point& center, double first_deg, double span_deg) {
  Camera camera;
  camera.center = center;
  camera.fov_first_rad = first_deg * kDegree;
  camera.fov_second_rad = (first_deg + span_deg) * kDegree;
  camera.fov_first = DirectionFromDegrees(first_deg);
  camera.fov_second = DirectionFromDegrees(first_deg + span_deg);
  return camera;
}

bool Camera::Sees(const Point& p) const {
  if (p == center) return false;
  const Point origin(0, 0);
  const Point first(fov_first), second(fov_second);
  return CrossSign(origin, first, center, p) >= 0 && CrossSign(center, p, origin, second) >= 0;
}

bool Camera::InView(const Point& p) const {
  if (!Sees(p)) return false;
  if (!pinhole) return true;
  const auto interval = ViewInterval(p, p);
  return interval.has_value();
}

std::optional<std::pair<double, double>> Camera::ViewInterval(const Point& from, const Point& to) const {
  double lo = 0, hi = 1;
  if (!pinhole) return std::make_pair(lo, hi);
  // Camera coordinates of the plane point from + s (to - from) are affine in s: c(s) = c0 + s c1. It is in view iff
  // z > 0 and margin <= u <= width - margin (likewise v), with u = px x / z + u0: each condition is affine in s once
  // multiplied by z > 0, so the set is an intersection of half-lines.
  const PinholeCamera& cam = *pinhole;
  const Eigen::Matrix3d cRw = cam.wMc.topLeftCorner<3, 3>().transpose();
  const Eigen::Vector3d w_t_c = cam.wMc.topRightCorner<3, 1>();
  const Eigen::Vector3d c0 = cRw * (Eigen::Vector3d(from.x(), from.y(), 0) - w_t_c);
  const Eigen::Vector3d c1 = cRw * Eigen::Vector3d(to.x() - from.x(), to.y() - from.y(), 0);
  // Keeps the s with a0 + s a1 >= 0.
  auto keep = [&](double a0, double a1) {
    if (a1 == 0) {
      if (a0 < 0) hi = -1;
      return;
    }
    const double root = -a0 / a1;
    if (a1 > 0) {
      lo = std::max(lo, root);
    } else {
      hi = std::min(hi, root);
    }
  };
  // z >= tiny (strictly in front; the pixel conditions below then bound the rest).
  const double tiny = 1e-9 * (c0.norm() + c1.norm());
  keep(c0.z() - tiny, c1.z());
  const double m = kImageMargin;
  // px x + (u0 - m) z >= 0 and (width - m - u0) z - px x >= 0; likewise for v.
  keep(cam.px * c0.x() + (cam.u0 - m) * c0.z(), cam.px * c1.x() + (cam.u0 - m) * c1.z());
  keep((cam.width - m - cam.u0) * c0.z() - cam.px * c0.x(), (cam.width - m - cam.u0) * c1.z() - cam.px * c1.x());
  keep(cam.py * c0.y() + (cam.v0 - m) * c0.z(), cam.py * c1.y() + (cam.v0 - m) * c1.z());
  keep((cam.height - m - cam.v0) * c0.z() - cam.py * c0.y(), (cam.height - m - cam.v0) * c1.z() - cam.py * c1.y());
  if (!(lo <= hi)) return std::nullopt;
  return std::make_pair(lo, hi);
}

Camera DerivePlanarCamera(const PinholeCamera& pinhole, const std::string& source, const std::string& object) {
  const Eigen::Matrix3d wRc = pinhole.wMc.topLeftCorner<3, 3>();
  const Eigen::Vector3d w_t_c = pinhole.wMc.topRightCorner<3, 1>();
  if (!(w_t_c.z() > 0)) {
    throw InputError(source, object, "the camera centre must lie above the motion plane (world z > 0)");
  }
  const Point foot(w_t_c.x(), w_t_c.y());
  // Image corners (pixel borders) -> world ray directions. A ray meets the plane z = 0 iff its direction has
  // d_z < 0; d_z is affine in (u, v), so the part of the image that sees the plane is the image rectangle clipped by
  // a half-plane: a convex polygon whose vertices are image corners and points on the horizon line.
  auto ray = [&](double u, double v) -> Eigen::Vector3d {
    return wRc * Eigen::Vector3d((u - pinhole.u0) / pinhole.px, (v - pinhole.v0) / pinhole.py, 1.0);
  };
  const double w = pinhole.width, h = pinhole.height;
  const std::vector<Eigen::Vector2d> corners = {{0, 0}, {w, 0}, {w, h}, {0, h}};
  std::vector<Eigen::Vector3d> seen;  // ray directions of the clipped polygon's vertices (d_z <= 0)
  for (std::size_t i = 0; i < corners.size(); ++i) {
    const Eigen::Vector2d& a = corners[i];
    const Eigen::Vector2d& b = corners[(i + 1) % corners.size()];
    const Eigen::Vector3d ra = ray(a.x(), a.y()), rb = ray(b.x(), b.y());
    if (ra.z() < 0) seen.push_back(ra);
    if ((ra.z() < 0) != (rb.z() < 0) && ra.z() != rb.z()) {
      const double t = ra.z() / (ra.z() - rb.z());
      const Eigen::Vector2d c = a + t * (b - a);
      seen.push_back(ray(c.x(), c.y()));
    }
  }
  if (seen.empty()) throw InputError(source, object, "the image does not see the motion plane (z = 0) at all");
  // Azimuths of these directions seen from the foot point. The footprint point of a ray C + s d has azimuth
  // atan2(d_y, d_x) from the foot point, for every s > 0 (horizon points: the limit s -> infinity).
  std::vector<double> azimuths;
  for (const Eigen::Vector3d& d : seen) {
    if (std::hypot(d.x(), d.y()) < 1e-12 * d.norm()) {
      throw InputError(source, object,
                       "the camera looks straight down at its own foot point; the planar camera model needs the "
                       "foot point outside the field of view");
    }
    azimuths.push_back(std::atan2(d.y(), d.x()));
  }
  // Smallest arc containing all azimuths: find the largest gap between consecutive sorted azimuths.
  std::sort(azimuths.begin(), azimuths.end());
  double best_gap = -1, first = 0;
  for (std::size_t i = 0; i < azimuths.size(); ++i) {
    const double next = i + 1 < azimuths.size() ? azimuths[i + 1] : azimuths[0] + 2 * kPi;
    if (next - azimuths[i] > best_gap) {
      best_gap = next - azimuths[i];
      first = next;
    }
  }
  const double span = 2 * kPi - best_gap;
  if (!(span > 1e-9) || span >= kPi) {
    throw InputError(source, object,
                     fmt::format("the image's footprint spans {:.1f} degrees around the camera's foot point; the "
                                 "planar camera model needs a field of view strictly between 0 and 180 degrees "
                                 "(tilt the camera so that it does not see below itself)",
                                 span / kDegree));
  }
  Camera camera = MakePlanarCamera(foot, std::remainder(first, 2 * kPi) / kDegree, span / kDegree);
  camera.pinhole = pinhole;
  camera.height = w_t_c.z();
  return camera;
}

int SourceEdgeIndex(const ScenePolygon& polygon, std::size_t i) {
  if (polygon.source_edge.size() == polygon.polygon.size()) return polygon.source_edge.at(i);
  const std::size_t n = polygon.source_index.size();
  const int here = polygon.source_index.at(i), next = polygon.source_index.at((i + 1) % n);
  return next == (here + 1) % static_cast<int>(n) ? here : next;
}

}  // namespace visco::planning

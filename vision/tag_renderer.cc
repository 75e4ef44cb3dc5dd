#include "vision/tag_renderer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "common/error.h"

namespace visco::vision {
namespace {

// One planar item in the scene, with what is needed to intersect a ray and look up its grey level.
struct Item {
  Eigen::Vector3d origin;             // a point of the plane (world)
  Eigen::Vector3d e1, e2, normal;     // orthonormal in-plane axes and normal (world)
  std::vector<Eigen::Vector2d> poly;  // polygon in (e1, e2) coordinates (polygons only)
  const TagBitmap* bitmap = nullptr;  // tags only
  double cell = 0;                    // tag cell size, metres
  std::uint8_t gray = 0;
  int u0 = 0, v0 = 0, u1 = -1, v1 = -1;  // image bounding box (inclusive)
};

bool InsidePolygon(const std::vector<Eigen::Vector2d>& poly, double a, double b) {
  bool inside = false;
  for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const auto& p = poly[i];
    const auto& q = poly[j];
    if ((p.y() > b) != (q.y() > b) && a < (q.x() - p.x()) * (b - p.y()) / (q.y() - p.y()) + p.x()) inside = !inside;
  }
  return inside;
}

void BoundingBox(const CameraModel& cam, const Eigen::Isometry3d& cMw, const std::vector<Eigen::Vector3d>& world,
                 Item& item) {
  double umin = std::numeric_limits<double>::infinity(), vmin = umin, umax = -umin, vmax = -umin;
  bool behind = false;
  for (const auto& w : world) {
    const Eigen::Vector3d c = cMw * w;
    if (c.z() < 1e-6) {
      behind = true;
      break;
    }
    const Eigen::Vector2d p = cam.Project(c);
    umin = std::min(umin, p.x());
    umax = std::max(umax, p.x());
    vmin = std::min(vmin, p.y());
    vmax = std::max(vmax, p.y());
  }
  if (behind || cam.distortion != DistortionModel::kNone) {
    // Curved edges (distortion) or a polygon crossing the camera plane: test every pixel.
    if (behind) {
      item.u0 = 0, item.v0 = 0, item.u1 = cam.width - 1, item.v1 = cam.height - 1;
      return;
    }
    const double pad = 0.05 * std::max(cam.width, cam.height);
    umin -= pad, vmin -= pad, umax += pad, vmax += pad;
  }
  item.u0 = std::max(0, static_cast<int>(std::floor(umin - 2)));
  item.v0 = std::max(0, static_cast<int>(std::floor(vmin - 2)));
  item.u1 = std::min(cam.width - 1, static_cast<int>(std::ceil(umax + 2)));
  item.v1 = std::min(cam.height - 1, static_cast<int>(std::ceil(vmax + 2)));
}

}  // namespace

void AddPrism(RenderScene& scene, const std::vector<Eigen::Vector2d>& polygon, double height,
              const Eigen::Isometry3d& wMo, std::uint8_t top_gray, std::uint8_t side_gray) {
  RenderPolygon top;
  top.gray = top_gray;
  for (const auto& p : polygon) top.vertices.push_back(wMo * Eigen::Vector3d(p.x(), p.y(), height));
  scene.polygons.push_back(top);
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const auto& a = polygon[i];
    const auto& b = polygon[(i + 1) % polygon.size()];
    RenderPolygon side;
    side.gray = side_gray;
    side.vertices = {wMo * Eigen::Vector3d(a.x(), a.y(), 0), wMo * Eigen::Vector3d(b.x(), b.y(), 0),
                     wMo * Eigen::Vector3d(b.x(), b.y(), height), wMo * Eigen::Vector3d(a.x(), a.y(), height)};
    scene.polygons.push_back(side);
  }
}

GrayImage Render(const CameraModel& cam, const Eigen::Isometry3d& wMc, const RenderScene& scene,
                 const RenderOptions& options) {
  if (cam.width <= 0 || cam.height <= 0) throw InputError("camera", cam.name, "has no image size to render");
  const int ss = std::max(1, options.supersample);
  const Eigen::Isometry3d cMw = wMc.inverse();

  std::map<std::pair<std::string, int>, TagBitmap> bitmaps;
  std::vector<Item> items;
  for (const auto& poly : scene.polygons) {
    if (poly.vertices.size() < 3) continue;
    Item it;
    it.origin = poly.vertices[0];
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < poly.vertices.size(); ++i) {
      n += poly.vertices[i].cross(poly.vertices[(i + 1) % poly.vertices.size()]);
    }
    if (n.norm() < 1e-15) continue;
    it.normal = n.normalized();
    it.e1 = (poly.vertices[1] - poly.vertices[0]).normalized();
    it.e2 = it.normal.cross(it.e1);
    for (const auto& v : poly.vertices) it.poly.emplace_back(it.e1.dot(v - it.origin), it.e2.dot(v - it.origin));
    it.gray = poly.gray;
    BoundingBox(cam, cMw, poly.vertices, it);
    items.push_back(std::move(it));
  }
  for (const auto& tag : scene.tags) {
    auto key = std::make_pair(tag.family, tag.id);
    auto found = bitmaps.find(key);
    if (found == bitmaps.end()) found = bitmaps.emplace(key, MakeTagBitmap(tag.family, tag.id)).first;
    Item it;
    it.bitmap = &found->second;
    it.cell = tag.size / it.bitmap->width_at_border;
    it.origin = tag.wMt.translation();
    it.e1 = tag.wMt.linear().col(0);
    it.e2 = tag.wMt.linear().col(1);
    it.normal = tag.wMt.linear().col(2);
    const double half = 0.5 * it.cell * it.bitmap->total_width;
    std::vector<Eigen::Vector3d> corners;
    for (int k = 0; k < 4; ++k) {
      const double a = (k == 0 || k == 3) ? -half : half, b = (k < 2) ? -half : half;
      corners.push_back(tag.wMt * Eigen::Vector3d(a, b, 0));
    }
    BoundingBox(cam, cMw, corners, it);
    items.push_back(std::move(it));
  }

  // Everything in the camera frame: a ray is d = (x, y, 1) in normalized coordinates, so the ray parameter is depth.
  struct CamItem {
    Eigen::Vector3d o, n, e1, e2;
    double num;
  };
  std::vector<CamItem> citems;
  for (const auto& it : items) {
    CamItem c;
    c.o = cMw * it.origin;
    c.n = cMw.linear() * it.normal;
    c.e1 = cMw.linear() * it.e1;
    c.e2 = cMw.linear() * it.e2;
    c.num = c.n.dot(c.o);
    citems.push_back(c);
  }
  // Casts one ray; returns a label (which surface and which tag cell was hit, -1 for none) and sets the grey level.
  auto cast = [&](const Eigen::Vector2d& xy, int u, int v, int& gray) {
    double best = std::numeric_limits<double>::infinity();
    int label = -1;
    gray = options.background;
    for (std::size_t i = 0; i < items.size(); ++i) {
      const Item& it = items[i];
      if (u < it.u0 || u > it.u1 || v < it.v0 || v > it.v1) continue;
      const CamItem& c = citems[i];
      const double den = c.n.x() * xy.x() + c.n.y() * xy.y() + c.n.z();
      if (std::abs(den) < 1e-12) continue;
      const double t = c.num / den;
      // Tags (after the polygons in `items`) win depth ties: a tag glued on a face lies in that face's plane.
      if (t <= 0 || (it.bitmap != nullptr ? t > best * (1 + 1e-9) : t >= best)) continue;
      const Eigen::Vector3d rel(t * xy.x() - c.o.x(), t * xy.y() - c.o.y(), t - c.o.z());
      const double a = c.e1.dot(rel), b = c.e2.dot(rel);
      if (it.bitmap != nullptr) {
        const int w = it.bitmap->total_width;
        const int col = static_cast<int>(std::floor(a / it.cell + 0.5 * w));
        const int row = static_cast<int>(std::floor(0.5 * w - b / it.cell));
        if (col < 0 || row < 0 || col >= w || row >= w) continue;
        best = t;
        const bool white = it.bitmap->at(col, row) != 0;
        gray = white ? options.white : options.black;
        label = static_cast<int>(i) * 2 + (white ? 1 : 0);
      } else {
        if (!InsidePolygon(it.poly, a, b)) continue;
        best = t;
        gray = it.gray;
        label = static_cast<int>(i) * 2;
      }
    }
    return label;
  };
  auto normalized = [&](double u, double v) -> Eigen::Vector2d {
    if (cam.distortion == DistortionModel::kNone) return {(u - cam.u0) / cam.px, (v - cam.v0) / cam.py};
    return cam.PixelToNormalized({u, v});
  };

  // Pass 1: one ray through each pixel centre. Pass 2: pixels whose surface (or tag cell colour) differs from a
  // neighbour's straddle an edge; they are re-rendered as the mean of ss x ss sub-pixel rays.
  GrayImage out(cam.width, cam.height, options.background);
  std::vector<int> labels(static_cast<std::size_t>(cam.width) * cam.height, -1);
  for (int v = 0; v < cam.height; ++v) {
    for (int u = 0; u < cam.width; ++u) {
      int gray;
      labels[static_cast<std::size_t>(v) * cam.width + u] = cast(normalized(u, v), u, v, gray);
      out.at(u, v) = static_cast<std::uint8_t>(gray);
    }
  }
  if (ss > 1) {
    auto label = [&](int u, int v) { return labels[static_cast<std::size_t>(v) * cam.width + u]; };
    for (int v = 0; v < cam.height; ++v) {
      for (int u = 0; u < cam.width; ++u) {
        const int l = label(u, v);
        const bool edge = (u > 0 && label(u - 1, v) != l) || (u + 1 < cam.width && label(u + 1, v) != l) ||
                          (v > 0 && label(u, v - 1) != l) || (v + 1 < cam.height && label(u, v + 1) != l);
        if (!edge) continue;
        int sum = 0;
        for (int sy = 0; sy < ss; ++sy) {
          for (int sx = 0; sx < ss; ++sx) {
            int gray;
            cast(normalized(u + (sx + 0.5) / ss - 0.5, v + (sy + 0.5) / ss - 0.5), u, v, gray);
            sum += gray;
          }
        }
        out.at(u, v) = static_cast<std::uint8_t>((sum + ss * ss / 2) / (ss * ss));
      }
    }
  }

  if (options.blur_sigma > 0 || options.noise_stddev > 0) {
    cv::Mat m(out.height, out.width, CV_8UC1, out.pixels.data());
    cv::Mat f;
    m.convertTo(f, CV_32F);
    if (options.blur_sigma > 0) cv::GaussianBlur(f, f, cv::Size(0, 0), options.blur_sigma);
    if (options.noise_stddev > 0) {
      std::mt19937 rng(options.seed);
      std::normal_distribution<float> noise(0.0f, static_cast<float>(options.noise_stddev));
      for (int r = 0; r < f.rows; ++r) {
        float* p = f.ptr<float>(r);
        for (int c = 0; c < f.cols; ++c) p[c] += noise(rng);
      }
    }
    f.convertTo(m, CV_8U);  // rounds and saturates
  }
  return out;
}

}  // namespace visco::vision

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
  // The same in the camera frame: a ray is d = (x, y, 1) in normalized coordinates, so the ray parameter is depth.
  Eigen::Vector3d c_o, c_n, c_e1, c_e2;
  double num = 0;
  int id = 0;           // the surface's label is 2 id (+ 1 on a tag's white cells)
  bool moving = false;  // of CachedRenderer's moving part
};

using Bitmaps = std::map<std::pair<std::string, int>, TagBitmap>;

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

void ToCamera(const Eigen::Isometry3d& cMw, Item& it) {
  it.c_o = cMw * it.origin;
  it.c_n = cMw.linear() * it.normal;
  it.c_e1 = cMw.linear() * it.e1;
  it.c_e2 = cMw.linear() * it.e2;
  it.num = it.c_n.dot(it.c_o);
}

void AddPolygons(const CameraModel& cam, const Eigen::Isometry3d& cMw, const RenderScene& scene, bool moving,
                 std::vector<Item>& items) {
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
    it.moving = moving;
    BoundingBox(cam, cMw, poly.vertices, it);
    ToCamera(cMw, it);
    items.push_back(std::move(it));
  }
}

void AddTags(const CameraModel& cam, const Eigen::Isometry3d& cMw, const RenderScene& scene, bool moving,
             Bitmaps& bitmaps, std::vector<Item>& items) {
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
    it.moving = moving;
    BoundingBox(cam, cMw, corners, it);
    ToCamera(cMw, it);
    items.push_back(std::move(it));
  }
}

// The items of `fixed` and `moving` in the order rays test them (the fixed polygons, the moving ones, the fixed tags,
// the moving ones: Render's order for the union of the two scenes). Ids: the fixed items first, in that order, then
// the moving ones (so that the fixed items' labels do not depend on the moving part).
std::vector<Item> BuildItems(const CameraModel& cam, const Eigen::Isometry3d& cMw, const RenderScene& fixed,
                             const RenderScene& moving, Bitmaps& bitmaps) {
  std::vector<Item> items;
  AddPolygons(cam, cMw, fixed, false, items);
  AddPolygons(cam, cMw, moving, true, items);
  AddTags(cam, cMw, fixed, false, bitmaps, items);
  AddTags(cam, cMw, moving, true, bitmaps, items);
  int fixed_count = 0;
  for (const Item& it : items) fixed_count += it.moving ? 0 : 1;
  int next_fixed = 0, next_moving = fixed_count;
  for (Item& it : items) it.id = it.moving ? next_moving++ : next_fixed++;
  return items;
}

// Casts one ray through (normalized) xy, from pixel (u, v) (items whose bounding box misses the pixel are skipped);
// returns a label (which surface and which tag cell was hit, -1 for none) and sets the grey level.
int Cast(const std::vector<Item>& items, const RenderOptions& options, const Eigen::Vector2d& xy, int u, int v,
         int& gray) {
  double best = std::numeric_limits<double>::infinity();
  int label = -1;
  gray = options.background;
  for (const Item& it : items) {
    if (u < it.u0 || u > it.u1 || v < it.v0 || v > it.v1) continue;
    const double den = it.c_n.x() * xy.x() + it.c_n.y() * xy.y() + it.c_n.z();
    if (std::abs(den) < 1e-12) continue;
    const double t = it.num / den;
    // Tags (after the polygons in `items`) win depth ties: a tag glued on a face lies in that face's plane.
    if (t <= 0 || (it.bitmap != nullptr ? t > best * (1 + 1e-9) : t >= best)) continue;
    const Eigen::Vector3d rel(t * xy.x() - it.c_o.x(), t * xy.y() - it.c_o.y(), t - it.c_o.z());
    const double a = it.c_e1.dot(rel), b = it.c_e2.dot(rel);
    if (it.bitmap != nullptr) {
      const int w = it.bitmap->total_width;
      const int col = static_cast<int>(std::floor(a / it.cell + 0.5 * w));
      const int row = static_cast<int>(std::floor(0.5 * w - b / it.cell));
      if (col < 0 || row < 0 || col >= w || row >= w) continue;
      best = t;
      const bool white = it.bitmap->at(col, row) != 0;
      gray = white ? options.white : options.black;
      label = it.id * 2 + (white ? 1 : 0);
    } else {
      if (!InsidePolygon(it.poly, a, b)) continue;
      best = t;
      gray = it.gray;
      label = it.id * 2;
    }
  }
  return label;
}

Eigen::Vector2d Normalized(const CameraModel& cam, double u, double v) {
  if (cam.distortion == DistortionModel::kNone) return {(u - cam.u0) / cam.px, (v - cam.v0) / cam.py};
  return cam.PixelToNormalized({u, v});
}

// A pixel whose surface (or tag cell colour) differs from a neighbour's straddles an edge.
bool IsEdge(const std::vector<int>& labels, int width, int height, int u, int v) {
  auto label = [&](int x, int y) { return labels[static_cast<std::size_t>(y) * width + x]; };
  const int l = label(u, v);
  return (u > 0 && label(u - 1, v) != l) || (u + 1 < width && label(u + 1, v) != l) ||
         (v > 0 && label(u, v - 1) != l) || (v + 1 < height && label(u, v + 1) != l);
}

// An edge pixel's grey level: the mean of ss x ss sub-pixel rays.
std::uint8_t Supersampled(const CameraModel& cam, const std::vector<Item>& items, const RenderOptions& options, int ss,
                          int u, int v) {
  int sum = 0;
  for (int sy = 0; sy < ss; ++sy) {
    for (int sx = 0; sx < ss; ++sx) {
      int gray;
      Cast(items, options, Normalized(cam, u + (sx + 0.5) / ss - 0.5, v + (sy + 0.5) / ss - 0.5), u, v, gray);
      sum += gray;
    }
  }
  return static_cast<std::uint8_t>((sum + ss * ss / 2) / (ss * ss));
}

void Blur(cv::Mat& f, const RenderOptions& options) { cv::GaussianBlur(f, f, cv::Size(0, 0), options.blur_sigma); }

// Adds the noise to the (float) picture `f`, row by row, and rounds it into `out` (saturated).
void AddNoiseAndQuantize(cv::Mat& f, const RenderOptions& options, GrayImage& out) {
  if (options.noise_stddev > 0) {
    std::mt19937 rng(options.seed);
    std::normal_distribution<float> noise(0.0f, static_cast<float>(options.noise_stddev));
    for (int r = 0; r < f.rows; ++r) {
      float* p = f.ptr<float>(r);
      for (int c = 0; c < f.cols; ++c) p[c] += noise(rng);
    }
  }
  cv::Mat m(out.height, out.width, CV_8UC1, out.pixels.data());
  f.convertTo(m, CV_8U);  // rounds and saturates
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
  Bitmaps bitmaps;
  const std::vector<Item> items = BuildItems(cam, wMc.inverse(), scene, RenderScene{}, bitmaps);

  // Pass 1: one ray through each pixel centre. Pass 2: pixels that straddle an edge are re-rendered as the mean of
  // ss x ss sub-pixel rays.
  GrayImage out(cam.width, cam.height, options.background);
  std::vector<int> labels(static_cast<std::size_t>(cam.width) * cam.height, -1);
  for (int v = 0; v < cam.height; ++v) {
    for (int u = 0; u < cam.width; ++u) {
      int gray;
      labels[static_cast<std::size_t>(v) * cam.width + u] = Cast(items, options, Normalized(cam, u, v), u, v, gray);
      out.at(u, v) = static_cast<std::uint8_t>(gray);
    }
  }
  if (ss > 1) {
    for (int v = 0; v < cam.height; ++v) {
      for (int u = 0; u < cam.width; ++u) {
        if (IsEdge(labels, cam.width, cam.height, u, v)) out.at(u, v) = Supersampled(cam, items, options, ss, u, v);
      }
    }
  }

  if (options.blur_sigma > 0 || options.noise_stddev > 0) {
    cv::Mat m(out.height, out.width, CV_8UC1, out.pixels.data());
    cv::Mat f;
    m.convertTo(f, CV_32F);
    if (options.blur_sigma > 0) Blur(f, options);
    AddNoiseAndQuantize(f, options, out);
  }
  return out;
}

// The fixed part alone is rendered once per camera pose and options (labels, pass-1 and final grey levels, and the
// float picture before and after the blur); a frame starts from it and redoes only the box of pixels the moving items'
// bounding boxes cover (a ray outside every moving item's box skips them, so it hits what it hits in the fixed part),
// grown by the one-pixel ring whose edge test reads those pixels' labels, and the blur's rows around that box.
struct CachedRenderer::Impl {
  struct Box {
    int u0 = 0, v0 = 0, u1 = -1, v1 = -1;  // inclusive; empty when u1 < u0
    bool empty() const { return u1 < u0 || v1 < v0; }
    bool contains(int u, int v) const { return u >= u0 && u <= u1 && v >= v0 && v <= v1; }
  };

  CameraModel cam;
  RenderScene fixed;
  Bitmaps bitmaps;
  std::vector<Eigen::Vector2d> rays;  // normalized ray through each pixel centre, row-major

  // What the cache was made for.
  bool cached = false;
  Eigen::Matrix4d wMc_key;
  RenderOptions key;

  // The fixed part alone, and the current frame (equal to the fixed part outside `dirty` and the blur's rows).
  std::vector<int> fixed_labels, labels;
  std::vector<std::uint8_t> fixed_pass1, pass1, fixed_final, final;
  cv::Mat fixed_float, frame_float, fixed_blurred, frame_blurred;  // CV_32F
  Box dirty;
  int blur_row0 = 0, blur_row1 = -1;

  std::size_t Index(int u, int v) const { return static_cast<std::size_t>(v) * cam.width + u; }

  bool SameKey(const Eigen::Isometry3d& wMc, const RenderOptions& o) const {
    return cached && wMc.matrix() == wMc_key && o.background == key.background && o.black == key.black &&
           o.white == key.white && std::max(1, o.supersample) == std::max(1, key.supersample) &&
           o.blur_sigma == key.blur_sigma;
  }

  void Rebuild(const Eigen::Isometry3d& wMc, const RenderOptions& o) {
    const int ss = std::max(1, o.supersample);
    const std::vector<Item> items = BuildItems(cam, wMc.inverse(), fixed, RenderScene{}, bitmaps);
    const std::size_t n = static_cast<std::size_t>(cam.width) * cam.height;
    fixed_labels.assign(n, -1);
    fixed_pass1.assign(n, o.background);
    for (int v = 0; v < cam.height; ++v) {
      for (int u = 0; u < cam.width; ++u) {
        int gray;
        fixed_labels[Index(u, v)] = Cast(items, o, rays[Index(u, v)], u, v, gray);
        fixed_pass1[Index(u, v)] = static_cast<std::uint8_t>(gray);
      }
    }
    fixed_final = fixed_pass1;
    if (ss > 1) {
      for (int v = 0; v < cam.height; ++v) {
        for (int u = 0; u < cam.width; ++u) {
          if (IsEdge(fixed_labels, cam.width, cam.height, u, v)) {
            fixed_final[Index(u, v)] = Supersampled(cam, items, o, ss, u, v);
          }
        }
      }
    }
    cv::Mat(cam.height, cam.width, CV_8UC1, fixed_final.data()).convertTo(fixed_float, CV_32F);
    fixed_blurred.release();
    if (o.blur_sigma > 0) {
      fixed_blurred = fixed_float.clone();
      Blur(fixed_blurred, o);
    }
    labels = fixed_labels;
    pass1 = fixed_pass1;
    final = fixed_final;
    frame_float = fixed_float.clone();
    frame_blurred = fixed_blurred.clone();
    dirty = Box{};
    blur_row0 = 0, blur_row1 = -1;
    cached = true;
    wMc_key = wMc.matrix();
    key = o;
  }

  // Back to the fixed part where the last frame differed from it.
  void Restore() {
    for (int v = dirty.v0; !dirty.empty() && v <= dirty.v1; ++v) {
      const std::size_t a = Index(dirty.u0, v), b = Index(dirty.u1, v) + 1;
      std::copy(fixed_labels.begin() + a, fixed_labels.begin() + b, labels.begin() + a);
      std::copy(fixed_final.begin() + a, fixed_final.begin() + b, final.begin() + a);
      std::copy(fixed_float.ptr<float>(v) + dirty.u0, fixed_float.ptr<float>(v) + dirty.u1 + 1,
                frame_float.ptr<float>(v) + dirty.u0);
    }
    if (blur_row1 >= blur_row0)
      fixed_blurred.rowRange(blur_row0, blur_row1 + 1).copyTo(frame_blurred.rowRange(blur_row0, blur_row1 + 1));
    dirty = Box{};
    blur_row0 = 0, blur_row1 = -1;
  }

  void Frame(const Eigen::Isometry3d& wMc, const RenderScene& moving, const RenderOptions& o, GrayImage& out) {
    if (!SameKey(wMc, o)) Rebuild(wMc, o);
    Restore();
    const int ss = std::max(1, o.supersample);
    const std::vector<Item> items = BuildItems(cam, wMc.inverse(), fixed, moving, bitmaps);
    std::vector<Box> boxes;  // the moving items' bounding boxes
    Box touched;             // their union's box
    for (const Item& it : items) {
      if (!it.moving || it.u1 < it.u0 || it.v1 < it.v0) continue;
      boxes.push_back({it.u0, it.v0, it.u1, it.v1});
      touched = touched.empty() ? boxes.back()
                                : Box{std::min(touched.u0, it.u0), std::min(touched.v0, it.v0),
                                      std::max(touched.u1, it.u1), std::max(touched.v1, it.v1)};
    }
    auto in_a_box = [&](int u, int v) {
      return std::any_of(boxes.begin(), boxes.end(), [&](const Box& b) { return b.contains(u, v); });
    };
    if (!touched.empty()) {
      for (int v = touched.v0; v <= touched.v1; ++v) {
        for (int u = touched.u0; u <= touched.u1; ++u) {
          const std::size_t p = Index(u, v);
          if (in_a_box(u, v)) {
            int gray;
            labels[p] = Cast(items, o, rays[p], u, v, gray);
            pass1[p] = static_cast<std::uint8_t>(gray);
          } else {
            labels[p] = fixed_labels[p];
            pass1[p] = fixed_pass1[p];
          }
        }
      }
      dirty = {std::max(0, touched.u0 - 1), std::max(0, touched.v0 - 1), std::min(cam.width - 1, touched.u1 + 1),
               std::min(cam.height - 1, touched.v1 + 1)};
      for (int v = dirty.v0; v <= dirty.v1; ++v) {
        for (int u = dirty.u0; u <= dirty.u1; ++u) {
          const std::size_t p = Index(u, v);
          std::uint8_t gray = touched.contains(u, v) ? pass1[p] : fixed_pass1[p];
          if (ss > 1 && IsEdge(labels, cam.width, cam.height, u, v)) {
            // Outside the moving boxes a sub-pixel ray hits what it hits in the fixed part.
            gray = !in_a_box(u, v) && IsEdge(fixed_labels, cam.width, cam.height, u, v)
                       ? fixed_final[p]
                       : Supersampled(cam, items, o, ss, u, v);
          }
          final[p] = gray;
          frame_float.at<float>(v, u) = gray;
        }
      }
      if (o.blur_sigma > 0) {
        // OpenCV's kernel size for a float image (cv::createGaussianKernels), and a row of margin.
        const int reach = (cvRound(o.blur_sigma * 8 + 1) | 1) / 2 + 1;
        blur_row0 = std::max(0, dirty.v0 - reach);
        blur_row1 = std::min(cam.height - 1, dirty.v1 + reach);
        // A band of whole rows: the filter reads the rows around it from the frame (not a mirrored border).
        cv::Mat band;
        cv::GaussianBlur(frame_float.rowRange(blur_row0, blur_row1 + 1), band, cv::Size(0, 0), o.blur_sigma);
        band.copyTo(frame_blurred.rowRange(blur_row0, blur_row1 + 1));
      }
    }
    out = GrayImage(cam.width, cam.height);
    if (o.blur_sigma > 0 || o.noise_stddev > 0) {
      cv::Mat f = o.blur_sigma > 0 ? frame_blurred : frame_float;
      if (o.noise_stddev > 0) f = f.clone();  // the noise must not reach the cache
      AddNoiseAndQuantize(f, o, out);
    } else {
      out.pixels = final;
    }
  }
};

CachedRenderer::CachedRenderer(const CameraModel& camera, const RenderScene& fixed) : impl_(std::make_unique<Impl>()) {
  if (camera.width <= 0 || camera.height <= 0) {
    throw InputError("camera", camera.name, "has no image size to render");
  }
  impl_->cam = camera;
  impl_->fixed = fixed;
  for (const auto& tag : fixed.tags) {
    const auto key = std::make_pair(tag.family, tag.id);
    if (impl_->bitmaps.count(key) == 0) impl_->bitmaps.emplace(key, MakeTagBitmap(tag.family, tag.id));
  }
  impl_->rays.resize(static_cast<std::size_t>(camera.width) * camera.height);
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) impl_->rays[impl_->Index(u, v)] = Normalized(camera, u, v);
  }
}

CachedRenderer::~CachedRenderer() = default;

GrayImage CachedRenderer::Render(const Eigen::Isometry3d& wMc, const RenderScene& moving,
                                 const RenderOptions& options) {
  GrayImage out;
  impl_->Frame(wMc, moving, options, out);
  return out;
}

const CameraModel& CachedRenderer::camera() const { return impl_->cam; }

}  // namespace visco::vision

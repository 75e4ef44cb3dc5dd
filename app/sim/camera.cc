#include "app/sim/camera.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cstring>

#include "common/error.h"
#include "vision/camera.h"
#include "vision/image_png.h"
#include "vision/object_model.h"
#include "vision/tag_renderer.h"

namespace visco::sim {

struct RenderedCamera::Impl {
  RenderedCameraConfig config;
  vision::CameraModel camera;
  Eigen::Isometry3d wMc = Eigen::Isometry3d::Identity();
  vision::ObjectModels models;
  vision::RenderScene fixed;                         // the table and the obstacles (world frame)
  std::unique_ptr<vision::CachedRenderer> renderer;  // renders `fixed` once; each frame only around the robot
};

namespace {

constexpr std::uint8_t kTableGray = 150;
constexpr std::uint8_t kObstacleTop = 110, kObstacleSide = 70;
constexpr std::uint8_t kRobotTop = 190, kRobotSide = 160;

void AddObject(vision::RenderScene& scene, const vision::ObjectModel& object, const Eigen::Isometry3d& wMo,
               std::uint8_t top, std::uint8_t side) {
  vision::AddPrism(scene, object.polygon, object.height, wMo, top, side);
  for (const vision::TagMount& mount : object.tags) {
    vision::RenderTag tag;
    tag.family = mount.family;
    tag.id = mount.id;
    tag.size = mount.size;
    tag.wMt = wMo * mount.oMt;
    scene.tags.push_back(tag);
  }
}

}  // namespace

control::ServoCamera ServoCameraFromFiles(const RenderedCameraConfig& config) {
  const vision::CameraModel camera = vision::LoadCamera(config.calibration_path, config.camera_name);
  const Eigen::Isometry3d wMc = vision::LoadExtrinsics(config.extrinsics_path);
  const vision::ObjectModels models = vision::LoadObjectModels(config.objects_path);
  double r[3][3], t[3];
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 3; ++k) r[i][k] = wMc.linear()(i, k);
    t[i] = wMc.translation()[i];
  }
  return control::MakeServoCamera(camera.px, camera.py, camera.u0, camera.v0, r, t, models.robot.height);
}

RenderedCamera::RenderedCamera(const RenderedCameraConfig& config) : impl_(std::make_unique<Impl>()) {
  impl_->config = config;
  impl_->camera = vision::LoadCamera(config.calibration_path, config.camera_name);
  if (impl_->camera.width <= 0 || impl_->camera.height <= 0) {
    throw InputError(config.calibration_path, "camera", "has no image size; the simulated camera needs one");
  }
  impl_->wMc = vision::LoadExtrinsics(config.extrinsics_path);
  impl_->models = vision::LoadObjectModels(config.objects_path);
  if (!(config.blur_sigma_px >= 0)) throw InputError("command line", "--blur-px", "must be >= 0");
  if (!(config.noise_gray >= 0)) throw InputError("command line", "--image-noise", "must be >= 0");
  if (config.png_level > vision::kPngLevelMax) throw InputError("command line", "--png-level", "must be 0..9 (zlib)");
  if (config.supersample < 1 || config.supersample > 8) {
    throw InputError("command line", "--supersample", "must be in 1..8");
  }
  // The table: a grey floor under everything the models span (plus a margin), drawn first.
  Eigen::AlignedBox2d box;
  for (const auto& p : impl_->models.robot.polygon) box.extend(p);
  for (const auto& o : impl_->models.obstacles) {
    for (const auto& p : o.polygon) box.extend(p);
  }
  const double margin = 3.0 * std::max(box.sizes().x(), box.sizes().y());
  vision::RenderPolygon table;
  table.gray = kTableGray;
  table.vertices = {{box.min().x() - margin, box.min().y() - margin, 0.0},
                    {box.max().x() + margin, box.min().y() - margin, 0.0},
                    {box.max().x() + margin, box.max().y() + margin, 0.0},
                    {box.min().x() - margin, box.max().y() + margin, 0.0}};
  impl_->fixed.polygons.push_back(table);
  for (const auto& o : impl_->models.obstacles) {
    AddObject(impl_->fixed, o, Eigen::Isometry3d::Identity(), kObstacleTop, kObstacleSide);
  }
  impl_->renderer = std::make_unique<vision::CachedRenderer>(impl_->camera, impl_->fixed);
  // Fail now, not in the camera thread: render once (unknown tag families or ids throw InputError).
  image_t probe;
  Capture({0.0, 0.0}, 0, 0, {}, probe);
}

RenderedCamera::~RenderedCamera() = default;

void RenderedCamera::Capture(control::Vec2 q, std::int64_t utime, std::int64_t seq, const CaptureConditions& conditions,
                             image_t& image) {
  vision::RenderScene scene;  // the moving part: the robot
  if (!conditions.robot_occluded) {
    Eigen::Isometry3d wMr = Eigen::Isometry3d::Identity();
    wMr.translation() = Eigen::Vector3d(q.x, q.y, 0.0);
    AddObject(scene, impl_->models.robot, wMr, kRobotTop, kRobotSide);
  }
  vision::RenderOptions options;
  options.supersample = impl_->config.supersample;
  options.blur_sigma = impl_->config.blur_sigma_px;
  options.noise_stddev = impl_->config.noise_gray;
  options.seed = static_cast<std::uint32_t>(impl_->config.seed + static_cast<std::uint64_t>(seq));
  // What vision::Render draws of the fixed part and the robot, byte for byte.
  const vision::GrayImage picture = impl_->renderer->Render(impl_->wMc, scene, options);
  image.utime = utime;
  image.seq = seq;
  image.camera = impl_->camera.name.empty() ? "camera" : impl_->camera.name;
  image.width = picture.width;
  image.height = picture.height;
  image.row_stride = picture.width;
  if (impl_->config.png_level >= 0) {
    vision::PackGrayPng(picture.view(), impl_->config.png_level, image);
    return;
  }
  image.pixel_format = image_t::PIXEL_FORMAT_GRAY8;
  image.data = picture.pixels;
  image.size = static_cast<std::int32_t>(image.data.size());
}

int RenderedCamera::width() const { return impl_->camera.width; }
int RenderedCamera::height() const { return impl_->camera.height; }
const std::string& RenderedCamera::camera_name() const { return impl_->camera.name; }

}  // namespace visco::sim

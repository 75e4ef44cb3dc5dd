// CachedRenderer against Render(), its reference: byte for byte on seeded random scenes and camera poses, frame after
// frame with the robot moving (the camera anywhere, looking at the table or past it, close enough for items to cross
// its plane; distortion of both models or none; items overlapping; the robot partly or wholly out of view or hidden;
// supersampling, blur and noise on and off; the camera and the options changing between frames).

#include <gtest/gtest.h>

#include <random>
#include <sstream>

#include "common/error.h"
#include "vision/camera.h"
#include "vision/tag_renderer.h"

namespace visco::vision {
namespace {

Eigen::Isometry3d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  // Camera frame: z forward, x right, y down; "up" is the world's z unless the camera looks straight along it.
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d up = std::abs(z.z()) > 0.99 ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d x = z.cross(up).normalized();
  Eigen::Isometry3d wMc = Eigen::Isometry3d::Identity();
  wMc.linear().col(0) = x;
  wMc.linear().col(1) = z.cross(x);
  wMc.linear().col(2) = z;
  wMc.translation() = eye;
  return wMc;
}

class World {
 public:
  explicit World(std::uint32_t seed) : rng_(seed) {}

  double Uniform(double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng_); }
  int Int(int a, int b) { return std::uniform_int_distribution<int>(a, b)(rng_); }
  std::uint8_t Gray() { return static_cast<std::uint8_t>(Int(0, 255)); }

  CameraModel Camera(int width, int height) {
    CameraModel cam =
        CameraModel::Pinhole(Uniform(0.6, 1.4) * width, Uniform(0.6, 1.4) * width, (width - 1) / 2.0 + Uniform(-10, 10),
                             (height - 1) / 2.0 + Uniform(-10, 10), width, height);
    switch (Int(0, 2)) {
      case 1:
        cam.distortion = DistortionModel::kViSP;
        cam.kud = Uniform(-0.2, 0.2);
        cam.kdu = -cam.kud;
        break;
      case 2:
        cam.distortion = DistortionModel::kOpenCV;
        cam.dist = {Uniform(-0.2, 0.2), Uniform(-0.05, 0.05), Uniform(-0.01, 0.01), Uniform(-0.01, 0.01)};
        break;
      default:
        break;
    }
    return cam;
  }

  // Anywhere above or beside the table, looking at a point of it (or past it); now and then so close to the
  // objects that some of them cross the camera's plane.
  Eigen::Isometry3d CameraPose() {
    const Eigen::Vector3d target(Uniform(-0.6, 0.6), Uniform(-0.6, 0.6), Uniform(-0.2, 0.3));
    Eigen::Vector3d eye(Uniform(-1.5, 1.5), Uniform(-1.5, 1.5), Uniform(0.4, 2.5));
    if (Int(0, 4) == 0) eye = Eigen::Vector3d(Uniform(-0.4, 0.4), Uniform(-0.4, 0.4), Uniform(0.05, 0.25));
    return LookAt(eye, target);
  }

  std::vector<Eigen::Vector2d> Footprint() {
    const double w = Uniform(0.1, 0.4), d = Uniform(0.1, 0.4);
    switch (Int(0, 2)) {
      case 0:
        return {{0, 0}, {w, 0}, {w, d}, {0, d}};
      case 1:
        return {{0, 0}, {w, 0}, {0.5 * w, d}};
      default:  // an L: not convex
        return {{0, 0}, {w, 0}, {w, 0.4 * d}, {0.4 * w, 0.4 * d}, {0.4 * w, d}, {0, d}};
    }
  }

  RenderTag Tag(const Eigen::Isometry3d& wMt) {
    static const char* const kFamilies[] = {"tag36h11", "tag25h9", "tag16h5"};
    static const int kIds[] = {587, 35, 30};
    const int f = Int(0, 2);
    return {kFamilies[f], Int(0, kIds[f] - 1), Uniform(0.04, 0.15), wMt};
  }

  Eigen::Isometry3d Planar(double x, double y, double yaw) {
    Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
    m.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    m.translation() = Eigen::Vector3d(x, y, 0);
    return m;
  }

  // A prism at wMo with a tag on its top, and sometimes one on a side face.
  void Object(RenderScene& scene, const std::vector<Eigen::Vector2d>& foot, double height, const Eigen::Isometry3d& wMo,
              bool side_tag) {
    AddPrism(scene, foot, height, wMo, Gray(), Gray());
    Eigen::Vector2d c = Eigen::Vector2d::Zero();
    for (const auto& p : foot) c += p;
    c /= static_cast<double>(foot.size());
    Eigen::Isometry3d oMt = Eigen::Isometry3d::Identity();
    oMt.translation() = Eigen::Vector3d(c.x(), c.y(), height);
    scene.tags.push_back(Tag(wMo * oMt));
    if (side_tag) {
      // On the first side face (from foot[0] to foot[1]), facing out of it.
      Eigen::Isometry3d oMs = Eigen::Isometry3d::Identity();
      const Eigen::Vector3d along =
          Eigen::Vector3d(foot[1].x() - foot[0].x(), foot[1].y() - foot[0].y(), 0).normalized();
      oMs.linear().col(0) = along;
      oMs.linear().col(1) = Eigen::Vector3d::UnitZ();
      oMs.linear().col(2) = along.cross(Eigen::Vector3d::UnitZ());
      oMs.translation() =
          Eigen::Vector3d(0.5 * (foot[0].x() + foot[1].x()), 0.5 * (foot[0].y() + foot[1].y()), 0.5 * height);
      scene.tags.push_back(Tag(wMo * oMs));
    }
  }

  RenderScene Fixed() {
    RenderScene scene;
    scene.polygons.push_back({{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, Gray()});
    const int obstacles = Int(0, 3);
    for (int i = 0; i < obstacles; ++i) {
      Object(scene, Footprint(), Uniform(0.02, 0.3), Planar(Uniform(-0.6, 0.4), Uniform(-0.6, 0.4), Uniform(-3, 3)),
             Int(0, 1) == 1);
    }
    if (Int(0, 3) == 0) scene.tags.push_back(Tag(Planar(Uniform(-0.5, 0.5), Uniform(-0.5, 0.5), Uniform(-3, 3))));
    return scene;
  }

  RenderOptions Options() {
    RenderOptions o;
    o.background = Gray();
    o.black = Gray();
    o.white = Gray();
    o.supersample = Int(1, 4);
    static const double kBlur[] = {0, 0.5, 1.3, 3};
    o.blur_sigma = kBlur[Int(0, 3)];
    o.noise_stddev = Int(0, 1) == 1 ? Uniform(0.5, 4) : 0;
    return o;
  }

  std::mt19937 rng_;
};

RenderScene Union(const RenderScene& a, const RenderScene& b) {
  RenderScene u = a;
  u.polygons.insert(u.polygons.end(), b.polygons.begin(), b.polygons.end());
  u.tags.insert(u.tags.end(), b.tags.begin(), b.tags.end());
  return u;
}

std::string Differences(const GrayImage& want, const GrayImage& got) {
  if (want.width != got.width || want.height != got.height) return "the sizes differ";
  int count = 0, first_u = -1, first_v = -1;
  for (int v = 0; v < want.height; ++v) {
    for (int u = 0; u < want.width; ++u) {
      if (want.at(u, v) == got.at(u, v)) continue;
      if (count++ == 0) first_u = u, first_v = v;
    }
  }
  if (count == 0) return "";
  std::ostringstream s;
  s << count << " pixels differ, the first at (" << first_u << ", " << first_v
    << "): " << int(want.at(first_u, first_v)) << " expected, " << int(got.at(first_u, first_v)) << " rendered";
  return s.str();
}

// A sequence of frames: the robot (a prism with its tags) moving by small steps and now and then a jump (possibly
// out of view), now and then hidden; the camera moving and the options changing now and then.
void CheckSequence(std::uint32_t seed, int width, int height, int frames) {
  World w(seed);
  const CameraModel cam = w.Camera(width, height);
  const RenderScene fixed = w.Fixed();
  CachedRenderer renderer(cam, fixed);
  Eigen::Isometry3d wMc = w.CameraPose();
  RenderOptions options = w.Options();
  const auto foot = w.Footprint();
  const double height_m = w.Uniform(0.02, 0.3);
  const bool side_tag = w.Int(0, 1) == 1;
  const std::uint8_t top = w.Gray(), side = w.Gray();
  double x = w.Uniform(-0.5, 0.5), y = w.Uniform(-0.5, 0.5), yaw = w.Uniform(-3, 3);
  // The robot's tags: drawn once (their family and id stay), placed each frame.
  World tags(seed + 1);
  RenderScene robot_model;
  tags.Object(robot_model, foot, height_m, Eigen::Isometry3d::Identity(), side_tag);
  if (tags.Int(0, 1) == 1) {
    // A tag carried beside the robot, tilted, outside its prism (the prism's pixels do not cover it).
    Eigen::Isometry3d oMf = Eigen::Isometry3d::Identity();
    oMf.linear() = Eigen::AngleAxisd(tags.Uniform(-1, 1), Eigen::Vector3d::UnitX()).toRotationMatrix();
    oMf.translation() = Eigen::Vector3d(tags.Uniform(0.45, 0.6), tags.Uniform(-0.2, 0.2), tags.Uniform(0.05, 0.3));
    robot_model.tags.push_back(tags.Tag(oMf));
  }
  for (int k = 0; k < frames; ++k) {
    SCOPED_TRACE(::testing::Message() << "seed " << seed << ", " << width << "x" << height << ", distortion "
                                      << static_cast<int>(cam.distortion) << ", frame " << k);
    const int event = w.Int(0, 9);
    if (event == 0) x = w.Uniform(-2, 2), y = w.Uniform(-2, 2);  // a jump, possibly out of view
    if (event == 1) wMc = w.CameraPose();
    if (event == 2) options = w.Options();
    x += w.Uniform(-0.02, 0.02), y += w.Uniform(-0.02, 0.02), yaw += w.Uniform(-0.05, 0.05);
    options.seed = static_cast<std::uint32_t>(seed * 100 + k);
    RenderScene moving;
    if (event != 3) {  // event 3: the robot hidden
      const Eigen::Isometry3d wMr = w.Planar(x, y, yaw);
      AddPrism(moving, foot, height_m, wMr, top, side);
      for (const RenderTag& t : robot_model.tags) moving.tags.push_back({t.family, t.id, t.size, wMr * t.wMt});
    }
    const GrayImage want = Render(cam, wMc, Union(fixed, moving), options);
    const GrayImage got = renderer.Render(wMc, moving, options);
    ASSERT_EQ(Differences(want, got), "");
  }
}

TEST(CachedRenderer, EqualsRenderOnRandomScenesAndPoses) {
  for (std::uint32_t seed = 1; seed <= 40; ++seed) CheckSequence(seed, 128, 96, 6);
}

TEST(CachedRenderer, EqualsRenderAtFullSize) {
  for (std::uint32_t seed = 101; seed <= 102; ++seed) CheckSequence(seed, 640, 480, 3);
}

TEST(CachedRenderer, RefusesWhatRenderRefuses) {
  EXPECT_THROW(CachedRenderer(CameraModel::Pinhole(500, 500, 320, 240), RenderScene{}), InputError);
  RenderScene bad;
  bad.tags.push_back({"tag36h11", 587, 0.1, Eigen::Isometry3d::Identity()});
  const CameraModel cam = CameraModel::Pinhole(500, 500, 319.5, 239.5, 640, 480);
  EXPECT_THROW(CachedRenderer(cam, bad), InputError);
  CachedRenderer renderer(cam, RenderScene{});
  EXPECT_THROW(renderer.Render(Eigen::Isometry3d::Identity(), bad), InputError);
}

}  // namespace
}  // namespace visco::vision

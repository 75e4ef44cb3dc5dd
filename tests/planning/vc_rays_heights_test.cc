// 2.5D visibility (docs/planning_cspace.md "Heights"): prisms with heights seen from a camera above the plane, and a
// pinhole camera's image border. Hand scenes with known answers, and properties against a slow obvious reference
// that samples the 3D line of sight on random scenes (cameras anywhere around and above, convex and non-convex prisms,
// overlapping parts).

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <string>

#include "common/error.h"
#include "planning/cspace.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "planning/vc_rays.h"
#include "tests/planning/random_vc_scenes.h"

namespace visco::planning {
namespace {

Scene Make(const std::string& obstacles, const std::string& camera) {
  const std::string text = R"({"bounds": {"min": [-10, -10], "max": [12, 10]},
    "robot": {"polygon": [[0, 0], [0.2, 0], [0.2, 0.2], [0, 0.2]]}, "obstacles": )" +
                           obstacles + R"(,
    "goal": {"polygon": [[-10, -10], [-9, -10], [-9, -9], [-10, -9]]},
    "camera": )" + camera + R"(, "uncertainty": {"velocity_cone_deg": 5, "position": 0.01}, "friction_cone_deg": 10})";
  return ParseScene(text, "hand.json");
}

bool IsVisible(const Scene& s, const std::string& id, int file_vertex) {
  for (const UnoccludedVertex& u : FindUnoccludedVertices(s)) {
    if (s.obstacles[u.obstacle].id == id && s.obstacles[u.obstacle].shape.source_index[u.vertex] == file_vertex) {
      return true;
    }
  }
  return false;
}

// A box with corner (1, 1), a wall between it and the camera at (10, 0), 4 m up. The line of sight from (1, 1) meets
// the wall's footprint (x in [4, 4.5]) first at s = 1/3 of the way, 4/3 m up.
const char* kBoxAndWall = R"([{"id": "box", "polygon": [[0, -1], [1, -1], [1, 1], [0, 1]], "height": 1},
                              {"id": "wall", "polygon": [[4, -3], [4.5, -3], [4.5, 3], [4, 3]], "height": HEIGHT}])";

Scene BoxAndWall(const std::string& wall_height, const std::string& camera_height = R"(, "height": 4)") {
  std::string obstacles = kBoxAndWall;
  if (wall_height.empty()) {
    obstacles.replace(obstacles.find(R"(, "height": HEIGHT)"), std::string(R"(, "height": HEIGHT)").size(), "");
  } else {
    obstacles.replace(obstacles.find("HEIGHT"), 6, wall_height);
  }
  return Make(obstacles, R"({"center": [10, 0], "fov_deg": [100, 260])" + camera_height + "}");
}

TEST(Heights, ALowWallHidesNothingAboveItsTop) {
  // Over a 0.5 m wall the camera sees the box's corner; a 2 m wall, an unbounded one, or a camera without a height
  // (the planar model) hide it.
  EXPECT_TRUE(UsesHeights(BoxAndWall("0.5")));
  EXPECT_TRUE(IsVisible(BoxAndWall("0.5"), "box", 2));
  EXPECT_FALSE(IsVisible(BoxAndWall("2"), "box", 2));
  EXPECT_FALSE(IsVisible(BoxAndWall(""), "box", 2));
  EXPECT_FALSE(UsesHeights(BoxAndWall("0.5", "")));
  EXPECT_FALSE(IsVisible(BoxAndWall("0.5", ""), "box", 2));
  // Exactly at the wall's height (4 / 3 m) the line of sight grazes its top edge: counted hidden (the tolerance
  // errs towards hiding).
  EXPECT_FALSE(IsVisible(BoxAndWall("1.3333333333333333"), "box", 2));
  EXPECT_TRUE(IsVisible(BoxAndWall("1.3333"), "box", 2));
}

TEST(Heights, ARobotJustBehindALowWallIsHidden) {
  const Scene s = BoxAndWall("0.5");
  // From b = (1, 1) to P = (10, 0): the wall's footprint spans s in [1/3, 7/18]. A robot vertex at s sees the camera
  // over the wall iff 4 (1/3 - s) / (1 - s) >= 0.5, i.e. s <= (4/3 - 0.5) / 3.5 = 5/21.
  const auto visible = VisibleRayParameters(s, Point(1, 1));
  ASSERT_EQ(visible.size(), 2u);
  EXPECT_EQ(visible[0].first, 0.0);
  EXPECT_NEAR(visible[0].second, 5.0 / 21.0, 1e-8);
  EXPECT_LT(visible[0].second, 5.0 / 21.0);  // the tolerance errs towards hiding
  EXPECT_NEAR(visible[1].first, 7.0 / 18.0, 1e-8);
  EXPECT_GT(visible[1].first, 7.0 / 18.0);
  EXPECT_EQ(visible[1].second, 1.0);

  // The CVC rays of that vertex break where the robot is hidden, with open ends there (complying towards them
  // fails: the servo loses the vertex).
  const CSpace cspace(s);
  const VcRays rays = ComputeVcRays(s, cspace);
  int checked = 0;
  for (const CvcRay& cvc : rays.cvc_rays) {
    const VcRay& ray = rays.vc_rays[cvc.vc_ray];
    if (ray.from != Point(1, 1)) continue;
    ++checked;
    const Point hidden_from = ray.from + (5.0 / 21.0) * (ray.to - ray.from) + cvc.offset;
    bool open_end_there = false;
    for (std::size_t k = 0; k < cvc.segments.size(); ++k) {
      open_end_there |= cvc.open_ends[k][1] && (cvc.segments[k].target - hidden_from).norm() < 1e-6;
      // No part of the ray lies where the robot is hidden.
      for (double t : {0.0, 0.5, 1.0}) {
        const Point q = cvc.segments[k].source + t * (cvc.segments[k].target - cvc.segments[k].source);
        const double s_q = (q - cvc.offset - ray.from).dot(ray.to - ray.from) / (ray.to - ray.from).squaredNorm();
        EXPECT_FALSE(s_q > 5.0 / 21.0 + 1e-9 && s_q < 7.0 / 18.0 - 1e-9) << cvc.id << " at s = " << s_q;
      }
    }
    EXPECT_TRUE(open_end_there) << cvc.id;
  }
  EXPECT_EQ(checked, 2);
}

TEST(Heights, SceneFileFields) {
  EXPECT_EQ(BoxAndWall("0.5").obstacles[1].height, 0.5);
  EXPECT_FALSE(BoxAndWall("").obstacles[1].height.has_value());
  EXPECT_EQ(BoxAndWall("0.5").camera->height, 4.0);
  try {
    BoxAndWall("0");
    FAIL() << "a zero height was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("obstacles[1] (wall).height"), std::string::npos) << e.what();
  }
  try {
    BoxAndWall("0.5", R"(, "height": -1)");
    FAIL() << "a camera below the plane was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("camera.height"), std::string::npos) << e.what();
  }
  // The pinhole's height is its centre's.
  const Scene pinhole = LoadScene("data/scenes/slot_pinhole.json");
  EXPECT_EQ(pinhole.camera->height, 4.0);
}

// The pixel of a plane point in a pinhole camera's image (false when behind the camera).
bool Project(const PinholeCamera& c, const Point& p, double z, Eigen::Vector2d& uv) {
  const Eigen::Matrix3d cRw = c.wMc.topLeftCorner<3, 3>().transpose();
  const Eigen::Vector3d x = cRw * (Eigen::Vector3d(p.x(), p.y(), z) - c.wMc.topRightCorner<3, 1>());
  if (x.z() <= 0) return false;
  uv = {c.px * x.x() / x.z() + c.u0, c.py * x.y() / x.z() + c.v0};
  return true;
}

TEST(Heights, ThePinholeImageBorderCutsTheRaysNearTheCamera) {
  // slot_pinhole's camera, 4 m up at (11, 9), looks down at 22 degrees: the plane within about 4 m of its foot
  // point lies below the image. The planar model's sector would let a CM vertex be "seen" there.
  const Scene s = LoadScene("data/scenes/slot_pinhole.json");
  const PinholeCamera& c = *s.camera->pinhole;
  const CSpace cspace(s);
  const VcRays rays = ComputeVcRays(s, cspace);
  ASSERT_FALSE(rays.vc_rays.empty());
  for (const VcRay& ray : rays.vc_rays) {
    const auto visible = VisibleRayParameters(s, ray.from);
    ASSERT_EQ(visible.size(), 1u) << ray.id;  // no heights: only the image border cuts
    EXPECT_EQ(visible[0].first, 0.0) << ray.id;
    EXPECT_LT(visible[0].second, 1.0) << ray.id;
    // The last seen point projects onto the border (minus the margin); 10 cm beyond it (about 7 pixels there) it is
    // out of the image.
    const Point last = ray.from + visible[0].second * (ray.to - ray.from);
    Eigen::Vector2d uv;
    ASSERT_TRUE(Project(c, last, 0, uv));
    const double to_border = std::min({uv.x(), c.width - uv.x(), uv.y(), c.height - uv.y()});
    EXPECT_NEAR(to_border, Camera::kImageMargin, 1e-6) << ray.id << " at (" << uv.transpose() << ")";
    const Point beyond = last + 0.1 * (ray.to - ray.from).normalized();
    const bool in = Project(c, beyond, 0, uv) && uv.x() >= 0 && uv.y() >= 0 && uv.x() <= c.width && uv.y() <= c.height;
    EXPECT_FALSE(in) << ray.id;
    EXPECT_GT((last - ray.to).norm(), 3.0) << ray.id;
  }
  // Every CVC part ends before the camera's foot point, with an open end where the image's border cuts it.
  for (const CvcRay& cvc : rays.cvc_rays) {
    for (const Segment& part : cvc.segments) {
      EXPECT_GT((part.target - (rays.vc_rays[cvc.vc_ray].to + cvc.offset)).norm(), 3.0) << cvc.id;
    }
  }
}

// --- Properties against sampling the 3D line of sight ------------------------------------------------------------

// Signed distance from p to the polygon's boundary, positive inside.
double Depth(const Polygon& poly, const Point& p) {
  double dist = 1e300;
  for (std::size_t e = 0; e < poly.size(); ++e) {
    const Segment edge = poly.Edge(e);
    const Vector d = edge.target - edge.source;
    const double t = std::clamp((p - edge.source).dot(d) / d.squaredNorm(), 0.0, 1.0);
    dist = std::min(dist, (p - (edge.source + t * d)).norm());
  }
  return InsideEvenOdd(poly.vertices, p) ? dist : -dist;
}

enum class Seen { kYes, kNo, kUnsure };

// Whether a point (a, 0) of the plane is seen from the camera centre (P, H), by sampling its line of sight: hidden if
// some sample lies inside a prism by more than `margin` (horizontally and below its top), seen if no sample comes
// within `margin` of one, unsure otherwise. The image border likewise, in pixels.
Seen Sample(const Scene& s, const Point& a, double margin) {
  const Camera& cam = *s.camera;
  const double H = *cam.height;
  if (!cam.Sees(a)) return Seen::kNo;
  Seen result = Seen::kYes;
  if (cam.pinhole) {
    Eigen::Vector2d uv;
    if (!Project(*cam.pinhole, a, 0, uv)) return Seen::kNo;
    const PinholeCamera& c = *cam.pinhole;
    const double inside = std::min({uv.x(), c.width - uv.x(), uv.y(), c.height - uv.y()}) - Camera::kImageMargin;
    if (inside < -1e-3) return Seen::kNo;
    if (inside < 1e-3) result = Seen::kUnsure;
  }
  // Evenly spaced samples, and more between each two consecutive crossings of the line of sight with obstacle edges,
  // denser towards the first: a chord through a sliver's tip can be shorter than the spacing (seed 19 at
  // VISCO_SEED_OFFSET=210000: 0.5 mm), and a line of sight that enters a prism just below its top is under it only
  // for a hair after the entry (seed 15 at 290000: 1.2 mm).
  const Vector d = cam.center - a;
  std::vector<double> crossings = {0.0, 1.0};
  for (const Obstacle& o : s.obstacles) {
    for (std::size_t e = 0; e < o.shape.polygon.size(); ++e) {
      const Segment edge = o.shape.polygon.Edge(e);
      const Vector f = edge.target - edge.source, w = edge.source - a;
      const double denominator = d.x() * f.y() - d.y() * f.x();
      if (denominator == 0) continue;
      const double t = (w.x() * f.y() - w.y() * f.x()) / denominator, u = (w.x() * d.y() - w.y() * d.x()) / denominator;
      if (t > 0 && t < 1 && u >= 0 && u <= 1) crossings.push_back(t);
    }
  }
  std::sort(crossings.begin(), crossings.end());
  const int n = 3000;
  std::vector<double> samples;
  for (int k = 1; k < n; ++k) samples.push_back(static_cast<double>(k) / n);
  samples.push_back(0.5 * crossings[1]);
  for (std::size_t k = 1; k + 1 < crossings.size(); ++k) {  // (from the point itself, samples near it are unsure)
    for (const double f : {1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 0.1, 0.5}) {
      samples.push_back(crossings[k] + f * (crossings[k + 1] - crossings[k]));
    }
  }
  for (const double t : samples) {
    const Point x = a + t * d;
    const double z = t * H;
    for (const Obstacle& o : s.obstacles) {
      const double depth = Depth(o.shape.polygon, x);
      const double clearance = o.height ? *o.height - z : 1e300;
      if (depth > margin && clearance > margin) return Seen::kNo;
      if (depth > -margin && clearance > -margin) result = Seen::kUnsure;
    }
  }
  return result;
}

// A look-at pinhole camera (ViSP frame: x right, y down, z forward) at `centre` looking at `target`.
PinholeCamera LookAt(const Eigen::Vector3d& centre, const Eigen::Vector3d& target, double focal) {
  const Eigen::Vector3d z = (target - centre).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  PinholeCamera c;
  c.px = c.py = focal;
  c.u0 = 320;
  c.v0 = 240;
  c.width = 640;
  c.height = 480;
  c.wMc.topLeftCorner<3, 3>() << x, y, z;
  c.wMc.topRightCorner<3, 1>() = centre;
  return c;
}

// A random scene whose camera has a height: planar (a sector, with `height`) for even seeds, a pinhole camera
// anywhere around and above the bounds looking into them for odd ones; prisms 0.2-3 m high, one in five unbounded.
bool HeightScene(std::uint64_t seed, Scene& s, int max_vertices) {
  testing::RandomSceneOptions o;
  o.cells_x = 3;
  o.cells_y = 3;
  o.lattice = 0;
  o.fill = 0.6;
  o.max_vertices = max_vertices;
  o.overlap = seed % 3 == 0 ? 0.4 : 0.0;
  s = testing::RandomScene(seed, o);
  std::mt19937_64 rng(seed * 131 + 7);
  std::uniform_real_distribution<double> unit(0, 1);
  for (Obstacle& ob : s.obstacles) {
    if (unit(rng) < 0.8) ob.height = 0.2 + 2.8 * unit(rng);
  }
  const Eigen::Vector2d lo = s.bounds.min, hi = s.bounds.max;
  const auto anywhere = [&](double spill) {
    return Point(lo.x() - spill + unit(rng) * (hi.x() - lo.x() + 2 * spill),
                 lo.y() - spill + unit(rng) * (hi.y() - lo.y() + 2 * spill));
  };
  for (int attempt = 0; attempt < 50; ++attempt) {
    const Point foot = anywhere(4.0);
    bool inside = false;
    for (const Obstacle& ob : s.obstacles) inside |= Locate(ob.shape.polygon, foot) != Location::kOutside;
    if (inside) continue;
    const double height = 1.0 + 8.0 * unit(rng);
    if (seed % 2 == 0) {
      const double first = 360 * unit(rng);
      s.camera = MakePlanarCamera(foot, first, 60 + 110 * unit(rng));
      s.camera->height = height;
      return true;
    }
    const Point target = anywhere(-2.0);
    try {
      s.camera = DerivePlanarCamera(
          LookAt({foot.x(), foot.y(), height}, {target.x(), target.y(), 0}, 300 + 500 * unit(rng)), "random", "camera");
      return true;
    } catch (const InputError&) {  // sees its own foot point, or not the plane: another pose
    }
  }
  return false;
}

// What blocks the line of sight from (a, 0), for messages.
std::string Explain(const Scene& s, const Point& a) {
  const Camera& cam = *s.camera;
  std::string out = " (camera (" + std::to_string(cam.center.x()) + ", " + std::to_string(cam.center.y()) +
                    ") height " + std::to_string(*cam.height) + (cam.pinhole ? ", pinhole" : ", planar") + ")";
  const int n = 3000;
  for (int k = 1; k < n; ++k) {
    const double t = static_cast<double>(k) / n;
    const Point x = a + t * (cam.center - a);
    for (const Obstacle& o : s.obstacles) {
      const double depth = Depth(o.shape.polygon, x);
      const double clearance = o.height ? *o.height - t * *cam.height : 1e300;
      if (depth > 1e-6 && clearance > 1e-6) {
        return out + "; blocked by " + o.id + " (height " + (o.height ? std::to_string(*o.height) : "none") +
               ") at t = " + std::to_string(t) + ", depth " + std::to_string(depth);
      }
    }
  }
  return out;
}

struct Tally {
  int agree = 0, unsure = 0;
};

// Vertices: reported unoccluded iff the sampled line of sight from the vertex is clear (where sampling is sure).
// With convex prisms the rule is exact, so both directions hold; with non-convex ones only soundness.
void CheckVertices(const Scene& s, std::uint64_t seed, bool exact, Tally& tally) {
  std::set<std::pair<int, int>> reported;
  for (const UnoccludedVertex& u : FindUnoccludedVertices(s)) reported.insert({u.obstacle, u.vertex});
  for (int o = 0; o < static_cast<int>(s.obstacles.size()); ++o) {
    const Polygon& poly = s.obstacles[o].shape.polygon;
    for (int v = 0; v < static_cast<int>(poly.size()); ++v) {
      const Seen seen = Sample(s, poly[v], 1e-6);
      const bool is_reported = reported.count({o, v}) > 0;
      if (seen == Seen::kUnsure) {
        ++tally.unsure;
        continue;
      }
      if (is_reported) {
        EXPECT_EQ(seen, Seen::kYes) << "seed " << seed << ": vertex " << v << " of " << s.obstacles[o].id << " at ("
                                    << poly[v].transpose() << ") reported unoccluded but its line of sight is blocked"
                                    << Explain(s, poly[v]);
      } else if (exact) {
        EXPECT_EQ(seen, Seen::kNo) << "seed " << seed << ": vertex " << v << " of " << s.obstacles[o].id
                                   << " is seen but not reported";
      }
      ++tally.agree;
    }
  }
}

// Robot vertices along each VC ray: points inside a reported interval are seen; with convex prisms, seen points
// (sure, away from the intervals' ends) are inside one.
void CheckRays(const Scene& s, std::uint64_t seed, bool exact, Tally& tally) {
  const Point p = s.camera->center;
  for (const UnoccludedVertex& u : FindUnoccludedVertices(s)) {
    const Point b = s.obstacles[u.obstacle].shape.polygon[u.vertex];
    const auto visible = VisibleRayParameters(s, b);
    for (int k = 1; k < 60; ++k) {
      const double t = k / 60.0;
      const Point a = b + t * (p - b);
      bool in_interval = false, near_end = false;
      for (const auto& [lo, hi] : visible) {
        in_interval |= t >= lo && t <= hi;
        near_end |= std::abs(t - lo) < 1e-6 || std::abs(t - hi) < 1e-6;
      }
      bool in_footprint = false;  // a robot vertex cannot stand inside an obstacle: nothing to check there
      for (const Obstacle& o : s.obstacles) in_footprint |= Depth(o.shape.polygon, a) > -1e-6;
      if (near_end || in_footprint) continue;
      const Seen seen = Sample(s, a, 1e-6);
      if (seen == Seen::kUnsure) {
        ++tally.unsure;
        continue;
      }
      ++tally.agree;
      if (in_interval) {
        EXPECT_EQ(seen, Seen::kYes) << "seed " << seed << ": a robot vertex at s = " << t << " on the ray of ("
                                    << b.transpose() << ") is counted seen but is not";
      } else if (exact) {
        EXPECT_EQ(seen, Seen::kNo) << "seed " << seed << ": a robot vertex at s = " << t << " on the ray of ("
                                   << b.transpose() << ") is seen but not counted";
      }
    }
  }
}

// The sampled 3D line-of-sight reference is slow under the sanitizers (70 s per test instead of 4): there every
// third scene is checked (pinhole and planar cameras alternate with the seed), with the same thresholds per scene.
#if defined(__SANITIZE_ADDRESS__)
constexpr std::uint64_t kSeedStride = 3;
#else
constexpr std::uint64_t kSeedStride = 1;
#endif
constexpr int kStride = static_cast<int>(kSeedStride);

TEST(HeightsProperty, ConvexPrismsAgainstSampling) {
  Tally vertices, robot;
  int scenes = 0, pinholes = 0;
  for (std::uint64_t seed = 1; seed <= 40; seed += kSeedStride) {
    Scene s;
    if (!HeightScene(seed, s, /*max_vertices=*/3)) continue;
    ++scenes;
    pinholes += s.camera->pinhole.has_value();
    CheckVertices(s, seed, /*exact=*/true, vertices);
    CheckRays(s, seed, /*exact=*/true, robot);
  }
  std::printf("scenes %d (pinhole %d): vertices %d sure, %d unsure; robot samples %d sure, %d unsure\n", scenes,
              pinholes, vertices.agree, vertices.unsure, robot.agree, robot.unsure);
  EXPECT_GE(scenes, 35 / kStride);
  EXPECT_GE(pinholes, 12 / kStride);
  EXPECT_GE(scenes - pinholes, 12 / kStride) << "planar cameras with heights";
  EXPECT_GT(vertices.agree, 20 * vertices.unsure);
  EXPECT_GT(robot.agree, 1000 / kStride);
}

TEST(HeightsProperty, NonConvexAndOverlappingPrismsAreSound) {
  Tally vertices, robot;
  int scenes = 0;
  for (std::uint64_t seed = 101; seed <= 130; seed += kSeedStride) {
    Scene s;
    if (!HeightScene(seed, s, /*max_vertices=*/7)) continue;
    ++scenes;
    CheckVertices(s, seed, /*exact=*/false, vertices);
    CheckRays(s, seed, /*exact=*/false, robot);
  }
  std::printf("scenes %d: vertices %d sure, %d unsure; robot samples %d sure, %d unsure\n", scenes, vertices.agree,
              vertices.unsure, robot.agree, robot.unsure);
  EXPECT_GE(scenes, 25 / kStride);
  EXPECT_GT(robot.agree, 1000 / kStride);
}

// The CVC parts of random 2.5D scenes are the free parts of the seen pieces: every part lies inside a reported
// interval of its ray, and ends where the interval does are open.
TEST(HeightsProperty, CvcPartsLieWhereTheRobotIsSeen) {
  int parts = 0, cut_open = 0;
  for (std::uint64_t seed = 1; seed <= 30; ++seed) {
    Scene s;
    if (!HeightScene(seed, s, 5)) continue;
    const CSpace cspace(s);
    const VcRays rays = ComputeVcRays(s, cspace);
    for (const CvcRay& cvc : rays.cvc_rays) {
      const VcRay& ray = rays.vc_rays[cvc.vc_ray];
      const auto visible = VisibleRayParameters(s, ray.from);
      const Vector d = ray.to - ray.from;
      for (std::size_t k = 0; k < cvc.segments.size(); ++k) {
        ++parts;
        const double s0 = (cvc.segments[k].source - cvc.offset - ray.from).dot(d) / d.squaredNorm();
        const double s1 = (cvc.segments[k].target - cvc.offset - ray.from).dot(d) / d.squaredNorm();
        bool inside = false;
        for (const auto& [lo, hi] : visible) inside |= s0 >= lo - 1e-9 && s1 <= hi + 1e-9;
        EXPECT_TRUE(inside) << "seed " << seed << " " << cvc.id << " part " << k;
        for (const auto& [lo, hi] : visible) {
          if (std::abs(s1 - hi) < 1e-9 && hi < 1) {
            EXPECT_TRUE(cvc.open_ends[k][1]) << "seed " << seed << " " << cvc.id;
            ++cut_open;
          }
          if (std::abs(s0 - lo) < 1e-9 && lo > 0) {
            EXPECT_TRUE(cvc.open_ends[k][0]) << "seed " << seed << " " << cvc.id;
          }
        }
      }
    }
  }
  std::printf("parts %d, ends cut by visibility %d\n", parts, cut_open);
  EXPECT_GT(parts, 100);
  EXPECT_GT(cut_open, 20);
}

}  // namespace
}  // namespace visco::planning

#include "planning/scene.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "common/error.h"
#include "planning/scene_file.h"
#include "tests/planning/random_vc_scenes.h"
#include "tests/planning/scene_json.h"

namespace visco::planning {
namespace {

using Json = nlohmann::json;

Json BaseScene() {
  return Json::parse(R"({
    "name": "t",
    "bounds": {"min": [0, 0], "max": [10, 8]},
    "robot": {"polygon": [[0, 0], [1, 0], [1, 1], [0, 1]]},
    "obstacles": [{"id": "left", "polygon": [[0, 0], [4, 0], [4, 2], [0, 2]]},
                  {"id": "right", "polygon": [[5.5, 0], [10, 0], [10, 2], [5.5, 2]]}],
    "goal": {"polygon": [[4, 0], [4.5, 0], [4.5, 0.5], [4, 0.5]]},
    "start": {"polygon": [[1, 6], [2, 6], [2, 7], [1, 7]]},
    "camera": {"center": [9, 7.5], "fov_deg": [180, 270]},
    "uncertainty": {"velocity_cone_deg": 8, "position": 0.05},
    "friction_cone_deg": 15
  })");
}

// Expects ParseScene to throw InputError whose object and message contain the given texts.
void ExpectRejected(const Json& scene, const std::string& object, const std::string& what) {
  try {
    ParseScene(scene.dump(), "test.json");
    ADD_FAILURE() << "accepted: " << scene.dump();
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "test.json");
    EXPECT_NE(e.object().find(object), std::string::npos) << "object: " << e.object() << " / " << e.what();
    EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
  }
}

TEST(Scene, LoadsTheBaseScene) {
  const Scene scene = ParseScene(BaseScene().dump(), "test.json");
  EXPECT_EQ(scene.name, "t");
  EXPECT_EQ(scene.obstacles.size(), 2u);
  EXPECT_EQ(scene.obstacles[1].id, "right");
  ASSERT_TRUE(scene.camera.has_value());
  EXPECT_NEAR(scene.camera->fov_first_rad, M_PI, 1e-12);
  EXPECT_NEAR(scene.camera->fov_second_rad, 1.5 * M_PI, 1e-12);
  EXPECT_NEAR(scene.uncertainty.velocity_cone_rad, 8 * M_PI / 180, 1e-15);
  EXPECT_NEAR(scene.friction_cone_rad, 15 * M_PI / 180, 1e-15);
  EXPECT_TRUE(scene.start.has_value());
  EXPECT_TRUE(scene.camera->Sees({5, 2}));
  EXPECT_TRUE(scene.camera->Sees({9, 0}));    // on the limit direction 270 (limits belong to the view)
  EXPECT_TRUE(scene.camera->Sees({0, 7.5}));  // on the limit direction 180
  EXPECT_FALSE(scene.camera->Sees({9.5, 0}));
  EXPECT_FALSE(scene.camera->Sees({9, 7.5}));
}

TEST(Scene, NormalisesOrientationAndKeepsFileIndices) {
  Json j = BaseScene();
  j["obstacles"][0]["polygon"] = Json::parse("[[0, 0], [0, 2], [0, 2], [4, 2], [4, 0]]");  // clockwise, repeated
  const Scene scene = ParseScene(j.dump(), "test.json");
  const ScenePolygon& shape = scene.obstacles[0].shape;
  ASSERT_EQ(shape.polygon.size(), 4u);
  EXPECT_EQ(PolygonOrientation(shape.polygon), 1);
  for (std::size_t i = 0; i < shape.polygon.size(); ++i) {
    const int file_index = shape.source_index[i];
    const auto& written = j["obstacles"][0]["polygon"][file_index];
    EXPECT_EQ(shape.polygon[i], Point(written[0].get<double>(), written[1].get<double>()));
    EXPECT_NE(file_index, 2);  // the repeated vertex is dropped
  }
}

TEST(Scene, RejectsUnknownAndMissingFields) {
  Json j = BaseScene();
  j["frictoin_cone_deg"] = 3;
  ExpectRejected(j, "frictoin_cone_deg", "unknown field");
  j = BaseScene();
  j["camera"]["fov"] = 3;
  ExpectRejected(j, "camera.fov", "unknown field");
  j = BaseScene();
  j["obstacles"][1]["colour"] = "red";
  ExpectRejected(j, "obstacles[1] (right).colour", "unknown field");
  j = BaseScene();
  j.erase("goal");
  ExpectRejected(j, "goal", "missing field");
  j = BaseScene();
  j["uncertainty"].erase("position");
  ExpectRejected(j, "uncertainty.position", "missing field");
  j = BaseScene();
  j["obstacles"][0].erase("id");
  ExpectRejected(j, "obstacles[0].id", "missing field");
}

TEST(Scene, RejectsBadJsonAndNumbers) {
  try {
    ParseScene("{\"name\": ", "broken.json");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("invalid JSON"), std::string::npos);
  }
  // JSON has no NaN or infinity literal; an overflowing number is the way a non-finite value arrives.
  std::string text = BaseScene().dump();
  text.replace(text.find("\"position\":0.05"), 15, "\"position\":1e999");
  try {
    ParseScene(text, "test.json");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("number overflow parsing '1e999'"), std::string::npos) << e.what();
  }
  Json j = BaseScene();
  j["robot"]["polygon"][1][0] = "one";
  ExpectRejected(j, "robot.polygon[1][0]", "expected a number");
  j = BaseScene();
  j["bounds"]["max"] = Json::parse("[0, 8]");
  ExpectRejected(j, "bounds", "min must be smaller");
}

TEST(Scene, RejectsBadPolygons) {
  Json j = BaseScene();
  j["robot"]["polygon"] = Json::parse("[[0, 0], [1, 0], [1, 0], [0, 0]]");
  ExpectRejected(j, "robot.polygon", "at least 3 distinct vertices");
  j = BaseScene();
  j["obstacles"][0]["polygon"] = Json::parse("[[0, 0], [4, 2], [4, 0], [0, 2]]");
  ExpectRejected(j, "obstacles[0] (left).polygon", "not simple");
  j = BaseScene();
  j["goal"]["polygon"] = Json::parse("[[4, 0], [4.5, 0], [5, 0]]");
  ExpectRejected(j, "goal.polygon", "not simple");
  j = BaseScene();
  j["obstacles"][1]["id"] = "left";
  ExpectRejected(j, "obstacles[1] (left).id", "duplicate id");
}

TEST(Scene, AcceptsOverlappingAndTouchingObstacles) {
  // docs/semantics.md: scenes are built from overlapping parts; the obstacle region is their union.
  Json j = BaseScene();
  j["obstacles"][1]["polygon"] = Json::parse("[[3, 1], [10, 1], [10, 2], [3, 2]]");
  j["goal"]["polygon"] = Json::parse("[[4, 2], [4.5, 2], [4.5, 2.5], [4, 2.5]]");
  EXPECT_NO_THROW(ParseScene(j.dump(), "test.json"));
  // A funnel: a floor and two walls that overlap it, written in either orientation.
  j = BaseScene();
  j["obstacles"] = Json::parse(R"([{"id": "floor", "polygon": [[-1, -1], [11, -1], [11, 0.5], [-1, 0.5]]},
                                   {"id": "wall_l", "polygon": [[0, 0], [4, 0], [4, 3], [0, 3]]},
                                   {"id": "wall_r", "polygon": [[10, 0], [10, 3], [5.5, 3], [5.5, 0]]}])");
  j["goal"]["polygon"] = Json::parse("[[4, 0.5], [4.5, 0.5], [4.5, 1], [4, 1]]");
  const Scene funnel = ParseScene(j.dump(), "funnel.json");
  EXPECT_EQ(funnel.obstacles.size(), 3u);
  // The goal must still keep a free part in the union's C-space.
  j["goal"]["polygon"] = Json::parse("[[1, 0.5], [2, 0.5], [2, 1], [1, 1]]");
  ExpectRejected(j, "goal", "entirely inside the C-obstacles");
  j = BaseScene();
  j["obstacles"][1]["polygon"] = Json::parse("[[4, 0], [10, 0], [10, 1], [4, 1]]");  // shares part of an edge
  j["goal"]["polygon"] = Json::parse("[[4, 2], [4.5, 2], [4.5, 2.5], [4, 2.5]]");
  EXPECT_NO_THROW(ParseScene(j.dump(), "test.json"));
  j = BaseScene();
  j["obstacles"][1]["polygon"] = Json::parse("[[4, 2], [10, 2], [10, 3], [4, 3]]");  // shares a corner
  EXPECT_NO_THROW(ParseScene(j.dump(), "test.json"));
}

TEST(Scene, RejectsGoalOrStartInsideCObstacles) {
  Json j = BaseScene();
  // Inside CB of "left" (the robot's reference point at its lower-left corner, robot 1 x 1): x in (-1, 4).
  j["goal"]["polygon"] = Json::parse("[[1, 0], [3, 0], [3, 1], [1, 1]]");
  ExpectRejected(j, "goal", "entirely inside the C-obstacles");
  j = BaseScene();
  j["start"]["polygon"] = Json::parse("[[3.5, 0], [4, 0], [4, 1], [3.5, 1]]");  // touches the free slot only
  ExpectRejected(j, "start", "entirely inside the C-obstacles");
  j = BaseScene();
  j["start"]["polygon"] = Json::parse("[[4, 0], [4.5, 0], [4.5, 1], [4, 1]]");
  j["obstacles"][1]["polygon"] = Json::parse("[[5, 0], [10, 0], [10, 2], [5, 2]]");  // the slot closes to width 0
  j["goal"]["polygon"] = Json::parse("[[4, 2], [4.5, 2], [4.5, 2.5], [4, 2.5]]");
  ExpectRejected(j, "start", "entirely inside the C-obstacles");
  j = BaseScene();
  j["goal"]["polygon"] = Json::parse("[[3.5, 0], [4.1, 0], [4.1, 1], [3.5, 1]]");  // partly free: accepted
  EXPECT_NO_THROW(ParseScene(j.dump(), "test.json"));
}

TEST(Scene, RejectsBadCamera) {
  Json j = BaseScene();
  j["camera"]["center"] = Json::parse("[2, 1]");
  ExpectRejected(j, "camera", "inside obstacles[0] (left)");
  j = BaseScene();
  j["camera"]["center"] = Json::parse("[4, 1]");  // on an obstacle's boundary: allowed
  EXPECT_NO_THROW(ParseScene(j.dump(), "test.json"));
  j = BaseScene();
  j["camera"]["fov_deg"] = Json::parse("[90, 90]");
  ExpectRejected(j, "camera.fov_deg", "empty");
  j = BaseScene();
  j["camera"]["fov_deg"] = Json::parse("[0, 180]");
  ExpectRejected(j, "camera.fov_deg", "narrower than 180");
  j = BaseScene();
  j["camera"]["fov_deg"] = Json::parse("[270, 180]");  // counter-clockwise from 270 to 180 is 270 degrees
  ExpectRejected(j, "camera.fov_deg", "270 degrees wide");
  j = BaseScene();
  j["camera"]["fov_deg"] = Json::parse("[0, 360]");
  ExpectRejected(j, "camera.fov_deg", "full turn");
  j = BaseScene();
  j["camera"]["fov_deg"] = Json::parse("[-100, 170]");  // 270 wide
  ExpectRejected(j, "camera.fov_deg", "narrower than 180");
  j = BaseScene();
  j["camera"]["fov_deg"] = Json::parse("[350, 370]");  // 20 wide, across 0
  const Scene scene = ParseScene(j.dump(), "test.json");
  EXPECT_NEAR(scene.camera->fov_second_rad - scene.camera->fov_first_rad, 20 * M_PI / 180, 1e-12);
}

TEST(Scene, RejectsBadAngles) {
  Json j = BaseScene();
  j["uncertainty"]["position"] = -0.1;
  ExpectRejected(j, "uncertainty.position", "negative");
  j = BaseScene();
  j["uncertainty"]["velocity_cone_deg"] = 90;
  ExpectRejected(j, "uncertainty.velocity_cone_deg", "outside [0, 90)");
  j = BaseScene();
  j["uncertainty"]["velocity_cone_deg"] = -1;
  ExpectRejected(j, "uncertainty.velocity_cone_deg", "outside [0, 90)");
  j = BaseScene();
  j["friction_cone_deg"] = 95;
  ExpectRejected(j, "friction_cone_deg", "outside [0, 90)");
  j = BaseScene();
  j["friction_cone_deg"] = 0;
  EXPECT_NO_THROW(ParseScene(j.dump(), "test.json"));
}

// A pinhole camera at (5, -3, 4) looking at (5, 4, 0): camera x = world +x, z towards the target, y = z x x (down).
Json PinholeCamera(const Eigen::Vector3d& centre, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - centre).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Json m = Json::array();
  for (int r = 0; r < 3; ++r) m.push_back({x[r], y[r], z[r], centre[r]});
  m.push_back({0, 0, 0, 1});
  return {
      {"pinhole", {{"px", 500}, {"py", 500}, {"u0", 320}, {"v0", 240}, {"width", 640}, {"height", 480}, {"wMc", m}}}};
}

TEST(Scene, PinholeCameraGivesFootPointAndFootprint) {
  Json j = BaseScene();
  j["camera"] = PinholeCamera({5, -3, 4}, {5, 4, 0});
  const Scene scene = ParseScene(j.dump(), "test.json");
  ASSERT_TRUE(scene.camera && scene.camera->pinhole);
  EXPECT_NEAR(scene.camera->center.x(), 5, 1e-12);
  EXPECT_NEAR(scene.camera->center.y(), -3, 1e-12);
  // Closed form: with n = |(0, 7, -4)|, the ray of normalised image point (x, y) has horizontal part
  // (x, (7 - 4 y) / n); the widest azimuths are at the top corners x = +-0.64, y = -0.48.
  const double half = std::atan2(0.64 * std::sqrt(65.0), 7 - 4 * 0.48);
  EXPECT_NEAR(scene.camera->fov_first_rad, M_PI / 2 - half, 1e-9);
  EXPECT_NEAR(scene.camera->fov_second_rad, M_PI / 2 + half, 1e-9);
  // The pinhole example scene loads.
  const Scene example = LoadScene("data/scenes/slot_pinhole.json");
  EXPECT_NEAR(example.camera->center.x(), 11, 1e-12);
  EXPECT_GT(example.camera->fov_second_rad - example.camera->fov_first_rad, 0.5);
}

TEST(Scene, PinholeCameraRejections) {
  Json j = BaseScene();
  j["camera"] = PinholeCamera({5, 3, 6}, {5, 3.1, 0});  // looking (almost) straight down: sees its foot point
  ExpectRejected(j, "camera.pinhole", "foot point");
  j["camera"] = PinholeCamera({5, 3, -1}, {5, 6, -2});  // below the plane
  ExpectRejected(j, "camera.pinhole", "above the motion plane");
  j["camera"] = PinholeCamera({5, 3, 2}, {5, 10, 8});  // looking up: the image misses the plane
  ExpectRejected(j, "camera.pinhole", "does not see the motion plane");
  j["camera"] = PinholeCamera({5, -3, 4}, {5, 4, 0});
  j["camera"]["pinhole"]["wMc"][0][0] = 2.0;
  ExpectRejected(j, "camera.pinhole.wMc", "not a rotation");
  j["camera"] = PinholeCamera({5, -3, 4}, {5, 4, 0});
  j["camera"]["pinhole"]["fov"] = 3;
  ExpectRejected(j, "camera.pinhole.fov", "unknown field");
  j["camera"] = PinholeCamera({5, -3, 4}, {5, 4, 0});
  j["camera"]["center"] = {1, 1};
  ExpectRejected(j, "camera.center", "unknown field");
}

TEST(Scene, LoadScene) {
  EXPECT_THROW(LoadScene("/nonexistent/scene.json"), InputError);
  const Scene slot = LoadScene("data/scenes/slot.json");
  EXPECT_EQ(slot.name, "slot");
  EXPECT_EQ(slot.source, "data/scenes/slot.json");
  const Scene embedded = DefaultScene();
  EXPECT_EQ(embedded.name, "slot");
  EXPECT_EQ(embedded.obstacles.size(), slot.obstacles.size());
  std::ifstream in("data/scenes/slot.json");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(std::string(DefaultSceneJson()), text);
}

// The tests' scene writer (tests/planning/scene_json.h, for reproducing a failing random scene with the command-line
// tools) gives back the same scene: random scenes with heights and a planar camera, and both pinhole example scenes.
TEST(SceneJson, WrittenScenesLoadAsTheSameScene) {
  std::vector<Scene> scenes = {LoadScene("data/scenes/slot_pinhole.json"), LoadScene("data/scenes/fig13.json")};
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    Scene s;
    double theta = 0;
    if (!testing::RandomWholeScene(seed, s, theta, 2, 1)) continue;
    if (seed % 2 == 0) {
      for (Obstacle& o : s.obstacles) o.height = 0.5 + 0.1 * static_cast<double>(seed);
      if (s.camera) s.camera->height = 3.0;
    }
    testing::PlaceStartRegion(seed, s);
    scenes.push_back(s);
  }
  ASSERT_GE(scenes.size(), 8u);
  for (const Scene& a : scenes) {
    const Scene b = ParseScene(testing::SceneToJson(a), "written");
    EXPECT_EQ(b.bounds.min, a.bounds.min);
    EXPECT_EQ(b.bounds.max, a.bounds.max);
    EXPECT_EQ(b.robot.polygon.vertices, a.robot.polygon.vertices);
    ASSERT_EQ(b.obstacles.size(), a.obstacles.size());
    for (size_t i = 0; i < a.obstacles.size(); ++i) {
      EXPECT_EQ(b.obstacles[i].id, a.obstacles[i].id);
      EXPECT_EQ(b.obstacles[i].shape.polygon.vertices, a.obstacles[i].shape.polygon.vertices);
      EXPECT_EQ(b.obstacles[i].height, a.obstacles[i].height);
    }
    EXPECT_EQ(b.goal.polygon.vertices, a.goal.polygon.vertices);
    ASSERT_EQ(b.start.has_value(), a.start.has_value());
    if (a.start) {
      EXPECT_EQ(b.start->polygon.vertices, a.start->polygon.vertices);
    }
    ASSERT_EQ(b.camera.has_value(), a.camera.has_value());
    if (a.camera) {
      EXPECT_EQ(b.camera->center, a.camera->center);
      EXPECT_NEAR(b.camera->fov_first_rad, a.camera->fov_first_rad, 1e-12);
      EXPECT_NEAR(b.camera->fov_second_rad, a.camera->fov_second_rad, 1e-12);
      EXPECT_EQ(b.camera->height, a.camera->height);
      EXPECT_EQ(b.camera->pinhole.has_value(), a.camera->pinhole.has_value());
    }
    EXPECT_NEAR(b.uncertainty.velocity_cone_rad, a.uncertainty.velocity_cone_rad, 1e-15);
    EXPECT_EQ(b.uncertainty.position, a.uncertainty.position);
    EXPECT_EQ(b.uncertainty.vc_tracking, a.uncertainty.vc_tracking);
    EXPECT_NEAR(b.friction_cone_rad, a.friction_cone_rad, 1e-15);
  }
}

}  // namespace
}  // namespace visco::planning

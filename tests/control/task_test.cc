// Loading strategies (contract JSON and LCM), rays and scenes; the goal kernel against a brute-force reference.

#include "control/task.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <random>
#include <string>

#include "common/error.h"
#include "visco/motion_strategy_t.hpp"

namespace visco::control {
namespace {

constexpr char kRays[] = R"({
  "vc_rays": [{"id": "vc0", "obstacle": "left", "vertex": 2, "from": [4, 2], "to": [9, 7.5]}],
  "cvc_rays": [{"id": "vc0.cm0", "vc_ray": "vc0", "cm_vertex": 0, "segments": [[[4, 2], [9, 7.5]]]},
               {"id": "vc0.cm2", "vc_ray": "vc0", "cm_vertex": 2, "segments": [[[3, 1], [8, 6.5]]]}]})";

constexpr char kPlan[] = R"({
  "feasible": true, "speed": 0.04,
  "steps": [
    {"theta_deg": -90, "active_rays": ["vc0.cm2"], "terminate": {"kind": "vc", "ref": "vc0.cm0"}, "preimage": {}},
    {"theta_deg": 0, "active_rays": [], "terminate": {"kind": "contact", "ref": null}, "timeout_s": 12},
    {"theta_deg": 180, "active_rays": [], "terminate": {"kind": "goal", "ref": null}}]})";

std::string WriteTemp(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

TEST(Task, ParsesTheContractStrategyWithRays) {
  const std::vector<CvcRay> rays = LoadRays(WriteTemp("rays.json", kRays));
  ASSERT_EQ(rays.size(), 2u);
  EXPECT_EQ(rays[1].cm_vertex, 2);
  EXPECT_NEAR(Norm(rays[1].direction), 1.0, 1e-12);
  EXPECT_NEAR(rays[1].direction.x, 5.0 / std::hypot(5.0, 5.5), 1e-12);
  const Task task = ParseStrategyJson(kPlan, "plan.json", rays);
  ASSERT_EQ(task.steps.size(), 3u);
  EXPECT_DOUBLE_EQ(task.speed, 0.04);
  EXPECT_NEAR(task.steps[0].theta, -std::numbers::pi / 2, 1e-15);
  EXPECT_EQ(task.steps[0].terminate, TerminateKind::kVisualGuarded);
  EXPECT_EQ(task.steps[0].terminate_ray, 0);
  EXPECT_EQ(task.steps[0].active_rays, std::vector<int>{1});
  EXPECT_EQ(task.steps[1].terminate, TerminateKind::kContact);
  EXPECT_DOUBLE_EQ(task.steps[1].timeout_s, 12.0);
  EXPECT_EQ(task.steps[2].terminate, TerminateKind::kGoal);
}

TEST(Task, BadStrategiesNameTheObject) {
  auto message = [](const std::string& json) {
    try {
      ParseStrategyJson(json, "plan.json", {});
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message("{"), message("{").substr(0, 0) + message("{"));  // stable
  EXPECT_NE(message("{").find("plan.json: not valid JSON"), std::string::npos);
  EXPECT_NE(message(R"({"steps": []})").find("plan.json: steps: must be a non-empty array"), std::string::npos);
  EXPECT_NE(message(R"({"steps": [{"terminate": {"kind": "goal"}}]})").find("steps[0]: missing \"theta_deg\""),
            std::string::npos);
  EXPECT_NE(message(R"({"steps": [{"theta_deg": 0, "terminate": {"kind": "jump"}}]})")
                .find("steps[0].terminate.kind: unknown terminate kind \"jump\""),
            std::string::npos);
  EXPECT_NE(message(R"({"steps": [{"theta_deg": 0, "terminate": {"kind": "vc", "ref": null}}]})")
                .find("steps[0].terminate.ref"),
            std::string::npos);
  EXPECT_THROW(ParseStrategyJson(R"({"feasible": false, "steps": []})", "plan.json", {}), JobFailed);
  // With a rays file, unknown ray ids are errors.
  const std::vector<CvcRay> rays = LoadRays(WriteTemp("rays2.json", kRays));
  EXPECT_THROW(
      ParseStrategyJson(R"({"steps": [{"theta_deg": 0, "terminate": {"kind": "vc", "ref": "nope"}}]})", "p", rays),
      InputError);
}

TEST(Task, ConvertsTheLcmStrategy) {
  motion_strategy_t m;
  m.feasible = true;
  m.speed = 0.03;
  m.scene = "slot";
  motion_step_t s;
  s.theta = 0.5;
  s.num_active_rays = 0;
  s.terminate_kind = motion_step_t::TERMINATE_VC;
  s.terminate_ref = "vc0.cm0";
  s.timeout_s = 3;
  m.steps.push_back(s);
  s.terminate_kind = motion_step_t::TERMINATE_CONTACT;
  s.terminate_ref = "";
  m.steps.push_back(s);
  m.num_steps = 2;
  const Task task = FromLcm(m, {});
  ASSERT_EQ(task.steps.size(), 2u);
  EXPECT_EQ(task.steps[0].terminate_ray, 0);
  EXPECT_EQ(task.rays[0].id, "vc0.cm0");
  EXPECT_EQ(task.rays[0].cm_vertex, -1);  // no geometry: fine for guarded motion only
  EXPECT_EQ(task.steps[1].terminate, TerminateKind::kContact);
  m.steps[1].terminate_kind = 9;
  EXPECT_THROW(FromLcm(m, {}), InputError);
}

TEST(Task, SceneAttachesGoalBoundsAndVertexOffsets) {
  const std::string scene = WriteTemp("scene.json", R"({
    "name": "slot", "bounds": {"min": [0, 0], "max": [10, 8]},
    "robot": {"polygon": [[0, 0], [1, 0], [1, 1], [0, 1]]},
    "obstacles": [{"id": "left", "polygon": [[0, 0], [4, 0], [4, 2], [0, 2]]}],
    "goal": {"polygon": [[4, 0], [5, 0], [5, 0.5], [4, 0.5]]},
    "camera": {"center": [9, 7.5], "fov_deg": [180, 270]},
    "uncertainty": {"velocity_cone_deg": 8, "position": 0.05}, "friction_cone_deg": 15})");
  const SceneInfo info = LoadScene(scene);
  Task task = ParseStrategyJson(kPlan, "plan.json", LoadRays(WriteTemp("rays3.json", kRays)));
  AttachScene(task, info, scene);
  EXPECT_TRUE(task.goal.has_value());
  EXPECT_DOUBLE_EQ(task.position_uncertainty, 0.05);
  EXPECT_TRUE(task.rays[1].has_cm_offset);
  EXPECT_DOUBLE_EQ(task.rays[1].cm_offset.x, 1.0);
  EXPECT_DOUBLE_EQ(task.rays[1].cm_offset.y, 1.0);
  EXPECT_NEAR(info.friction_cone, 15 * std::numbers::pi / 180, 1e-12);
  EXPECT_NO_THROW(ValidateTask(task, "plan.json"));
  EXPECT_THROW(LoadScene(WriteTemp("bad.json", R"({"robot": {"polygon": [[0, 0], [1, 0]]}})")), InputError);
}

// A strategy or rays file made for another scene is refused (a strategy planned for the slot drove the
// robot out of another scene's workspace). The digest is of the scene's content, whatever its spacing and key order.
TEST(Task, FilesMadeForAnotherSceneAreRefused) {
  const char* const kScene = R"({"name": "slot", "bounds": {"min": [0, 0], "max": [10, 8]},
    "robot": {"polygon": [[0, 0], [1, 0], [1, 1], [0, 1]]}, "obstacles": [],
    "goal": {"polygon": [[4, 0], [5, 0], [5, 0.5], [4, 0.5]]},
    "uncertainty": {"velocity_cone_deg": 8, "position": 0.05}, "friction_cone_deg": 15})";
  const SceneInfo scene = LoadScene(WriteTemp("digest_a.json", kScene));
  EXPECT_EQ(scene.digest.size(), 16u);
  EXPECT_TRUE(scene.named);
  // The same content written otherwise: the same digest.
  const SceneInfo same = LoadScene(WriteTemp("digest_b.json", R"({"friction_cone_deg": 15,
      "uncertainty": {"position": 0.05, "velocity_cone_deg": 8}, "goal": {"polygon": [[4, 0], [5, 0], [5, 0.5],
      [4, 0.5]]}, "obstacles": [], "robot": {"polygon": [[0, 0], [1, 0], [1, 1], [0, 1]]},
      "bounds": {"max": [10, 8], "min": [0, 0]}, "name": "slot"})"));
  EXPECT_EQ(same.digest, scene.digest);
  // The goal moved, the name kept: another digest.
  std::string moved = kScene;
  moved.replace(moved.find("[4, 0], [5, 0]"), 14, "[4, 1], [5, 1]");
  const SceneInfo edited = LoadScene(WriteTemp("digest_c.json", moved));
  EXPECT_NE(edited.digest, scene.digest);
  EXPECT_EQ(edited.name, "slot");

  auto message = [](auto&& check) {
    try {
      check();
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message([&] {
              CheckMadeFor({"slot", scene.digest}, "strategy", "plan.json", same, "b.json");
            }),
            "no error");
  const std::string edited_message = message([&] {
    CheckMadeFor({"slot", scene.digest}, "strategy", "plan.json", edited, "c.json");
  });
  EXPECT_EQ(edited_message.find("plan.json: scene: the strategy was planned for scene \"slot\" (scene_digest " +
                                scene.digest + "), not for c.json, which is scene \"slot\" (scene_digest " +
                                edited.digest + ")"),
            0u)
      << edited_message;
  EXPECT_NE(edited_message.find("the scene file was edited"), std::string::npos);
  const std::string rays_message = message([&] {
    CheckMadeFor({"corner", "0123456789abcdef"}, "rays", "rays.json", scene, "a.json");
  });
  EXPECT_NE(rays_message.find("rays.json: scene: the rays were computed for scene \"corner\""), std::string::npos)
      << rays_message;
  EXPECT_NE(rays_message.find("visco vcrays a.json"), std::string::npos) << rays_message;
  // Files from before the digest, and LCM strategies: the names decide, when the scene file names itself.
  EXPECT_NE(message([&] { CheckMadeFor({"corner", ""}, "strategy", "old.json", scene, "a.json"); }), "no error");
  EXPECT_EQ(message([&] { CheckMadeFor({"slot", ""}, "strategy", "old.json", scene, "a.json"); }), "no error");
  EXPECT_EQ(message([&] { CheckMadeFor({}, "strategy", "hand_written.json", scene, "a.json"); }), "no error");
  std::string unnamed = kScene;
  unnamed.replace(unnamed.find("\"name\": \"slot\", "), 16, "");
  const SceneInfo stem = LoadScene(WriteTemp("scene.json", unnamed));
  EXPECT_FALSE(stem.named);
  EXPECT_EQ(stem.name, "scene");  // as the planner names it
  EXPECT_EQ(message([&] { CheckMadeFor({"corner", ""}, "strategy", "old.json", stem, "scene.json"); }), "no error");
  // A strategy and rays of different scenes, with no scene file to compare them with.
  EXPECT_NE(message([&] {
              CheckSameScene({"slot", scene.digest}, "plan.json", {"slot", edited.digest}, "rays.json");
            }).find("rays.json: scene: the rays were computed for"),
            std::string::npos);
  EXPECT_EQ(message([&] {
              CheckSameScene({"slot", scene.digest}, "plan.json", {"slot", ""}, "rays.json");
            }),
            "no error");
}

// A rays file without rays (a scene without a camera) is still a rays file: a ray the strategy names is not in it
// (not "give the rays with --rays", which was given).
TEST(Task, AnEmptyRaysFileIsARaysFile) {
  const std::string plan =
      R"({"steps": [{"theta_deg": 0, "active_rays": ["vc9.cm1"], "terminate": {"kind": "goal"}}]})";
  try {
    ParseStrategyJson(plan, "plan.json", {}, true);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("CVC ray \"vc9.cm1\" is not in the rays file"), std::string::npos) << e.what();
  }
}

// Property: the kernel test equals "a dense ring of points at distance r around p lies in the goal" on seeded
// random star-shaped goals (a slow, obvious reading of the Minkowski difference with a disc).
TEST(TaskProperty, GoalKernelMatchesDiscContainment) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int inside = 0;
  for (int trial = 0; trial < 60; ++trial) {
    Polygon goal;
    const int n = 3 + static_cast<int>(unit(rng) * 8);
    for (int i = 0; i < n; ++i) {
      const double a = 2 * std::numbers::pi * (i + 0.8 * unit(rng)) / n;
      const double r = 0.5 + unit(rng);
      goal.vertices.push_back({r * std::cos(a), r * std::sin(a)});
    }
    const double erosion = 0.05 + 0.2 * unit(rng);
    for (int k = 0; k < 200; ++k) {
      const Vec2 p{3 * unit(rng) - 1.5, 3 * unit(rng) - 1.5};
      bool reference = InPolygon(goal, p);
      for (int s = 0; s < 360 && reference; ++s) {
        const double a = 2 * std::numbers::pi * s / 360;
        for (double f : {0.25, 0.5, 0.75, 1.0}) {
          if (!InPolygon(goal, p + (f * erosion) * FromAngle(a))) reference = false;
        }
      }
      const double margin = BoundaryDistance(goal, p) - erosion;
      if (std::abs(margin) < 1e-3) continue;  // the ring's sampling cannot decide this close
      EXPECT_EQ(InKernel(goal, erosion, p), reference) << "trial " << trial << " point " << p.x << "," << p.y;
      inside += reference;
    }
  }
  EXPECT_GT(inside, 100);  // the test exercised both outcomes
}

}  // namespace
}  // namespace visco::control

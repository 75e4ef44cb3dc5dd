#pragma once
// What the executor runs: a motion strategy (the contract's `visco plan` JSON or the LCM motion_strategy_t) and
// the geometry it needs at run time (CVC rays from `visco vcrays`, the goal, the bounds, the robot polygon and the
// camera from the scene file). Built and validated once at setup (not real-time safe); read-only afterwards.

#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "control/types.h"

namespace visco {
class motion_strategy_t;
}

namespace visco::control {

/// How a step ends (values equal motion_step_t::TERMINATE_*).
enum class TerminateKind : std::int8_t { kGoal = 1, kVisualGuarded = 2, kContact = 3 };
const char* ToString(TerminateKind kind);

/// One step: commanded direction, rays to comply to, termination, time-out.
struct Step {
  double theta = 0.0;            // radians, commanded direction, CCW from world +x
  std::vector<int> active_rays;  // indices into Task::rays
  TerminateKind terminate = TerminateKind::kGoal;
  int terminate_ray = -1;  // index into Task::rays for kVisualGuarded, else -1
  double timeout_s = 0.0;  // seconds, 0 = the executor's default
};

/// A CVC ray as the executor needs it. The workspace VC ray runs from the obstacle vertex `from` to the camera
/// centre `to`; the CVC ray is its copy displaced by -(robot vertex cm_vertex) so that the reference point lies
/// on the CVC ray exactly when the CM vertex lies on the VC ray.
struct CvcRay {
  std::string id;      // planner's CVC ray id
  std::string vc_ray;  // workspace VC ray id
  int cm_vertex = -1;  // robot polygon vertex index
  Vec2 from;           // metres, workspace obstacle vertex
  Vec2 to;             // metres, camera projection centre (foot point)
  Vec2 direction;      // unit vector from `from` to `to` (the visual_event_t sign convention's ray direction)
  Vec2 cm_offset;      // metres, robot-frame position of the CM vertex (0 if the scene is not known)
  bool has_cm_offset = false;
};

/// Axis-aligned workspace bounds of the reference point.
struct Bounds {
  Vec2 min;
  Vec2 max;
};

/// A simple polygon (counter-clockwise or clockwise; tests use winding-independent predicates).
struct Polygon {
  std::vector<Vec2> vertices;
};

/// The subset of the contract's scene file that execution and simulation need.
struct SceneInfo {
  std::string name;    // the scene's "name", or the file's stem as the planner names it
  bool named = false;  // the file has a "name" (a stem says little: the demo's copy of any scene is scene.json)
  std::string digest;  // common/scene_digest.h: what plans and rays record of the scene they were made for
  std::optional<Bounds> bounds;
  Polygon robot;
  struct Obstacle {
    std::string id;
    Polygon polygon;
  };
  std::vector<Obstacle> obstacles;
  std::optional<Polygon> goal;
  std::optional<Polygon> start;
  std::optional<Vec2> camera_center;
  double velocity_cone = 0.0;         // radians, half-angle ε_v
  double position_uncertainty = 0.0;  // metres, ε_p
  double friction_cone = 0.0;         // radians, half-angle φ
};

/// Everything the executor runs.
struct Task {
  std::string scene;
  double speed = 0.0;  // m/s, commanded speed (0 = the executor's default)
  std::vector<Step> steps;
  std::vector<CvcRay> rays;
  std::optional<Polygon> goal;
  double position_uncertainty = 0.0;  // metres, ε_p: the goal kernel is the goal eroded by this disc
  std::optional<Bounds> bounds;
  std::optional<SceneInfo> scene_info;

  /// Index of the ray named `id`, or -1. Not real-time safe (hash lookup on strings).
  int RayIndex(const std::string& id) const;
  std::unordered_map<std::string, int> ray_index;
};

/// The scene a strategy or rays file says it was made for: its top-level "scene" (name) and "scene_digest", each
/// empty when absent (hand-written files, files from before the digest).
struct SceneIdentity {
  std::string name;
  std::string digest;
};

/// Reads a scene file (docs/formats.md). @throws InputError naming the file and object if it is malformed.
SceneInfo LoadScene(const std::string& path);
/// Reads `visco vcrays` output. @throws InputError.
std::vector<CvcRay> LoadRays(const std::string& path);
/// Reads the scene identity of a strategy or rays file. @throws InputError if it is unreadable or not JSON.
SceneIdentity ReadSceneIdentity(const std::string& path);
/// Refuses a file made for another scene: `what` ("strategy", "rays") read from `path` says it was made for
/// `made_for`; the scene is `scene`, read from `scene_path`. Digests decide when both are known; otherwise the names,
/// when the file names a scene and the scene file names itself. @throws InputError(path, "scene", ...) naming both
/// files and both scenes.
void CheckMadeFor(const SceneIdentity& made_for, const std::string& what, const std::string& path,
                  const SceneInfo& scene, const std::string& scene_path);
/// Refuses a strategy and a rays file made for different scenes (both digests known). @throws InputError.
void CheckSameScene(const SceneIdentity& strategy, const std::string& strategy_path, const SceneIdentity& rays,
                    const std::string& rays_path);
/// Parses the contract's `visco plan` JSON (plus optional extensions: top-level "speed" in m/s, per step
/// "timeout_s"). `source` names the input in errors. Rays named by the strategy must be in `rays` when a rays file
/// was given (`rays_given`) or `rays` is not empty; compliant steps need them. @throws InputError, JobFailed if the
/// strategy says it is infeasible.
Task ParseStrategyJson(const std::string& json_text, const std::string& source, const std::vector<CvcRay>& rays,
                       bool rays_given = false);
Task LoadStrategyFile(const std::string& path, const std::vector<CvcRay>& rays, bool rays_given = false);
/// Converts the LCM strategy. @throws InputError (source "VISCO_STRATEGY").
Task FromLcm(const motion_strategy_t& message, const std::vector<CvcRay>& rays, bool rays_given = false);
/// Adds the scene's goal, bounds, ε_p and robot vertex offsets to the task. @throws InputError on inconsistency
/// (a ray's cm_vertex not in the robot polygon).
void AttachScene(Task& task, const SceneInfo& scene, const std::string& scene_path);
/// Checks the task for execution: ray indices, visual steps have ray geometry, capacity. @throws InputError.
void ValidateTask(const Task& task, const std::string& source);

/// True if `p` is in the closed polygon. Real-time safe.
bool InPolygon(const Polygon& polygon, Vec2 p);
/// Distance from `p` to the polygon's boundary. Real-time safe.
double BoundaryDistance(const Polygon& polygon, Vec2 p);
/// True if `p` is in the goal kernel: in the goal and at least `erosion` from its boundary (the goal eroded by the
/// closed disc of radius `erosion`, docs/semantics.md). Real-time safe.
bool InKernel(const Polygon& goal, double erosion, Vec2 p);

}  // namespace visco::control

#include "control/task.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>

#include "common/error.h"
#include "common/scene_digest.h"
#include "visco/motion_strategy_t.hpp"

namespace visco::control {
namespace {

using nlohmann::json;
constexpr double kDegToRad = std::numbers::pi / 180.0;

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "", "cannot open the file");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

json ParseJson(const std::string& text, const std::string& source) {
  try {
    return json::parse(text);
  } catch (const json::parse_error& e) {
    throw InputError(source, "", std::string("not valid JSON: ") + e.what());
  }
}

const json& Member(const json& object, const char* key, const std::string& source, const std::string& where) {
  if (!object.is_object() || !object.contains(key)) {
    throw InputError(source, where, std::string("missing \"") + key + "\"");
  }
  return object.at(key);
}

double Number(const json& value, const std::string& source, const std::string& where) {
  if (!value.is_number()) throw InputError(source, where, "must be a number");
  const double x = value.get<double>();
  if (!std::isfinite(x)) throw InputError(source, where, "must be finite");
  return x;
}

Vec2 Point(const json& value, const std::string& source, const std::string& where) {
  if (!value.is_array() || value.size() != 2) throw InputError(source, where, "must be a point [x, y]");
  return {Number(value[0], source, where + "[0]"), Number(value[1], source, where + "[1]")};
}

Polygon ReadPolygon(const json& value, const std::string& source, const std::string& where) {
  if (!value.is_array() || value.size() < 3) {
    throw InputError(source, where, "must be an array of at least 3 points");
  }
  Polygon polygon;
  for (std::size_t i = 0; i < value.size(); ++i) {
    polygon.vertices.push_back(Point(value[i], source, where + "[" + std::to_string(i) + "]"));
  }
  return polygon;
}

TerminateKind ParseKind(const std::string& kind, const std::string& source, const std::string& where) {
  if (kind == "goal") return TerminateKind::kGoal;
  if (kind == "vc") return TerminateKind::kVisualGuarded;
  if (kind == "contact") return TerminateKind::kContact;
  throw InputError(source, where, "unknown terminate kind \"" + kind + "\" (expected goal, vc or contact)");
}

// Resolves a ray id against the task's table, adding a geometry-less entry when no ray file was given (visual
// guarded steps only need the events; ValidateTask rejects compliant steps without geometry).
int ResolveRay(Task& task, const std::string& id, const std::string& source, const std::string& where,
               bool have_table) {
  const int index = task.RayIndex(id);
  if (index >= 0) return index;
  if (have_table) throw InputError(source, where, "CVC ray \"" + id + "\" is not in the rays file");
  CvcRay ray;
  ray.id = id;
  task.rays.push_back(ray);
  const int added = static_cast<int>(task.rays.size()) - 1;
  task.ray_index[id] = added;
  return added;
}

void InitRays(Task& task, const std::vector<CvcRay>& rays) {
  task.rays = rays;
  task.ray_index.clear();
  for (std::size_t i = 0; i < rays.size(); ++i) task.ray_index[rays[i].id] = static_cast<int>(i);
}

}  // namespace

const char* ToString(TerminateKind kind) {
  switch (kind) {
    case TerminateKind::kGoal:
      return "goal";
    case TerminateKind::kVisualGuarded:
      return "vc";
    case TerminateKind::kContact:
      return "contact";
  }
  return "?";
}

int Task::RayIndex(const std::string& id) const {
  const auto it = ray_index.find(id);
  return it == ray_index.end() ? -1 : it->second;
}

SceneInfo LoadScene(const std::string& path) {
  const json scene = ParseJson(ReadFile(path), path);
  if (!scene.is_object()) throw InputError(path, "", "a scene must be a JSON object");
  SceneInfo info;
  info.digest = SceneDigest(scene.dump());
  if (scene.contains("name") && scene.at("name").is_string()) {
    info.name = scene.at("name").get<std::string>();
    info.named = true;
  } else {  // as the planner names it
    info.name = std::filesystem::path(path).filename().string();
    info.name = info.name.substr(0, info.name.find('.'));
  }
  if (scene.contains("bounds")) {
    const json& b = scene.at("bounds");
    Bounds bounds{Point(Member(b, "min", path, "bounds"), path, "bounds.min"),
                  Point(Member(b, "max", path, "bounds"), path, "bounds.max")};
    if (!(bounds.min.x < bounds.max.x && bounds.min.y < bounds.max.y)) {
      throw InputError(path, "bounds", "min must be below max in x and y");
    }
    info.bounds = bounds;
  }
  info.robot = ReadPolygon(Member(Member(scene, "robot", path, ""), "polygon", path, "robot"), path, "robot.polygon");
  if (scene.contains("obstacles")) {
    const json& obstacles = scene.at("obstacles");
    if (!obstacles.is_array()) throw InputError(path, "obstacles", "must be an array");
    for (std::size_t i = 0; i < obstacles.size(); ++i) {
      const std::string where = "obstacles[" + std::to_string(i) + "]";
      SceneInfo::Obstacle obstacle;
      obstacle.id = obstacles[i].contains("id") && obstacles[i].at("id").is_string()
                        ? obstacles[i].at("id").get<std::string>()
                        : std::to_string(i);
      obstacle.polygon = ReadPolygon(Member(obstacles[i], "polygon", path, where), path, where + ".polygon");
      info.obstacles.push_back(std::move(obstacle));
    }
  }
  if (scene.contains("goal"))
    info.goal = ReadPolygon(Member(scene.at("goal"), "polygon", path, "goal"), path, "goal.polygon");
  if (scene.contains("start")) {
    info.start = ReadPolygon(Member(scene.at("start"), "polygon", path, "start"), path, "start.polygon");
  }
  if (scene.contains("camera") && scene.at("camera").contains("center")) {
    info.camera_center = Point(scene.at("camera").at("center"), path, "camera.center");
  }
  if (scene.contains("uncertainty")) {
    const json& u = scene.at("uncertainty");
    if (u.contains("velocity_cone_deg")) {
      info.velocity_cone = Number(u.at("velocity_cone_deg"), path, "uncertainty.velocity_cone_deg") * kDegToRad;
    }
    if (u.contains("position")) info.position_uncertainty = Number(u.at("position"), path, "uncertainty.position");
    if (info.velocity_cone < 0 || info.velocity_cone >= std::numbers::pi / 2) {
      throw InputError(path, "uncertainty.velocity_cone_deg", "must be in [0, 90)");
    }
    if (info.position_uncertainty < 0) throw InputError(path, "uncertainty.position", "must not be negative");
  }
  if (scene.contains("friction_cone_deg")) {
    info.friction_cone = Number(scene.at("friction_cone_deg"), path, "friction_cone_deg") * kDegToRad;
    if (info.friction_cone < 0 || info.friction_cone >= std::numbers::pi / 2) {
      throw InputError(path, "friction_cone_deg", "must be in [0, 90)");
    }
  }
  return info;
}

std::vector<CvcRay> LoadRays(const std::string& path) {
  const json doc = ParseJson(ReadFile(path), path);
  const json& vc_rays = Member(doc, "vc_rays", path, "");
  const json& cvc_rays = Member(doc, "cvc_rays", path, "");
  if (!vc_rays.is_array() || !cvc_rays.is_array()) throw InputError(path, "", "vc_rays and cvc_rays must be arrays");
  std::unordered_map<std::string, std::pair<Vec2, Vec2>> workspace;
  for (std::size_t i = 0; i < vc_rays.size(); ++i) {
    const std::string where = "vc_rays[" + std::to_string(i) + "]";
    const json& id = Member(vc_rays[i], "id", path, where);
    const std::string key = id.is_string() ? id.get<std::string>() : id.dump();
    const Vec2 from = Point(Member(vc_rays[i], "from", path, where), path, where + ".from");
    const Vec2 to = Point(Member(vc_rays[i], "to", path, where), path, where + ".to");
    if (Norm(to - from) <= 0) throw InputError(path, where, "from and to coincide");
    workspace[key] = {from, to};
  }
  std::vector<CvcRay> rays;
  for (std::size_t i = 0; i < cvc_rays.size(); ++i) {
    const std::string where = "cvc_rays[" + std::to_string(i) + "]";
    CvcRay ray;
    const json& id = Member(cvc_rays[i], "id", path, where);
    ray.id = id.is_string() ? id.get<std::string>() : id.dump();
    const json& vc = Member(cvc_rays[i], "vc_ray", path, where);
    ray.vc_ray = vc.is_string() ? vc.get<std::string>() : vc.dump();
    const auto it = workspace.find(ray.vc_ray);
    if (it == workspace.end()) throw InputError(path, where + ".vc_ray", "names no entry of vc_rays");
    ray.from = it->second.first;
    ray.to = it->second.second;
    ray.direction = (1.0 / Norm(ray.to - ray.from)) * (ray.to - ray.from);
    const json& cm = Member(cvc_rays[i], "cm_vertex", path, where);
    if (!cm.is_number_integer() || cm.get<int>() < 0) throw InputError(path, where + ".cm_vertex", "must be an index");
    ray.cm_vertex = cm.get<int>();
    rays.push_back(ray);
  }
  return rays;
}

SceneIdentity ReadSceneIdentity(const std::string& path) {
  const json doc = ParseJson(ReadFile(path), path);
  SceneIdentity id;
  if (!doc.is_object()) return id;
  if (doc.contains("scene") && doc.at("scene").is_string()) id.name = doc.at("scene").get<std::string>();
  if (doc.contains("scene_digest") && doc.at("scene_digest").is_string()) {
    id.digest = doc.at("scene_digest").get<std::string>();
  }
  return id;
}

namespace {

std::string Describe(const std::string& name, const std::string& digest) {
  std::string text = "scene \"" + name + "\"";
  if (!digest.empty()) text += " (scene_digest " + digest + ")";
  return text;
}

}  // namespace

void CheckMadeFor(const SceneIdentity& made_for, const std::string& what, const std::string& path,
                  const SceneInfo& scene, const std::string& scene_path) {
  bool other = false;
  if (!made_for.digest.empty() && !scene.digest.empty()) {
    other = made_for.digest != scene.digest;
  } else if (!made_for.name.empty() && scene.named) {
    other = made_for.name != scene.name;
  }
  if (!other) return;
  const std::string redo = what == "rays" ? "`visco vcrays " + scene_path + " --out FILE`"
                                          : "plan it with `visco plan " + scene_path + " --out FILE`";
  const std::string why =
      made_for.name == scene.name ? " (the same name, another content: the scene file was edited)" : "";
  throw InputError(path, "scene",
                   (what == "rays" ? "the rays were computed for " : "the " + what + " was planned for ") +
                       Describe(made_for.name, made_for.digest) + ", not for " + scene_path + ", which is " +
                       Describe(scene.name, scene.digest) + why + ": " + redo);
}

void CheckSameScene(const SceneIdentity& strategy, const std::string& strategy_path, const SceneIdentity& rays,
                    const std::string& rays_path) {
  if (strategy.digest.empty() || rays.digest.empty() || strategy.digest == rays.digest) return;
  throw InputError(rays_path, "scene",
                   "the rays were computed for " + Describe(rays.name, rays.digest) + ", the strategy " +
                       strategy_path + " was planned for " + Describe(strategy.name, strategy.digest) +
                       ": give the rays of the strategy's scene (`visco vcrays SCENE --out FILE`)");
}

Task ParseStrategyJson(const std::string& json_text, const std::string& source, const std::vector<CvcRay>& rays,
                       bool rays_given) {
  rays_given = rays_given || !rays.empty();
  const json doc = ParseJson(json_text, source);
  if (!doc.is_object()) throw InputError(source, "", "a strategy must be a JSON object");
  if (doc.contains("feasible") && doc.at("feasible").is_boolean() && !doc.at("feasible").get<bool>()) {
    throw JobFailed(source + ": the strategy is not feasible (the planner found no plan)");
  }
  Task task;
  InitRays(task, rays);
  if (doc.contains("scene") && doc.at("scene").is_string()) task.scene = doc.at("scene").get<std::string>();
  if (doc.contains("speed")) {
    task.speed = Number(doc.at("speed"), source, "speed");
    if (task.speed <= 0) throw InputError(source, "speed", "must be positive");
  }
  const json& steps = Member(doc, "steps", source, "");
  if (!steps.is_array() || steps.empty()) throw InputError(source, "steps", "must be a non-empty array");
  for (std::size_t i = 0; i < steps.size(); ++i) {
    const std::string where = "steps[" + std::to_string(i) + "]";
    const json& s = steps[i];
    Step step;
    step.theta = Number(Member(s, "theta_deg", source, where), source, where + ".theta_deg") * kDegToRad;
    if (s.contains("active_rays")) {
      const json& active = s.at("active_rays");
      if (!active.is_array()) throw InputError(source, where + ".active_rays", "must be an array of ray ids");
      for (std::size_t k = 0; k < active.size(); ++k) {
        const std::string ray_where = where + ".active_rays[" + std::to_string(k) + "]";
        const std::string id = active[k].is_string() ? active[k].get<std::string>() : active[k].dump();
        step.active_rays.push_back(ResolveRay(task, id, source, ray_where, rays_given));
      }
    }
    const json& terminate = Member(s, "terminate", source, where);
    const json& kind = Member(terminate, "kind", source, where + ".terminate");
    if (!kind.is_string()) throw InputError(source, where + ".terminate.kind", "must be a string");
    step.terminate = ParseKind(kind.get<std::string>(), source, where + ".terminate.kind");
    if (step.terminate == TerminateKind::kVisualGuarded) {
      const json& ref = Member(terminate, "ref", source, where + ".terminate");
      if (ref.is_null()) throw InputError(source, where + ".terminate.ref", "a vc step must name its CVC ray");
      const std::string id = ref.is_string() ? ref.get<std::string>() : ref.dump();
      step.terminate_ray = ResolveRay(task, id, source, where + ".terminate.ref", rays_given);
    }
    if (s.contains("timeout_s")) {
      step.timeout_s = Number(s.at("timeout_s"), source, where + ".timeout_s");
      if (step.timeout_s < 0) throw InputError(source, where + ".timeout_s", "must not be negative");
    }
    task.steps.push_back(std::move(step));
  }
  return task;
}

Task LoadStrategyFile(const std::string& path, const std::vector<CvcRay>& rays, bool rays_given) {
  return ParseStrategyJson(ReadFile(path), path, rays, rays_given);
}

Task FromLcm(const motion_strategy_t& message, const std::vector<CvcRay>& rays, bool rays_given) {
  const std::string source = "VISCO_STRATEGY";
  rays_given = rays_given || !rays.empty();
  if (!message.feasible) throw JobFailed(source + ": the strategy is not feasible (the planner found no plan)");
  if (message.num_steps <= 0 || static_cast<std::size_t>(message.num_steps) != message.steps.size()) {
    throw InputError(source, "steps", "must be non-empty and match num_steps");
  }
  Task task;
  InitRays(task, rays);
  task.scene = message.scene;
  if (!(message.speed >= 0) || !std::isfinite(message.speed)) throw InputError(source, "speed", "must be >= 0");
  task.speed = message.speed;
  for (std::size_t i = 0; i < message.steps.size(); ++i) {
    const std::string where = "steps[" + std::to_string(i) + "]";
    const motion_step_t& m = message.steps[i];
    Step step;
    if (!std::isfinite(m.theta)) throw InputError(source, where + ".theta", "must be finite");
    step.theta = m.theta;
    for (std::size_t k = 0; k < m.active_rays.size(); ++k) {
      step.active_rays.push_back(
          ResolveRay(task, m.active_rays[k], source, where + ".active_rays[" + std::to_string(k) + "]", rays_given));
    }
    switch (m.terminate_kind) {
      case motion_step_t::TERMINATE_GOAL:
        step.terminate = TerminateKind::kGoal;
        break;
      case motion_step_t::TERMINATE_VC:
        step.terminate = TerminateKind::kVisualGuarded;
        step.terminate_ray = ResolveRay(task, m.terminate_ref, source, where + ".terminate_ref", rays_given);
        break;
      case motion_step_t::TERMINATE_CONTACT:
        step.terminate = TerminateKind::kContact;
        break;
      default:
        throw InputError(source, where + ".terminate_kind", "unknown value " + std::to_string(m.terminate_kind));
    }
    if (!(m.timeout_s >= 0)) throw InputError(source, where + ".timeout_s", "must not be negative");
    step.timeout_s = m.timeout_s;
    task.steps.push_back(std::move(step));
  }
  return task;
}

void AttachScene(Task& task, const SceneInfo& scene, const std::string& scene_path) {
  task.goal = scene.goal;
  task.bounds = scene.bounds;
  task.position_uncertainty = scene.position_uncertainty;
  for (CvcRay& ray : task.rays) {
    if (ray.cm_vertex < 0) continue;
    if (static_cast<std::size_t>(ray.cm_vertex) >= scene.robot.vertices.size()) {
      throw InputError(scene_path, "robot.polygon",
                       "has no vertex " + std::to_string(ray.cm_vertex) + " (CVC ray \"" + ray.id + "\")");
    }
    ray.cm_offset = scene.robot.vertices[static_cast<std::size_t>(ray.cm_vertex)];
    ray.has_cm_offset = true;
  }
  task.scene_info = scene;
}

void ValidateTask(const Task& task, const std::string& source) {
  if (task.steps.empty()) throw InputError(source, "steps", "the strategy has no steps");
  if (task.rays.size() > static_cast<std::size_t>(kMaxVisualObservations)) {
    throw InputError(source, "rays",
                     "more than " + std::to_string(kMaxVisualObservations) + " CVC rays; the executor's capacity");
  }
  for (std::size_t i = 0; i < task.steps.size(); ++i) {
    const Step& step = task.steps[i];
    const std::string where = "steps[" + std::to_string(i) + "]";
    for (int ray : step.active_rays) {
      const CvcRay& r = task.rays.at(static_cast<std::size_t>(ray));
      if (r.cm_vertex < 0) {
        throw InputError(source, where + ".active_rays",
                         "visual compliant motion along \"" + r.id +
                             "\" needs the ray's geometry: give the `visco vcrays` output with --rays");
      }
    }
    if (step.terminate == TerminateKind::kGoal && !task.goal) {
      throw InputError(source, where + ".terminate",
                       "goal recognition needs the goal region: give the scene file with --scene");
    }
  }
}

bool InPolygon(const Polygon& polygon, Vec2 p) {
  // Crossing number, with points on the boundary counted as inside.
  const auto& v = polygon.vertices;
  const std::size_t n = v.size();
  bool inside = false;
  for (std::size_t i = 0, j = n - 1; i < n; j = i++) {
    const Vec2 a = v[j];
    const Vec2 b = v[i];
    // On-segment test (closed polygon).
    const Vec2 ab = b - a;
    const Vec2 ap = p - a;
    if (Cross(ab, ap) == 0.0 && Dot(ap, ab) >= 0.0 && Dot(ap, ab) <= Dot(ab, ab)) return true;
    if ((a.y > p.y) != (b.y > p.y)) {
      const double x = a.x + (p.y - a.y) * (b.x - a.x) / (b.y - a.y);
      if (p.x < x) inside = !inside;
    }
  }
  return inside;
}

double BoundaryDistance(const Polygon& polygon, Vec2 p) {
  const auto& v = polygon.vertices;
  const std::size_t n = v.size();
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0, j = n - 1; i < n; j = i++) {
    const Vec2 a = v[j];
    const Vec2 ab = v[i] - a;
    const double len2 = Dot(ab, ab);
    double t = len2 > 0 ? Dot(p - a, ab) / len2 : 0.0;
    t = t < 0 ? 0 : (t > 1 ? 1 : t);
    best = std::min(best, Norm(p - (a + t * ab)));
  }
  return best;
}

bool InKernel(const Polygon& goal, double erosion, Vec2 p) {
  return InPolygon(goal, p) && BoundaryDistance(goal, p) >= erosion;
}

}  // namespace visco::control

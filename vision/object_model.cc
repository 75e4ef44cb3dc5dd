#include "vision/object_model.h"

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "common/error.h"
#include "vision/camera.h"

namespace visco::vision {
namespace {

using nlohmann::json;

void OnlyKeys(const json& j, const std::string& src, const std::string& where, const std::set<std::string>& keys) {
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (!keys.count(it.key()))
      throw InputError(src, where.empty() ? it.key() : where + "." + it.key(), "unknown field");
  }
}

double Number(const json& j, const std::string& src, const std::string& where) {
  if (!j.is_number() || !std::isfinite(j.get<double>())) throw InputError(src, where, "must be a finite number");
  return j.get<double>();
}

Eigen::Vector3d Vec3(const json& j, const std::string& src, const std::string& where) {
  if (!j.is_array() || j.size() != 3) throw InputError(src, where, "must be an array of 3 numbers");
  return {Number(j[0], src, where), Number(j[1], src, where), Number(j[2], src, where)};
}

ObjectModel ParseObject(const json& j, const std::string& src, const std::string& where) {
  if (!j.is_object()) throw InputError(src, where, "must be an object");
  OnlyKeys(j, src, where, {"id", "polygon", "height", "tags"});
  ObjectModel o;
  if (j.contains("id")) {
    if (!j["id"].is_string()) throw InputError(src, where + ".id", "must be a string");
    o.id = j["id"].get<std::string>();
  }
  if (!j.contains("polygon") || !j["polygon"].is_array()) {
    throw InputError(src, where + ".polygon", "missing (an array of [x, y] vertices in metres)");
  }
  for (std::size_t i = 0; i < j["polygon"].size(); ++i) {
    const auto& p = j["polygon"][i];
    const std::string w = where + ".polygon[" + std::to_string(i) + "]";
    if (!p.is_array() || p.size() != 2) throw InputError(src, w, "must be [x, y]");
    o.polygon.emplace_back(Number(p[0], src, w), Number(p[1], src, w));
  }
  if (o.polygon.size() < 3) throw InputError(src, where + ".polygon", "needs at least 3 vertices");
  if (!j.contains("height")) throw InputError(src, where + ".height", "missing (prism height in metres)");
  o.height = Number(j["height"], src, where + ".height");
  if (!(o.height > 0)) throw InputError(src, where + ".height", "must be positive");
  if (!j.contains("tags") || !j["tags"].is_array() || j["tags"].empty()) {
    throw InputError(src, where + ".tags", "missing (at least one tag must be mounted on each object)");
  }
  for (std::size_t i = 0; i < j["tags"].size(); ++i) {
    const auto& t = j["tags"][i];
    const std::string w = where + ".tags[" + std::to_string(i) + "]";
    if (!t.is_object()) throw InputError(src, w, "must be an object");
    OnlyKeys(t, src, w, {"family", "id", "size", "t", "rpy_deg"});
    TagMount m;
    if (t.contains("family")) {
      if (!t["family"].is_string()) throw InputError(src, w + ".family", "must be a string");
      m.family = t["family"].get<std::string>();
    }
    if (!t.contains("id") || !t["id"].is_number_integer() || t["id"].get<int>() < 0) {
      throw InputError(src, w + ".id", "must be a non-negative integer");
    }
    m.id = t["id"].get<int>();
    if (!t.contains("size")) throw InputError(src, w + ".size", "missing (metres, black border's outer edge)");
    m.size = Number(t["size"], src, w + ".size");
    if (!(m.size > 0)) throw InputError(src, w + ".size", "must be positive");
    if (!t.contains("t")) throw InputError(src, w + ".t", "missing (tag position in the object frame, metres)");
    m.oMt.translation() = Vec3(t["t"], src, w + ".t");
    if (t.contains("rpy_deg")) {
      const Eigen::Vector3d a = Vec3(t["rpy_deg"], src, w + ".rpy_deg") * (M_PI / 180);
      m.oMt.linear() = RotationFromRpy(a.x(), a.y(), a.z());
    }
    o.tags.push_back(m);
  }
  return o;
}

}  // namespace

ObjectModels ParseObjectModels(const std::string& text, const std::string& src) {
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    throw InputError(src, "", std::string("not valid JSON: ") + e.what());
  }
  if (!j.is_object()) throw InputError(src, "", "must be a JSON object");
  OnlyKeys(j, src, "", {"robot", "obstacles", "events"});
  ObjectModels m;
  if (!j.contains("robot")) throw InputError(src, "robot", "missing");
  m.robot = ParseObject(j["robot"], src, "robot");
  if (m.robot.id.empty()) m.robot.id = "robot";
  if (j.contains("obstacles")) {
    if (!j["obstacles"].is_array()) throw InputError(src, "obstacles", "must be an array");
    for (std::size_t i = 0; i < j["obstacles"].size(); ++i) {
      const std::string w = "obstacles[" + std::to_string(i) + "]";
      m.obstacles.push_back(ParseObject(j["obstacles"][i], src, w));
      if (m.obstacles.back().id.empty()) throw InputError(src, w + ".id", "missing");
    }
  }
  std::set<std::pair<std::string, int>> tag_ids;
  auto check_tags = [&](const ObjectModel& o) {
    for (const auto& t : o.tags) {
      if (!tag_ids.insert({t.family, t.id}).second) {
        throw InputError(src, o.id, "tag " + t.family + " id " + std::to_string(t.id) + " is used twice");
      }
    }
  };
  check_tags(m.robot);
  for (const auto& o : m.obstacles) check_tags(o);
  if (j.contains("events")) {
    if (!j["events"].is_array()) throw InputError(src, "events", "must be an array");
    for (std::size_t i = 0; i < j["events"].size(); ++i) {
      const auto& e = j["events"][i];
      const std::string w = "events[" + std::to_string(i) + "]";
      if (!e.is_object()) throw InputError(src, w, "must be an object");
      OnlyKeys(e, src, w, {"cvc_ray", "obstacle", "vertex", "cm_vertex"});
      EventPair p;
      if (!e.contains("obstacle") || !e["obstacle"].is_string()) throw InputError(src, w + ".obstacle", "missing");
      const std::string ob = e["obstacle"].get<std::string>();
      p.obstacle = -1;
      for (std::size_t k = 0; k < m.obstacles.size(); ++k) {
        if (m.obstacles[k].id == ob) p.obstacle = static_cast<int>(k);
      }
      if (p.obstacle < 0) throw InputError(src, w + ".obstacle", "no obstacle with id '" + ob + "'");
      if (!e.contains("vertex") || !e["vertex"].is_number_integer()) throw InputError(src, w + ".vertex", "missing");
      p.vertex = e["vertex"].get<int>();
      if (p.vertex < 0 || p.vertex >= static_cast<int>(m.obstacles[p.obstacle].polygon.size())) {
        throw InputError(src, w + ".vertex", "not a vertex of obstacle '" + ob + "'");
      }
      if (!e.contains("cm_vertex") || !e["cm_vertex"].is_number_integer()) {
        throw InputError(src, w + ".cm_vertex", "missing");
      }
      p.cm_vertex = e["cm_vertex"].get<int>();
      if (p.cm_vertex < 0 || p.cm_vertex >= static_cast<int>(m.robot.polygon.size())) {
        throw InputError(src, w + ".cm_vertex", "not a vertex of the robot polygon");
      }
      p.cvc_ray = e.contains("cvc_ray") && e["cvc_ray"].is_string()
                      ? e["cvc_ray"].get<std::string>()
                      : ob + ".v" + std::to_string(p.vertex) + ".cm" + std::to_string(p.cm_vertex);
      m.events.push_back(p);
    }
  } else {
    for (std::size_t k = 0; k < m.obstacles.size(); ++k) {
      for (std::size_t v = 0; v < m.obstacles[k].polygon.size(); ++v) {
        for (std::size_t c = 0; c < m.robot.polygon.size(); ++c) {
          m.events.push_back({m.obstacles[k].id + ".v" + std::to_string(v) + ".cm" + std::to_string(c),
                              static_cast<int>(k), static_cast<int>(v), static_cast<int>(c)});
        }
      }
    }
  }
  return m;
}

ObjectModels LoadObjectModels(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "", "object-model file does not exist or cannot be read");
  std::stringstream ss;
  ss << in.rdbuf();
  return ParseObjectModels(ss.str(), path);
}

}  // namespace visco::vision

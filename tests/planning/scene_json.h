#pragma once
// A scene written back as a scene file (docs/formats.md), so that a random scene on which a property test fails can
// be reproduced and examined with the command-line tools (`visco plan FILE --check 24 --svg out.svg`). Coordinates are
// written with 17 significant digits: the file loads to the same scene. Set VISCO_DUMP_DIR to have the tests that
// use DumpScene write their failing scenes there (docs/development.md "Property tests on other seeds").

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "planning/scene.h"

namespace visco::planning::testing {

inline nlohmann::json PolygonJson(const Polygon& p) {
  nlohmann::json out = nlohmann::json::array();
  for (const Point& v : p.vertices) out.push_back({v.x(), v.y()});
  return out;
}

inline std::string SceneToJson(const Scene& s) {
  nlohmann::json j;
  j["name"] = s.name.empty() ? "random" : s.name;
  j["bounds"] = {{"min", {s.bounds.min.x(), s.bounds.min.y()}}, {"max", {s.bounds.max.x(), s.bounds.max.y()}}};
  j["robot"] = {{"polygon", PolygonJson(s.robot.polygon)}};
  j["obstacles"] = nlohmann::json::array();
  for (const Obstacle& o : s.obstacles) {
    nlohmann::json ob = {{"id", o.id}, {"polygon", PolygonJson(o.shape.polygon)}};
    if (o.height) ob["height"] = *o.height;
    j["obstacles"].push_back(ob);
  }
  j["goal"] = {{"polygon", PolygonJson(s.goal.polygon)}};
  if (s.start) j["start"] = {{"polygon", PolygonJson(s.start->polygon)}};
  if (s.camera) {
    const Camera& c = *s.camera;
    if (c.pinhole) {
      const PinholeCamera& p = *c.pinhole;
      nlohmann::json m = nlohmann::json::array();
      for (int r = 0; r < 4; ++r) m.push_back({p.wMc(r, 0), p.wMc(r, 1), p.wMc(r, 2), p.wMc(r, 3)});
      j["camera"] = {{"pinhole",
                      {{"px", p.px},
                       {"py", p.py},
                       {"u0", p.u0},
                       {"v0", p.v0},
                       {"width", p.width},
                       {"height", p.height},
                       {"wMc", m}}}};
    } else {
      j["camera"] = {{"center", {c.center.x(), c.center.y()}},
                     {"fov_deg", {c.fov_first_rad * 180 / M_PI, c.fov_second_rad * 180 / M_PI}}};
      if (c.height) j["camera"]["height"] = *c.height;
    }
  }
  j["uncertainty"] = {{"velocity_cone_deg", s.uncertainty.velocity_cone_rad * 180 / M_PI},
                      {"position", s.uncertainty.position},
                      {"vc_tracking", s.uncertainty.vc_tracking}};
  j["friction_cone_deg"] = s.friction_cone_rad * 180 / M_PI;
  return j.dump(1) + "\n";
}

// Writes the scene to $VISCO_DUMP_DIR/NAME.json if that variable is set; returns the path written, or "".
inline std::string DumpScene(const Scene& s, const std::string& name) {
  const char* dir = std::getenv("VISCO_DUMP_DIR");
  if (dir == nullptr || *dir == '\0') return "";
  std::string file = name;
  for (char& ch : file) {
    if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '-' && ch != '.') ch = '_';
  }
  const std::string path = std::string(dir) + "/" + file + ".json";
  std::ofstream(path) << SceneToJson(s);
  return path;
}

}  // namespace visco::planning::testing

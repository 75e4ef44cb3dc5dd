#include "drivers/simulated_robot_options.h"

#include <CLI/CLI.hpp>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "common/error.h"

namespace visco::drivers {
namespace {

using Json = nlohmann::ordered_json;
constexpr double kDeg = M_PI / 180.0;

// Reads the world file's JSON with every key checked: a user sees which key of which object is wrong.
class WorldReader {
 public:
  explicit WorldReader(std::string path) : path_(std::move(path)) {}

  [[noreturn]] void Fail(const std::string& object, const std::string& what) const {
    throw InputError(path_, object, what);
  }
  void Keys(const Json& j, const std::string& object, const std::set<std::string>& allowed) const {
    if (!j.is_object()) Fail(object, "must be a JSON object");
    for (const auto& [key, value] : j.items()) {
      if (allowed.count(key) == 0) {
        std::string list;
        for (const std::string& k : allowed) list += (list.empty() ? "" : ", ") + k;
        Fail(object.empty() ? key : object + "." + key, "unknown key (allowed: " + list + ")");
      }
    }
  }
  double Number(const Json& j, const std::string& object) const {
    if (!j.is_number() || !std::isfinite(j.get<double>())) Fail(object, "must be a finite number");
    return j.get<double>();
  }
  Eigen::Vector2d Point(const Json& j, const std::string& object) const {
    if (!j.is_array() || j.size() != 2) Fail(object, "must be a point [x, y]");
    return {Number(j[0], object + "[0]"), Number(j[1], object + "[1]")};
  }

 private:
  std::string path_;
};

std::vector<double> CheckedBox(const std::vector<double>& box, const char* option) {
  if (!box.empty() && !(box[0] < box[2] && box[1] < box[3])) {
    throw InputError("command line", option, "give XMIN YMIN XMAX YMAX with XMIN < XMAX and YMIN < YMAX");
  }
  return box;
}

}  // namespace

WorldFile LoadWorldFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "", "cannot open the world file");
  Json j;
  try {
    j = Json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path, "", std::string("not valid JSON: ") + e.what());
  }
  const WorldReader r(path);
  r.Keys(j, "", {"format", "obstacles", "bounds", "friction_cone_deg", "velocity_cone_deg", "start"});
  if (!j.contains("format") || j["format"] != "visco-world-1") {
    r.Fail("format", "must be \"visco-world-1\" (a world file written by `visco sim --write-world` or the demo)");
  }
  WorldFile w;
  if (!j.contains("bounds")) r.Fail("bounds", "missing");
  r.Keys(j["bounds"], "bounds", {"min", "max"});
  if (!j["bounds"].contains("min") || !j["bounds"].contains("max")) r.Fail("bounds", "needs min and max");
  w.world.bounds_min = r.Point(j["bounds"]["min"], "bounds.min");
  w.world.bounds_max = r.Point(j["bounds"]["max"], "bounds.max");
  if (!(w.world.bounds_min.array() < w.world.bounds_max.array()).all()) {
    r.Fail("bounds", "min must be below max on both axes");
  }
  if (j.contains("obstacles")) {
    if (!j["obstacles"].is_array()) r.Fail("obstacles", "must be an array of polygons");
    for (std::size_t i = 0; i < j["obstacles"].size(); ++i) {
      const std::string object = "obstacles[" + std::to_string(i) + "]";
      const Json& polygon = j["obstacles"][i];
      if (!polygon.is_array() || polygon.size() < 3) r.Fail(object, "must be a polygon of at least 3 points");
      std::vector<Eigen::Vector2d> vertices;
      for (std::size_t k = 0; k < polygon.size(); ++k) {
        vertices.push_back(r.Point(polygon[k], object + "[" + std::to_string(k) + "]"));
      }
      w.world.obstacles.push_back(std::move(vertices));
    }
  }
  auto angle = [&](const char* key, double max_deg) {
    if (!j.contains(key)) return 0.0;
    const double deg = r.Number(j[key], key);
    if (!(deg >= 0.0 && deg < max_deg)) r.Fail(key, "must be in [0, " + std::to_string(int(max_deg)) + ") degrees");
    return deg * kDeg;
  };
  w.world.friction_cone = angle("friction_cone_deg", 90.0);
  w.velocity_cone = angle("velocity_cone_deg", 90.0);
  if (j.contains("start")) {
    w.have_start = true;
    w.start = r.Point(j["start"], "start");
  }
  return w;
}

std::string WorldFileJson(const WorldFile& w) {
  Json j;
  j["format"] = "visco-world-1";
  auto point = [](const Eigen::Vector2d& p) { return Json::array({p.x(), p.y()}); };
  j["bounds"] = {{"min", point(w.world.bounds_min)}, {"max", point(w.world.bounds_max)}};
  j["friction_cone_deg"] = w.world.friction_cone / kDeg;
  j["velocity_cone_deg"] = w.velocity_cone / kDeg;
  if (w.have_start) j["start"] = point(w.start);
  Json obstacles = Json::array();
  for (const auto& polygon : w.world.obstacles) {
    Json vertices = Json::array();
    for (const auto& v : polygon) vertices.push_back(point(v));
    obstacles.push_back(std::move(vertices));
  }
  j["obstacles"] = std::move(obstacles);
  return j.dump(1) + "\n";  // nlohmann prints doubles with enough digits to read back the same value
}

void AddSimulatedRobotOptions(CLI::App& cmd, SimulatedRobotOptions& o, bool with_world) {
  const std::string group = "Simulated robot";
  if (with_world) {
    cmd.add_option("--world", o.world_path,
                   "simulate this world: C-obstacles, bounds, friction and velocity cone (a world file, "
                   "docs/formats.md; `visco sim SCENE --write-world FILE` writes one from a scene)")
        ->check(CLI::ExistingFile)
        ->group(group);
    cmd.add_option("--start", o.start, "initial reference point X Y, metres (default: the world's, else 0 0)")
        ->expected(2)
        ->group(group);
    cmd.add_option("--walls", o.walls, "rigid walls around the box XMIN YMIN XMAX YMAX, metres (C-obstacles)")
        ->expected(4)
        ->group(group);
    cmd.add_option("--workspace", o.workspace,
                   "bounds XMIN YMIN XMAX YMAX, metres: a motion that would leave them stops on the border and the "
                   "driver raises the bounds fault (EMCY 0x8612); default: the world's, else the free plane")
        ->expected(4)
        ->group(group);
    cmd.add_option("--friction-deg", o.friction_deg, "friction cone half-angle φ, degrees (default: the world's)")
        ->group(group);
    cmd.add_option("--velocity-cone-deg", o.velocity_cone_deg,
                   "control uncertainty ε_v, degrees: the adversary turns the commanded direction within it "
                   "(default: the world's)")
        ->group(group);
  }
  SimulatedRobotConfig& r = o.robot;
  cmd.add_option("--seed", r.seed, "seed of the robot's random adversary")->capture_default_str()->group(group);
  cmd.add_option("--mean-hold", r.mean_hold_m, "mean travel between the adversary's direction changes, m")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--max-acceleration", r.max_acceleration, "acceleration limit, m/s^2")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--quick-stop-deceleration", r.quick_stop_deceleration, "deceleration on a safety stop, m/s^2")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--contact-damping", r.contact_damping, "contact force per m/s of blocked velocity, N s/m")
      ->capture_default_str()
      ->group(group);
}

SimulatedRobotConfig ToConfig(const SimulatedRobotOptions& o) {
  SimulatedRobotConfig config = o.robot;
  if (!o.world_path.empty()) {
    const WorldFile w = LoadWorldFile(o.world_path);
    config.world = w.world;
    config.velocity_cone = w.velocity_cone;
    if (w.have_start) config.start = w.start;
  }
  if (o.start.size() == 2) config.start = {o.start[0], o.start[1]};
  if (!CheckedBox(o.workspace, "--workspace").empty()) {
    config.world.bounds_min = {o.workspace[0], o.workspace[1]};
    config.world.bounds_max = {o.workspace[2], o.workspace[3]};
  }
  if (!CheckedBox(o.walls, "--walls").empty()) {
    for (auto& wall : WallsAround({o.walls[0], o.walls[1]}, {o.walls[2], o.walls[3]})) {
      config.world.obstacles.push_back(std::move(wall));
    }
  }
  if (o.friction_deg >= 0) config.world.friction_cone = o.friction_deg * kDeg;
  if (o.velocity_cone_deg >= 0) config.velocity_cone = o.velocity_cone_deg * kDeg;
  if (!(o.friction_deg < 90)) throw InputError("command line", "--friction-deg", "must be below 90");
  return config;
}

}  // namespace visco::drivers

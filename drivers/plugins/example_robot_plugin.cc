// An example robot plugin (drivers/robot_plugin.h; docs/your_own_robot.md): a two-axis stage whose axes follow the
// commanded velocity with a first-order lag (time constant `time_constant_s`) within an acceleration limit, in a
// rectangular workspace. A user's plugin replaces Step() and Read() with its hardware's I/O: Configure() opens the
// communication, Activate() powers the axes, and the loop's calls neither allocate nor block.
//
// Configuration (JSON, every key optional):
//   {"time_constant_s": 0.05, "max_acceleration": 2.0, "quick_stop_deceleration": 20.0,
//    "workspace": [xmin, ymin, xmax, ymax], "start": [x, y]}
// Build: drivers/CMakeLists.txt (a MODULE library, lib/libvisco_example_robot_plugin.so); load it with
//   visco driver --robot plugin --robot-plugin build/lib/libvisco_example_robot_plugin.so --robot-config stage.json

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "common/error.h"
#include "drivers/robot_plugin.h"

namespace {

using visco::drivers::RobotFeedback;

struct StageConfig {
  double time_constant_s = 0.05;
  double max_acceleration = 2.0;
  double quick_stop_deceleration = 20.0;
  double workspace[4] = {-1.0, -1.0, 1.0, 1.0};
  double start[2] = {0.0, 0.0};
};

class ExampleStage final : public visco::drivers::RobotInterface {
 public:
  explicit ExampleStage(const StageConfig& config) : config_(config) {
    feedback_.position[0] = config.start[0];
    feedback_.position[1] = config.start[1];
  }

  void Configure() override { configured_ = true; }  // a real plugin opens its communication here
  void Activate() override {
    if (!configured_) throw visco::JobFailed("example stage: Activate() before Configure()");
    active_ = true;
  }
  void Deactivate() override {
    active_ = false;
    command_[0] = command_[1] = 0.0;
  }
  void SetVelocity(const double velocity[2]) override {
    for (int i = 0; i < 2; ++i) command_[i] = std::isfinite(velocity[i]) ? velocity[i] : 0.0;
    quick_stop_ = false;
  }
  void QuickStop() override {
    command_[0] = command_[1] = 0.0;
    quick_stop_ = true;
  }
  void Reset() override { SetVelocity(command_); }
  void Step(double dt) override {
    if (!(dt > 0.0)) return;
    for (int i = 0; i < 2; ++i) {
      const double target = active_ ? command_[i] : 0.0;
      // First-order lag within the acceleration limit; a quick stop brakes at its full deceleration.
      const double limit = (quick_stop_ ? config_.quick_stop_deceleration : config_.max_acceleration) * dt;
      const double lagged =
          quick_stop_ ? target - velocity_[i] : (target - velocity_[i]) * std::min(1.0, dt / config_.time_constant_s);
      const double change = std::clamp(lagged, -limit, limit);
      velocity_[i] += change;
      feedback_.position[i] += velocity_[i] * dt;
      feedback_.velocity[i] = velocity_[i];
    }
    feedback_.out_of_bounds =
        feedback_.position[0] < config_.workspace[0] || feedback_.position[1] < config_.workspace[1] ||
        feedback_.position[0] > config_.workspace[2] || feedback_.position[1] > config_.workspace[3];
  }
  RobotFeedback Read() const override { return feedback_; }

 private:
  StageConfig config_;
  bool configured_ = false;
  bool active_ = false;
  bool quick_stop_ = false;
  double command_[2] = {0.0, 0.0};
  double velocity_[2] = {0.0, 0.0};
  RobotFeedback feedback_;
};

// Every key checked: an error names the key and what is wrong.
bool Parse(const char* text, StageConfig& config, std::string& error) {
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!j.is_object()) return error = "the configuration must be a JSON object", false;
  auto positive = [&](const char* key, double& out) {
    if (!j.contains(key)) return true;
    if (!j[key].is_number() || !(j[key].get<double>() > 0.0))
      return error = std::string(key) + ": must be a positive number", false;
    out = j[key].get<double>();
    return true;
  };
  auto numbers = [&](const char* key, double* out, std::size_t n) {
    if (!j.contains(key)) return true;
    if (!j[key].is_array() || j[key].size() != n)
      return error = std::string(key) + ": must be " + std::to_string(n) + " numbers", false;
    for (std::size_t i = 0; i < n; ++i) {
      if (!j[key][i].is_number())
        return error = std::string(key) + ": must be " + std::to_string(n) + " numbers", false;
      out[i] = j[key][i].get<double>();
    }
    return true;
  };
  for (const auto& item : j.items()) {
    const std::string& key = item.key();
    if (key != "time_constant_s" && key != "max_acceleration" && key != "quick_stop_deceleration" &&
        key != "workspace" && key != "start") {
      return error =
                 key + ": unknown key (time_constant_s, max_acceleration, quick_stop_deceleration, workspace, start)",
             false;
    }
  }
  if (!positive("time_constant_s", config.time_constant_s) || !positive("max_acceleration", config.max_acceleration) ||
      !positive("quick_stop_deceleration", config.quick_stop_deceleration) ||
      !numbers("workspace", config.workspace, 4) || !numbers("start", config.start, 2)) {
    return false;
  }
  if (!(config.workspace[0] < config.workspace[2] && config.workspace[1] < config.workspace[3])) {
    return error = "workspace: give [xmin, ymin, xmax, ymax] with min below max", false;
  }
  return true;
}

}  // namespace

extern "C" {

__attribute__((visibility("default"))) int visco_robot_plugin_abi() { return VISCO_ROBOT_PLUGIN_ABI; }

__attribute__((visibility("default"))) visco::drivers::RobotInterface* visco_robot_plugin_create(
    const char* config_json, char* error, std::size_t error_size) {
  StageConfig config;
  std::string why;
  if (!Parse(config_json, config, why)) {
    std::snprintf(error, error_size, "%s", why.c_str());
    return nullptr;
  }
  return new ExampleStage(config);
}

__attribute__((visibility("default"))) void visco_robot_plugin_destroy(visco::drivers::RobotInterface* robot) {
  delete robot;
}
}

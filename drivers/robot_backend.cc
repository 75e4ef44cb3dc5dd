#include "drivers/robot_backend.h"

#include <dlfcn.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "common/error.h"
#include "drivers/cia402_robot.h"
#include "drivers/robot_plugin.h"
#include "drivers/simulated_robot.h"
#include "drivers/simulated_robot_options.h"

namespace visco::drivers {
namespace {

// The plugin's robot behind the driver's interface; unloads the library after destroying the robot.
class PluginRobot final : public RobotInterface {
 public:
  PluginRobot(void* library, RobotInterface* robot, visco_robot_plugin_destroy_fn* destroy)
      : library_(library), robot_(robot), destroy_(destroy) {}
  ~PluginRobot() override {
    destroy_(robot_);
    dlclose(library_);
  }
  PluginRobot(const PluginRobot&) = delete;
  PluginRobot& operator=(const PluginRobot&) = delete;

  void Configure() override { robot_->Configure(); }
  void Activate() override { robot_->Activate(); }
  void Deactivate() override { robot_->Deactivate(); }
  void SetVelocity(const double velocity[2]) override { robot_->SetVelocity(velocity); }
  void QuickStop() override { robot_->QuickStop(); }
  void Reset() override { robot_->Reset(); }
  void Step(double dt) override { robot_->Step(dt); }
  RobotFeedback Read() const override { return robot_->Read(); }

 private:
  void* library_;
  RobotInterface* robot_;
  visco_robot_plugin_destroy_fn* destroy_;
};

std::string ReadConfigText(const std::string& path, const char* option) {
  if (path.empty()) return "{}";
  std::ifstream in(path);
  if (!in) throw InputError(path, "", std::string("cannot open the robot configuration (") + option + ")");
  std::stringstream text;
  text << in.rdbuf();
  if (!nlohmann::json::accept(text.str())) throw InputError(path, "", "the robot configuration is not valid JSON");
  return text.str();
}

}  // namespace

std::unique_ptr<RobotInterface> LoadRobotPlugin(const std::string& library, const std::string& config_json) {
  void* handle = dlopen(library.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) {
    const char* why = dlerror();
    throw InputError(library, "", std::string("cannot load the robot plugin: ") + (why ? why : "dlopen failed"));
  }
  auto symbol = [&](const char* name) {
    void* address = dlsym(handle, name);
    if (address == nullptr) {
      dlclose(handle);
      throw InputError(library, name,
                       "missing: a robot plugin exports visco_robot_plugin_abi, "
                       "visco_robot_plugin_create and visco_robot_plugin_destroy (drivers/robot_plugin.h)");
    }
    return address;
  };
  auto* abi = reinterpret_cast<visco_robot_plugin_abi_fn*>(symbol("visco_robot_plugin_abi"));
  auto* create = reinterpret_cast<visco_robot_plugin_create_fn*>(symbol("visco_robot_plugin_create"));
  auto* destroy = reinterpret_cast<visco_robot_plugin_destroy_fn*>(symbol("visco_robot_plugin_destroy"));
  if (const int version = abi(); version != VISCO_ROBOT_PLUGIN_ABI) {
    dlclose(handle);
    throw InputError(library, "visco_robot_plugin_abi",
                     "built for plugin ABI " + std::to_string(version) + ", this driver loads ABI " +
                         std::to_string(VISCO_ROBOT_PLUGIN_ABI) + ": rebuild the plugin against this visco");
  }
  char error[512] = {};
  RobotInterface* robot = create(config_json.c_str(), error, sizeof(error));
  if (robot == nullptr) {
    dlclose(handle);
    throw InputError(library, "configuration", error[0] != '\0' ? error : "the plugin refused its configuration");
  }
  return std::make_unique<PluginRobot>(handle, robot, destroy);
}

std::unique_ptr<RobotInterface> MakeRobot(const RobotBackendOptions& options, const SimulatedRobotOptions& sim,
                                          SimulatedRobot** simulated) {
  if (simulated != nullptr) *simulated = nullptr;
  if (options.kind == "simulated") {
    if (!options.config_path.empty() || !options.plugin_path.empty()) {
      throw InputError("command line", options.config_path.empty() ? "--robot-plugin" : "--robot-config",
                       "the simulated robot takes its own options (--world, --seed, ...), not this");
    }
    auto robot = std::make_unique<SimulatedRobot>(ToConfig(sim));
    if (simulated != nullptr) *simulated = robot.get();
    return robot;
  }
  if (options.kind == "plugin") {
    if (options.plugin_path.empty())
      throw InputError("command line", "--robot-plugin", "--robot plugin needs a library");
    return LoadRobotPlugin(options.plugin_path, ReadConfigText(options.config_path, "--robot-config"));
  }
  if (options.kind == "cia402") {
    if (options.config_path.empty()) {
      throw InputError("command line", "--robot-config", "--robot cia402 needs the drives' configuration file");
    }
    if (!options.plugin_path.empty()) throw InputError("command line", "--robot-plugin", "only with --robot plugin");
    Cia402Config config = LoadCia402Config(options.config_path);
    Cia402DriverContext context;
    context.max_speed = options.max_speed;
    context.driver_node = options.driver_node;
    context.driver_interface = options.driver_interface;
    if (config.interface == options.driver_interface && config.master_node == options.driver_node &&
        config.heartbeat_timeout_ms < 2 * options.heartbeat_ms) {
      throw InputError(options.config_path, "heartbeat_timeout_ms",
                       "the drives consume the driver's own heartbeat (master_node = --node on its bus): must be at "
                       "least twice --heartbeat-ms");
    }
    return std::make_unique<Cia402Robot>(config, context);
  }
  throw InputError("command line", "--robot", "unknown robot '" + options.kind + "' (simulated, cia402, plugin)");
}

}  // namespace visco::drivers

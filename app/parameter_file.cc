#include "app/parameter_file.h"

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>

namespace visco::app {
namespace {

using Json = nlohmann::ordered_json;

// The options and positionals whose values are files or folders (every command's, by their long names): in a
// parameter file, a relative one is relative to the file's folder, so that the file works from any directory.
const std::set<std::string>& PathOptions() {
  static const std::set<std::string> names = {"IMAGE",      "LOG",        "OBSERVATION", "SCENE",      "camera",
                                              "candidates", "extrinsics", "images",      "log",        "objects",
                                              "out",        "overlay",    "rays",        "scene",      "strategy",
                                              "svg",        "video",      "world",       "write-world"};
  return names;
}

// CLI11's config items from the JSON file: one section per command, one item per option.
class JsonParameters final : public CLI::Config {
 public:
  explicit JsonParameters(const CLI::App& root) : root_(root) {}

  std::string to_config(const CLI::App* app, bool default_also, bool, std::string) const override {
    // The options of the selected subcommand with their values (and defaults with default_also).
    Json out = Json::object();
    for (const CLI::App* sub : app->get_subcommands()) {
      Json section = Json::object();
      for (const CLI::Option* o : sub->get_options()) {
        if (o->get_lnames().empty() || o->get_lnames().front() == "help") continue;
        std::vector<std::string> values = o->reduced_results();
        if (values.empty() && default_also && !o->get_default_str().empty()) values = {o->get_default_str()};
        if (values.empty()) continue;
        section[o->get_lnames().front()] = values.size() == 1 ? Json(values[0]) : Json(values);
      }
      out[sub->get_name()] = section;
    }
    return out.dump(1) + "\n";
  }

  std::vector<CLI::ConfigItem> from_config(std::istream& in) const override {
    Json j;
    try {
      j = Json::parse(in);
    } catch (const nlohmann::json::exception& e) {
      throw CLI::ConfigError(std::string("not valid JSON: ") + e.what());
    }
    if (!j.is_object()) throw CLI::ConfigError("must be a JSON object: {\"COMMAND\": {\"OPTION\": VALUE, ...}}");
    // CLI11 reads the --config files last to first and does not say which one this is.
    const std::vector<std::string> files = root_.get_config_ptr()->as<std::vector<std::string>>();
    std::filesystem::path folder;
    if (!files.empty()) {
      folder = std::filesystem::path(files[files.size() - 1 - files_read_ % files.size()]).parent_path();
    }
    ++files_read_;
    auto resolve = [&](const std::string& name, std::string value) {
      if (value.empty() || folder.empty() || PathOptions().count(name) == 0) return value;
      const std::filesystem::path path(value);
      return path.is_absolute() ? value : (folder / path).lexically_normal().string();
    };
    std::vector<CLI::ConfigItem> result;
    for (const auto& [command, options] : j.items()) {
      if (!options.is_object()) {
        throw CLI::ConfigError(command + ": must be an object of the command's options ({\"OPTION\": VALUE, ...})");
      }
      for (const auto& [name, value] : options.items()) {
        CLI::ConfigItem item;
        item.parents = {command};
        item.name = name;
        auto input = [&](const Json& v) {
          if (v.is_string()) return v.get<std::string>();
          if (v.is_boolean() || v.is_number()) return v.dump();
          throw CLI::ConfigError(command + "." + name + ": must be a string, number, true/false or a list of them");
        };
        if (value.is_array()) {
          for (const Json& v : value) item.inputs.push_back(resolve(name, input(v)));
        } else {
          item.inputs.push_back(resolve(name, input(value)));
        }
        result.push_back(std::move(item));
      }
    }
    return result;
  }

 private:
  const CLI::App& root_;
  mutable std::size_t files_read_ = 0;
};

Json Value(const std::string& text) {
  if (text.empty()) return text;
  char* end = nullptr;
  errno = 0;
  const long long integer = std::strtoll(text.c_str(), &end, 10);
  if (*end == '\0') return errno == 0 ? Json(integer) : Json(text);  // too large for 64 bits: kept as written
  errno = 0;
  const double number = std::strtod(text.c_str(), &end);
  // Written back by nlohmann as the shortest text that reads as the same double: the option gets the same value.
  if (errno == 0 && *end == '\0' && std::isfinite(number)) return number;
  return text;
}

}  // namespace

void EnableParameterFiles(CLI::App& app) {
  app.set_config("--config", "",
                 "read the command's options from this JSON parameter file ({\"COMMAND\": {\"OPTION\": VALUE}}, "
                 "docs/formats.md); options on the command line win");
  app.config_formatter(std::make_shared<JsonParameters>(app));
  app.allow_config_extras(CLI::config_extras_mode::error);
  // `visco driver --config FILE` as well as `visco --config FILE driver`: subcommands pass the root's options up
  // (they copied the root's setting when they were made, so each is set).
  app.fallthrough();
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) sub->fallthrough();
}

std::string ParameterFileJson(const std::string& command, const std::vector<std::string>& args) {
  Json options = Json::object();
  std::size_t i = 0;
  while (i < args.size() && args[i].rfind("--", 0) != 0) ++i;  // positionals stay on the command line
  while (i < args.size()) {
    const std::string name = args[i].substr(2);
    std::vector<Json> values;
    for (++i; i < args.size() && args[i].rfind("--", 0) != 0; ++i) values.push_back(Value(args[i]));
    if (values.empty()) {
      options[name] = true;
    } else {
      options[name] = values.size() == 1 ? values[0] : Json(values);
    }
  }
  Json j;
  j[command] = options;
  return j.dump(1) + "\n";
}

}  // namespace visco::app

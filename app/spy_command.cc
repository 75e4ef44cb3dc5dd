#include "app/spy_command.h"

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "app/paths.h"
#include "common/error.h"

namespace visco::app {
namespace {

struct SpyOptions {
  std::string lcm_url;
  std::string java = "java";
  bool print_only = false;
};

// Debian's own `lcm-spy` wrapper passes -Xincgc, which Java 17 rejects, and lacks jchart2d on the class path,
// so we start lcm.spy.Spy ourselves.
void RunSpy(const SpyOptions& options) {
  const std::filesystem::path jar = FindDataFile("share/java/visco_lcmtypes.jar");
  const std::string classpath = std::string(VISCO_LCM_JAVA_CLASSPATH) + ":" + VISCO_JCHART2D_JAR + ":" + jar.string();
  std::vector<std::string> args = {options.java, "-Djava.net.preferIPv4Stack=true", "-cp", classpath, "lcm.spy.Spy"};
  if (!options.lcm_url.empty()) {
    args.push_back("--lcm-url=" + options.lcm_url);
  }
  if (options.print_only) {
    for (const auto& arg : args) std::printf("%s ", arg.c_str());
    std::printf("\n");
    return;
  }
  std::vector<char*> argv;
  for (auto& arg : args) argv.push_back(arg.data());
  argv.push_back(nullptr);
  ::execvp(argv[0], argv.data());
  throw JobFailed("cannot start " + options.java + ": " + std::strerror(errno) +
                  " (Debian: apt-get install default-jre-headless)");
}

}  // namespace

void RegisterSpyCommand(CLI::App& app) {
  auto options = std::make_shared<SpyOptions>();
  CLI::App* spy = app.add_subcommand(
      "spy", "Start lcm-spy with visco's message types on the class path, so it decodes every visco channel.");
  spy->add_option("--lcm-url", options->lcm_url, "LCM provider URL (default: $LCM_DEFAULT_URL or LCM's default)");
  spy->add_option("--java", options->java, "Java launcher to use");
  spy->add_flag("--print", options->print_only, "Print the java command line instead of running it");
  spy->callback([options] { RunSpy(*options); });
}

}  // namespace visco::app

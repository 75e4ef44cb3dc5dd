#include "app/cli_run.h"

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <string>

#include "app/parameter_file.h"
#include "common/error.h"

namespace visco::app {

int RunCommandLine(CLI::App& app, const char* program, int argc, char** argv) {
  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ %v");
  EnableParameterFiles(app);
  auto parameter_file = [&app] {
    const CLI::Option* config = app.get_config_ptr();
    return config != nullptr && config->count() > 0 ? config->as<std::string>() : std::string();
  };
  try {
    app.parse(argc, argv);
  } catch (const CLI::ConfigError& e) {
    // A bad parameter file: name it and the key (CLI11 speaks of INI; the files are JSON).
    std::string what = e.what();
    const std::string ini = "INI was not able to parse ";
    if (what.rfind(ini, 0) == 0) what = what.substr(ini.size()) + ": unknown command or option";
    std::fprintf(stderr, "%s: %s: %s\nRun '%s COMMAND --help' for the options.\n", program, parameter_file().c_str(),
                 what.c_str(), program);
    return 2;
  } catch (const CLI::FileError& e) {
    std::fprintf(stderr, "%s: %s\n", program, e.what());
    return 2;
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // Usage errors are bad input: exit 2 with one line naming what is wrong.
    const std::string file = parameter_file();
    std::fprintf(stderr, "%s: %s: %s\nRun '%s --help' for usage.\n", program,
                 file.empty() ? "command line" : ("command line or " + file).c_str(), e.what(), program);
    return 2;
  } catch (const visco::InputError& e) {
    std::fprintf(stderr, "%s: %s\n", program, e.what());
    return 2;
  } catch (const visco::Incomplete& e) {
    std::fprintf(stderr, "%s: %s\n", program, e.what());
    return 3;
  } catch (const visco::JobFailed& e) {
    std::fprintf(stderr, "%s: %s\n", program, e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: internal error: %s\n", program, e.what());
    return 1;
  }
  return 0;
}

}  // namespace visco::app

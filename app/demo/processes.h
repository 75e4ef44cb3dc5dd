#pragma once
// The demo's supervision of its processes: start one with its output and log redirected (it dies with the demo), see
// whether it ended, stop them all (SIGINT, then SIGKILL), its command line with a parameter file, and read what it
// wrote.

#include <sys/types.h>

#include <chrono>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace visco::app::demo {

struct Child {
  std::string name;
  pid_t pid = -1;
  int status = -1;
  bool exited = false;
};

/// Starts `argv` with stdout and stderr redirected; the child dies with the demo (PR_SET_PDEATHSIG).
/// @throws visco::JobFailed when it cannot fork.
Child Spawn(const std::string& name, const std::vector<std::string>& argv, const std::filesystem::path& out,
            const std::filesystem::path& err);

/// The command line of `exe command args...` that takes its options from a parameter file (app/parameter_file.h),
/// written to `params`: the positionals stay on the command line. A user repeats the run from these files.
std::vector<std::string> WithParameterFile(const std::string& exe, const std::string& command,
                                           const std::vector<std::string>& args, const std::filesystem::path& params);

/// Whether `c` has ended (then its exit status, or 128 + the signal, is in c.status).
bool Poll(Child& c);

/// SIGINT, then SIGKILL after `grace`: no orphans.
void Stop(std::vector<Child>& children, std::chrono::milliseconds grace = std::chrono::milliseconds(4000));

/// The file's text, empty when it cannot be read.
std::string ReadText(const std::filesystem::path& p);

/// A process's JSON output, or an empty object when it wrote none or only part of one (it was killed, or failed
/// early): the run is then reported as failed with "no result", never as an exception from the fields read.
nlohmann::json ReadJson(const std::filesystem::path& p);

}  // namespace visco::app::demo

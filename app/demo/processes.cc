#include "app/demo/processes.h"

#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <sstream>
#include <thread>

#include "app/parameter_file.h"
#include "common/error.h"
#include "common/write_output.h"

namespace visco::app::demo {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

Child Spawn(const std::string& name, const std::vector<std::string>& argv, const fs::path& out, const fs::path& err) {
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) throw JobFailed("cannot start " + name + ": fork failed");
  if (pid == 0) {
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() != parent) _exit(126);
    if (!freopen(out.c_str(), "w", stdout) || !freopen(err.c_str(), "w", stderr)) _exit(126);
    std::vector<char*> cargv;
    for (const auto& a : argv) cargv.push_back(const_cast<char*>(a.c_str()));
    cargv.push_back(nullptr);
    execvp(cargv[0], cargv.data());
    std::fprintf(stderr, "cannot execute %s\n", cargv[0]);
    _exit(127);
  }
  return {name, pid, -1, false};
}

std::vector<std::string> WithParameterFile(const std::string& exe, const std::string& command,
                                           const std::vector<std::string>& args, const fs::path& params) {
  WriteTextOutput(ParameterFileJson(command, args), params.string());
  std::vector<std::string> argv = {exe, command};
  for (const std::string& a : args) {
    if (a.rfind("--", 0) == 0) break;
    argv.push_back(a);
  }
  argv.push_back("--config");
  argv.push_back(params.string());
  return argv;
}

bool Poll(Child& c) {
  if (c.exited) return true;
  int status = 0;
  if (waitpid(c.pid, &status, WNOHANG) == c.pid) {
    c.exited = true;
    c.status = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }
  return c.exited;
}

void Stop(std::vector<Child>& children, std::chrono::milliseconds grace) {
  for (auto& c : children) {
    if (!Poll(c)) kill(c.pid, SIGINT);
  }
  const auto deadline = Clock::now() + grace;
  for (auto& c : children) {
    while (!Poll(c) && Clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (!Poll(c)) {
      kill(c.pid, SIGKILL);
      int status = 0;
      waitpid(c.pid, &status, 0);
      c.exited = true;
      c.status = 128 + SIGKILL;
    }
  }
}

std::string ReadText(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

nlohmann::json ReadJson(const fs::path& p) {
  try {
    nlohmann::json j = nlohmann::json::parse(ReadText(p));
    return j.is_object() ? j : nlohmann::json::object();
  } catch (const std::exception&) {
    return nlohmann::json::object();
  }
}

}  // namespace visco::app::demo

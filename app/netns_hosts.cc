#include "app/netns_hosts.h"

#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <string>

#include "common/error.h"

namespace visco::app {
namespace {

// Runs a shell command, returns its exit status and what it printed (stdout and stderr).
int RunCapture(const std::string& command, std::string& output) {
  output.clear();
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) return -1;
  std::array<char, 512> buffer{};
  while (std::fgets(buffer.data(), static_cast<int>(buffer.size()), pipe) != nullptr) output += buffer.data();
  const int status = pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

NetnsHosts::NetnsHosts(std::string prefix, std::vector<std::string> hosts, int subnet)
    : prefix_(std::move(prefix)), hosts_(std::move(hosts)), subnet_(subnet) {
  try {
    const std::string hub = Namespace("hub");
    Ip("netns add " + hub);
    made_.push_back(hub);
    Ip("-n " + hub + " link set lo up");
    Ip("-n " + hub + " link add br0 type bridge mcast_snooping 0");
    Ip("-n " + hub + " link set br0 up");
    for (std::size_t k = 0; k < hosts_.size(); ++k) {
      const std::string ns = Namespace(hosts_[k]);
      Ip("netns add " + ns);
      made_.push_back(ns);
      const std::string port = fmt::format("p{}", k);
      Ip(fmt::format("-n {} link add {} type veth peer name eth0 netns {}", hub, port, ns));
      Ip(fmt::format("-n {} link set {} master br0 up", hub, port));
      Ip(fmt::format("-n {} link set lo up", ns));
      Ip(fmt::format("-n {} addr add {}/24 dev eth0", ns, Address(hosts_[k])));
      Ip(fmt::format("-n {} link set eth0 up", ns));
      Ip(fmt::format("-n {} route add 224.0.0.0/4 dev eth0", ns));
    }
  } catch (...) {
    for (auto it = made_.rbegin(); it != made_.rend(); ++it) {
      std::string ignored;
      RunCapture("ip netns del " + *it, ignored);
    }
    made_.clear();
    throw;
  }
}

NetnsHosts::~NetnsHosts() {
  for (auto it = made_.rbegin(); it != made_.rend(); ++it) {
    std::string output;
    if (RunCapture("ip netns del " + *it, output) != 0) {
      std::fprintf(stderr, "visco demo: could not delete network namespace %s: %s", it->c_str(), output.c_str());
    }
  }
}

void NetnsHosts::Ip(const std::string& args) {
  std::string output;
  const int status = RunCapture("ip " + args, output);
  if (status != 0) {
    while (!output.empty() && output.back() == '\n') output.pop_back();
    throw JobFailed(fmt::format("--netns: `ip {}` failed (exit {}): {}", args, status, output));
  }
}

std::vector<std::string> NetnsHosts::Wrap(const std::string& host, const std::vector<std::string>& argv) const {
  std::vector<std::string> out = {"ip", "netns", "exec", Namespace(host)};
  out.insert(out.end(), argv.begin(), argv.end());
  return out;
}

std::string NetnsHosts::Address(const std::string& host) const {
  const auto it = std::find(hosts_.begin(), hosts_.end(), host);
  return fmt::format("10.199.{}.{}", subnet_, 1 + (it - hosts_.begin()));
}

std::uint64_t NetnsHosts::NamespaceInode(const std::string& name) {
  struct stat st {};
  if (stat(("/run/netns/" + name).c_str(), &st) != 0) return 0;
  return st.st_ino;
}

std::uint64_t NetnsHosts::ProcessNamespaceInode(pid_t pid) {
  struct stat st {};
  if (stat(fmt::format("/proc/{}/ns/net", pid).c_str(), &st) != 0) return 0;
  return st.st_ino;
}

bool NetnsHosts::Available(std::string* why) {
  if (geteuid() != 0) {
    if (why != nullptr) *why = "needs root (it creates network namespaces with `ip netns`)";
    return false;
  }
  std::string output;
  if (RunCapture("ip -V", output) != 0) {
    if (why != nullptr) *why = "needs iproute2's `ip` (Debian: iproute2)";
    return false;
  }
  return true;
}

}  // namespace visco::app

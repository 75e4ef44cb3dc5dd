#pragma once
// Simulated hosts for `visco demo --netns`: one Linux network namespace per process, each with its own eth0 joined
// by a veth pair to a bridge in a hub namespace, addresses on a private /24 and a route for multicast, so that the
// demo's processes talk LCM (UDP multicast, ttl=1) across a real link as they would between machines. Needs root
// (`ip netns`, iproute2).

#include <sys/types.h>

#include <cstdint>
#include <string>
#include <vector>

namespace visco::app {

class NetnsHosts {
 public:
  /// Creates the hub (a bridge with multicast snooping off, so that every group floods to every port) and one
  /// namespace per host: `<prefix>-<host>` with eth0 at 10.199.<subnet>.<k + 1>/24 and 224.0.0.0/4 routed to it.
  /// @throws visco::JobFailed naming the `ip` command that failed and what it printed (what was made is removed).
  NetnsHosts(std::string prefix, std::vector<std::string> hosts, int subnet);
  /// Deletes the namespaces (their veths go with them).
  ~NetnsHosts();
  NetnsHosts(const NetnsHosts&) = delete;
  NetnsHosts& operator=(const NetnsHosts&) = delete;

  /// The namespace of `host`.
  std::string Namespace(const std::string& host) const { return prefix_ + "-" + host; }
  /// `argv` run inside the host's namespace (`ip netns exec NS argv...`: the same process, after setns).
  std::vector<std::string> Wrap(const std::string& host, const std::vector<std::string>& argv) const;
  /// The host's address (dotted quad).
  std::string Address(const std::string& host) const;

  /// Inode of a named namespace (/run/netns/NAME), 0 if unknown.
  static std::uint64_t NamespaceInode(const std::string& name);
  /// Inode of the network namespace a process is in (/proc/PID/ns/net), 0 if unknown.
  static std::uint64_t ProcessNamespaceInode(pid_t pid);
  /// Whether this process may create namespaces (root, `ip` present).
  static bool Available(std::string* why);

 private:
  void Ip(const std::string& args);
  std::string prefix_;
  std::vector<std::string> hosts_;
  int subnet_ = 0;
  std::vector<std::string> made_;  // namespaces to delete
};

}  // namespace visco::app

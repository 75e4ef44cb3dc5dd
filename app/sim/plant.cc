#include "app/sim/plant.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <thread>

#include "common/error.h"

namespace visco::sim {
namespace {

constexpr char kMagic[4] = {'V', 'P', 'L', '1'};
constexpr std::size_t kRequestSize = 16;
constexpr std::size_t kReplySize = 24;

// The wire's f64 is little-endian, as this machine's (x86-64, ARM64 in little-endian mode).
double ReadDouble(const unsigned char* p) {
  double v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
void WriteDouble(unsigned char* p, double v) { std::memcpy(p, &v, sizeof v); }

}  // namespace

void ParseUdpAddress(const std::string& address, const char* option, std::string& host, int& port) {
  const std::size_t colon = address.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == address.size()) {
    throw InputError("command line", option, "give HOST:PORT (e.g. 127.0.0.1:47000), not '" + address + "'");
  }
  host = address.substr(0, colon);
  if (host == "localhost") host = "127.0.0.1";
  in_addr a{};
  if (inet_pton(AF_INET, host.c_str(), &a) != 1) {
    throw InputError("command line", option, "'" + host + "' is not an IPv4 address");
  }
  const std::string p = address.substr(colon + 1);
  char* end = nullptr;
  const long value = std::strtol(p.c_str(), &end, 10);
  if (*end != '\0' || value < 0 || value > 65535) {
    throw InputError("command line", option, "the port must be 0..65535, not '" + p + "'");
  }
  port = static_cast<int>(value);
}

UdpPlant::UdpPlant(const PlantOptions& options, drivers::SimulatedRobot& robot) : options_(options), robot_(robot) {
  if (!(options.period_s > 0 && options.period_s <= 0.1)) {
    throw InputError("command line", "--plant-period-ms", "must be in (0, 100]");
  }
  if (!(options.axis_timeout_s > options.period_s)) {
    throw InputError("command line", "--plant-axis-timeout-ms", "must be longer than the plant's period");
  }
  std::string host;
  int port = 0;
  ParseUdpAddress(options.address, "--plant", host, port);
  fd_ = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd_ < 0) throw JobFailed(std::string("plant: socket: ") + std::strerror(errno));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  inet_pton(AF_INET, host.c_str(), &addr.sin_addr);
  if (bind(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    const int e = errno;
    close(fd_);
    fd_ = -1;
    throw JobFailed("plant: cannot bind UDP " + options.address + ": " + std::strerror(e));
  }
  socklen_t len = sizeof addr;
  getsockname(fd_, reinterpret_cast<sockaddr*>(&addr), &len);
  port_ = ntohs(addr.sin_port);
  if (!options.trace_path.empty()) {
    trace_ = std::fopen(options.trace_path.c_str(), "w");
    if (trace_ == nullptr) {
      close(fd_);
      fd_ = -1;
      throw InputError(options.trace_path, "", std::string("cannot write the plant's trace: ") + std::strerror(errno));
    }
  }
}

UdpPlant::~UdpPlant() {
  if (fd_ >= 0) close(fd_);
  if (trace_ != nullptr) std::fclose(trace_);
}

PlantStats UdpPlant::Stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

void UdpPlant::Run(const std::atomic<bool>& stop) {
  using Clock = std::chrono::steady_clock;
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(options_.period_s));
  double command[2] = {0.0, 0.0};
  Clock::time_point heard[2] = {};
  bool alive[2] = {false, false};
  // Who asked since the last step, answered after it.
  sockaddr_in asker[2] = {};
  bool asked[2] = {false, false};
  auto next = Clock::now();
  auto last = next;
  auto next_trace = next;
  PlantStats local;
  while (!stop.load()) {
    next += period;
    const auto before = Clock::now();
    if (next < before - 10 * period) next = before;  // fell far behind (a stalled CPU): no burst of catch-up steps
    std::this_thread::sleep_until(next);
    const auto now = Clock::now();
    for (;;) {
      unsigned char buf[64];
      sockaddr_in from{};
      socklen_t from_len = sizeof from;
      const ssize_t n = recvfrom(fd_, buf, sizeof buf, 0, reinterpret_cast<sockaddr*>(&from), &from_len);
      if (n < 0) break;  // EAGAIN: nothing more
      const int axis = n >= 5 ? buf[4] : -1;
      if (static_cast<std::size_t>(n) != kRequestSize || std::memcmp(buf, kMagic, 4) != 0 || axis < 0 || axis > 1 ||
          !std::isfinite(ReadDouble(buf + 8))) {
        ++local.malformed;
        continue;
      }
      ++local.datagrams;
      command[axis] = ReadDouble(buf + 8);
      heard[axis] = now;
      if (!alive[axis]) spdlog::info("plant: axis {} driven", axis == 0 ? "x" : "y");
      alive[axis] = true;
      asker[axis] = from;
      asked[axis] = true;
    }
    for (int axis = 0; axis < 2; ++axis) {
      if (alive[axis] && std::chrono::duration<double>(now - heard[axis]).count() > options_.axis_timeout_s) {
        alive[axis] = false;
        command[axis] = 0.0;
        ++local.axis_losses;
        spdlog::warn("plant: axis {}'s drive silent for {:.0f} ms: the axis is braked", axis == 0 ? "x" : "y",
                     options_.axis_timeout_s * 1e3);
      }
    }
    robot_.SetVelocity(command);
    // The elapsed time, not the nominal period: the drives run on the wall clock. A stall longer than 50 ms (a
    // stopped process) is not integrated.
    robot_.Step(std::min(std::chrono::duration<double>(now - last).count(), 0.05));
    last = now;
    ++local.steps;
    const drivers::RobotFeedback f = robot_.Read();
    for (int axis = 0; axis < 2; ++axis) {
      if (!asked[axis]) continue;
      asked[axis] = false;
      unsigned char reply[kReplySize] = {};
      std::memcpy(reply, kMagic, 4);
      reply[4] = static_cast<unsigned char>(axis);
      WriteDouble(reply + 8, f.position[axis]);
      WriteDouble(reply + 16, f.velocity[axis]);
      sendto(fd_, reply, sizeof reply, 0, reinterpret_cast<const sockaddr*>(&asker[axis]), sizeof asker[axis]);
    }
    local.last.time_ns = 0;
    for (int i = 0; i < 2; ++i) {
      local.last.position[i] = f.position[i];
      local.last.velocity[i] = f.velocity[i];
    }
    local.last.contact = f.contact;
    if (trace_ != nullptr && now >= next_trace) {
      next_trace = now + std::chrono::milliseconds(10);
      std::fprintf(trace_, "%.6f %.6f %.6f %.6f %.6f %d\n",
                   std::chrono::duration<double>(now.time_since_epoch()).count(), f.position[0], f.position[1],
                   f.velocity[0], f.velocity[1], f.contact ? 1 : 0);
      std::fflush(trace_);
    }
    std::lock_guard<std::mutex> lock(mutex_);
    stats_ = local;
  }
}

}  // namespace visco::sim

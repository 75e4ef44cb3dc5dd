// Figures on virtual CAN, run inside the HIL VM (tests/drivers/hil/run_in_vm.sh --bench), never on the host:
// - command throughput of RobotLink::SendCommand against can-utils' cangen sending the same number of 8-byte
//   frames (the baseline, same run, same VM, both timed from the outside of their send loops);
// - command-to-feedback round trip through the `visco driver` process against the plain vcan loopback latency of
//   one frame between two sockets of one process (the baseline).

#include <benchmark/benchmark.h>
#include <sched.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "drivers/robot_link.h"
#include "drivers/socketcan.h"

extern char** environ;

namespace {

using namespace visco::drivers;

pid_t Spawn(std::vector<std::string> args) {
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = -1;
  if (posix_spawnp(&pid, argv[0], nullptr, nullptr, argv.data(), environ) != 0) return -1;
  return pid;
}

int Wait(pid_t pid) {
  int status = 0;
  waitpid(pid, &status, 0);
  return status;
}

void BM_CangenBaseline(benchmark::State& state) {
  const auto frames = static_cast<int>(state.range(0));
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    const pid_t pid = Spawn(
        {"cangen", "vcan0", "-g", "0", "-p", "10", "-I", "27F", "-L", "8", "-D", "i", "-n", std::to_string(frames)});
    if (pid < 0 || Wait(pid) != 0) {
      state.SkipWithError("cangen failed");
      return;
    }
    state.SetIterationTime(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  state.SetItemsProcessed(state.iterations() * frames);
}
BENCHMARK(BM_CangenBaseline)->Arg(20000)->UseManualTime()->Unit(benchmark::kMillisecond);

void BM_SendCommand(benchmark::State& state) {
  const auto frames = static_cast<int>(state.range(0));
  RobotLinkConfig config;
  config.node_id = 127;  // nobody listens: pure send cost, as for cangen
  config.can_interface = "vcan0";
  auto link = MakeSocketCanRobotLink(config);
  VelocityCommand command;
  command.velocity[0] = 0.1;
  // Without a driver there is no session, and a link sends only e-stops then (the same frame, the same cost).
  command.estop = true;
  std::uint64_t retries = 0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    for (int i = 0; i < frames;) {
      const LinkResult r = link->SendCommand(command, MonotonicMicros());
      if (r == LinkResult::kOk) {
        ++i;
      } else if (r == LinkResult::kBufferFull) {
        ++retries;
        std::this_thread::yield();
      } else {
        state.SkipWithError(ToString(r));
        return;
      }
    }
    state.SetIterationTime(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  state.SetItemsProcessed(state.iterations() * frames);
  state.counters["buffer_full_retries"] = static_cast<double>(retries);
}
BENCHMARK(BM_SendCommand)->Arg(20000)->UseManualTime()->Unit(benchmark::kMillisecond);

void BM_VcanLoopbackBaseline(benchmark::State& state) {
  CanSocketOptions tx_options;
  tx_options.interface = "vcan0";
  tx_options.receive = false;
  CanSocket tx(tx_options);
  CanSocketOptions rx_options;
  rx_options.interface = "vcan0";
  rx_options.filters = {CanFilter{0x7E0, 0x7FF | visco::drivers::can::kEffFlag | visco::drivers::can::kRtrFlag}};
  CanSocket rx(rx_options);
  visco::drivers::can::Frame frame;
  frame.id = 0x7E0;
  frame.dlc = 8;
  ReceivedFrame in;
  for (auto _ : state) {
    tx.Write(frame);
    while (rx.Read(in) != CanIo::kOk) rx.WaitReadable(100'000);
  }
}
BENCHMARK(BM_VcanLoopbackBaseline)->Unit(benchmark::kMicrosecond);

void BM_CommandToFeedbackRoundTrip(benchmark::State& state) {
  cpu_set_t cpus;  // the controller on CPU 0, the driver on CPU 1 (as in the HIL test)
  CPU_ZERO(&cpus);
  CPU_SET(0, &cpus);
  sched_setaffinity(0, sizeof(cpus), &cpus);
  const char* bin = std::getenv("VISCO_BIN");
  const pid_t driver = Spawn({"taskset", "-c", "1", bin != nullptr ? bin : "build/bin/visco", "driver", "--can",
                              "vcan0", "--node", "9", "--watchdog-ms", "1000", "--status-period-ms", "100"});
  RobotLinkConfig config;
  config.node_id = 9;
  config.can_interface = "vcan0";
  auto link = MakeSocketCanRobotLink(config);
  RobotStatus status;
  const auto until_answer = [&](std::int64_t timeout_us) {
    const std::int64_t end = MonotonicMicros() + timeout_us;
    const std::uint32_t want = link->last_command_seq();
    while (MonotonicMicros() < end) {
      link->Poll(MonotonicMicros());
      if (link->TakeStatus(status) == LinkResult::kOk && status.command_seq == want) return true;
      std::this_thread::sleep_for(std::chrono::microseconds(20));  // leave the CPU to the driver
    }
    return false;
  };
  VelocityCommand command;
  command.reset = true;
  bool ready = false;
  for (int i = 0; i < 1200 && !ready; ++i) {  // the driver process needs a while to start in the VM
    // Not sent (kNoSession) until the link has seen the driver's session frame, which until_answer() polls for.
    ready = link->SendCommand(command, MonotonicMicros()) == LinkResult::kOk && until_answer(100'000) &&
            status.state == RobotState::kReady;
    if (!ready && link->session() == 0) until_answer(100'000);
  }
  if (!ready) {
    state.SkipWithError("the driver did not answer");
  } else {
    command.reset = false;
    command.velocity[0] = 0.01;
    std::vector<double> samples;
    for (auto _ : state) {
      const auto start = std::chrono::steady_clock::now();
      link->SendCommand(command, MonotonicMicros());
      if (!until_answer(1'000'000)) {
        state.SkipWithError("no answer within 1 s");
        break;
      }
      const double us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count();
      samples.push_back(us);
      state.SetIterationTime(us * 1e-6);
    }
    if (!samples.empty()) {
      std::sort(samples.begin(), samples.end());
      state.counters["p50_us"] = samples[samples.size() / 2];
      state.counters["p99_us"] = samples[samples.size() * 99 / 100];
      state.counters["max_us"] = samples.back();
    }
  }
  kill(driver, SIGTERM);
  Wait(driver);
}
BENCHMARK(BM_CommandToFeedbackRoundTrip)->UseManualTime()->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();

// A seeded fuzzer of `visco replay` itself: the checked-in log with random bytes changed inside random events'
// messages (images, vision outputs, controller records, the configuration) or in their framing, replayed with
// --check through vision and the controller. Every case must end in a summary or in one of the two user-facing
// errors (InputError: exit 2, JobFailed: exit 1), never in a crash or another exception (CI runs it under ASan and
// UBSan); and the damage must be noticed: most cases report a difference or skipped bytes.

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "common/error.h"
#include "replay/event_log.h"
#include "replay/replayer.h"

namespace visco::replay {
namespace {

#if defined(__SANITIZE_ADDRESS__)
constexpr int kDefaultCases = 8;  // each replay of the log is ~10x slower under ASan
#else
constexpr int kDefaultCases = 40;
#endif

int Cases() {
  const char* env = std::getenv("VISCO_FUZZ_ITERATIONS");  // to run longer by hand
  return env != nullptr ? std::max(1, std::atoi(env)) : kDefaultCases;
}

TEST(ReplayFuzz, DamagedMessagesAreReportedNeverACrash) {
  const std::string fixture = "tests/replay/data/slot_run.lcmlog";
  std::ifstream in(fixture, std::ios::binary);
  ASSERT_TRUE(in.good()) << "run from the repository top";
  const std::vector<std::uint8_t> original{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  struct Span {
    std::size_t data, size;
    std::string channel;
  };
  std::vector<Span> events;
  {
    EventLogReader reader(original);
    LogEvent e;
    while (reader.Next(e)) {
      events.push_back(
          {static_cast<std::size_t>(e.data.data() - original.data()), e.data.size(), std::string(e.channel)});
    }
  }
  ASSERT_GT(events.size(), 1000u);
  const std::string path =
      (std::filesystem::temp_directory_path() / ("visco_replay_fuzz_" + std::to_string(::getpid()) + ".lcmlog"))
          .string();
  const int kCases = Cases();
  int noticed = 0, input_errors = 0, job_failures = 0;
  for (int c = 0; c < kCases; ++c) {
    std::mt19937 rng(20261202u + static_cast<std::uint32_t>(c));
    std::vector<std::uint8_t> bytes = original;
    const int damages = 1 + static_cast<int>(rng() % 4);
    std::string what;
    for (int d = 0; d < damages; ++d) {
      const Span& e = events[rng() % events.size()];
      if (rng() % 5 == 0) {
        // Framing: a byte of the header (sync word, number, timestamp, lengths) or of the channel name.
        const std::size_t header = e.data - e.channel.size() - kHeaderBytes;
        bytes[header + rng() % (kHeaderBytes + e.channel.size())] ^= static_cast<std::uint8_t>(1 + rng() % 255);
        what += " header of " + e.channel;
      } else if (e.size > 0) {
        // The message: 1-8 bytes anywhere in it (fingerprint, lengths, strings, numbers, pixels).
        const int n = 1 + static_cast<int>(rng() % 8);
        for (int k = 0; k < n; ++k) bytes[e.data + rng() % e.size] ^= static_cast<std::uint8_t>(1 + rng() % 255);
        what += " message on " + e.channel;
      }
    }
    {
      std::ofstream out(path, std::ios::binary);
      out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    }
    ReplayOptions o;
    o.log_path = path;
    o.pipeline.camera = "data/sim/slot_camera.xml";
    o.pipeline.extrinsics = "data/sim/slot_extrinsics.json";
    o.pipeline.objects = "data/sim/slot_objects.json";
    // The fixture names its run's files relative to its own folder; this copy lies elsewhere.
    o.strategy_path = "tests/control/data/slot_e2e_plan.json";
    o.scene_path = "tests/control/data/slot_e2e_scene.json";
    o.rays_path = "tests/replay/data/slot_e2e_rays.json";
    o.fast = true;
    o.publish = false;
    o.check = true;
    try {
      const ReplaySummary s = RunReplay(o);
      if (!s.identical() || !s.log.clean() || s.undecodable > 0) ++noticed;
    } catch (const InputError& e) {
      ++input_errors;
      ++noticed;
    } catch (const JobFailed& e) {
      ++job_failures;
      ++noticed;
    } catch (const std::exception& e) {
      ADD_FAILURE() << "case " << c << " (" << what << "): unexpected exception: " << e.what();
    }
  }
  std::filesystem::remove(path);
  std::printf("%d damaged logs: %d noticed (%d input errors, %d job failures)\n", kCases, noticed, input_errors,
              job_failures);
  // Changed bytes may hit what the comparison leaves out (a publication stamp) or change nothing that matters (a
  // pixel far from any tag): most, not all, cases must be noticed.
  EXPECT_GE(noticed, kCases * 3 / 4);
}

}  // namespace
}  // namespace visco::replay

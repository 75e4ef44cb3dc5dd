// A seeded fuzzer of the event log reader: valid logs damaged at random (bit flips, truncation, overwritten sync
// words, inserted garbage, deleted ranges, random bytes over a range). Properties, for every case:
//  - the reader never crashes or reads outside the file (run under ASan in CI) and accounts for every byte: the
//    events it returns plus what it reports skipped make up the file;
//  - every event the damage did not touch is returned intact (same channel, timestamp, data), in order: damage costs
//    at most the events it hits.
// Payloads hold no 0xED byte, so no sync word appears inside an intact event by chance (a real log may hold one; the
// reader then checks the header that follows it and the sync word at its end).

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "replay/event_log.h"

namespace visco::replay {
namespace {

struct Original {
  std::string channel;
  std::int64_t timestamp;
  std::vector<std::uint8_t> data;
  std::size_t offset = 0, end = 0;  // in the damaged file; `hit` if the damage overlaps it
  bool hit = false;
};

int Iterations() {
  const char* env = std::getenv("VISCO_FUZZ_ITERATIONS");
  return env != nullptr ? std::max(1, std::atoi(env)) : 3000;
}

TEST(EventLogFuzz, DamageCostsAtMostTheEventsItHits) {
  const std::uint32_t base_seed = 20261201;
  int damaged_cases = 0, lost_events = 0, total_events = 0;
  for (int iteration = 0; iteration < Iterations(); ++iteration) {
    std::mt19937 rng(base_seed + static_cast<std::uint32_t>(iteration));
    std::vector<Original> events(1 + rng() % 25);
    std::vector<std::uint8_t> bytes;
    for (std::size_t i = 0; i < events.size(); ++i) {
      Original& e = events[i];
      e.channel = "VISCO_" + std::string(1 + rng() % 12, static_cast<char>('A' + rng() % 26));
      e.timestamp = 1'790'000'000'000'000 + static_cast<std::int64_t>(i) * 33'333;
      e.data.resize(rng() % 3 == 0 ? rng() % 4000 : rng() % 60);
      for (auto& b : e.data) b = static_cast<std::uint8_t>(rng() % 0xED);
      e.offset = bytes.size();
      AppendEvent(bytes, static_cast<std::int64_t>(i), e.timestamp, e.channel, e.data);
      e.end = bytes.size();
    }
    // One or two damages; each marks the original events it overlaps and shifts those after an insert/delete.
    const int damages = 1 + static_cast<int>(rng() % 2);
    for (int d = 0; d < damages && !bytes.empty(); ++d) {
      const std::size_t at = rng() % bytes.size();
      auto mark = [&](std::size_t from, std::size_t to) {
        for (Original& e : events) {
          if (e.offset < to && from < e.end) e.hit = true;
        }
      };
      switch (rng() % 6) {
        case 0: {  // flip 1-3 bits near each other
          const int n = 1 + static_cast<int>(rng() % 3);
          for (int k = 0; k < n; ++k) {
            const std::size_t p = std::min(bytes.size() - 1, at + rng() % 8);
            bytes[p] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
            mark(p, p + 1);
          }
          break;
        }
        case 1: {  // truncate
          mark(at, bytes.size());
          bytes.resize(at);
          break;
        }
        case 2: {  // a wrong sync word on a random event
          const Original& e = events[rng() % events.size()];
          const std::size_t p = e.offset + rng() % 4;  // stale if an earlier damage moved it: then just a byte
          if (p < bytes.size()) {
            bytes[p] ^= static_cast<std::uint8_t>(1 + rng() % 255);
            mark(p, p + 1);
          }
          break;
        }
        case 3: {  // insert garbage
          std::vector<std::uint8_t> garbage(1 + rng() % 100);
          for (auto& b : garbage) b = static_cast<std::uint8_t>(rng());
          bytes.insert(bytes.begin() + static_cast<std::ptrdiff_t>(at), garbage.begin(), garbage.end());
          for (Original& e : events) {
            if (e.offset < at && at < e.end) e.hit = true;  // inside an event
            if (e.offset >= at) e.offset += garbage.size(), e.end += garbage.size();
          }
          break;
        }
        case 4: {  // delete a range
          const std::size_t n = std::min(bytes.size() - at, std::size_t{1} + rng() % 300);
          mark(at, at + n);
          bytes.erase(bytes.begin() + static_cast<std::ptrdiff_t>(at),
                      bytes.begin() + static_cast<std::ptrdiff_t>(at + n));
          for (Original& e : events) {
            if (e.offset >= at + n) e.offset -= n, e.end -= n;
          }
          break;
        }
        default: {  // random bytes over a range
          const std::size_t n = std::min(bytes.size() - at, std::size_t{1} + rng() % 64);
          for (std::size_t k = 0; k < n; ++k) bytes[at + k] = static_cast<std::uint8_t>(rng());
          mark(at, at + n);
          break;
        }
      }
    }
    ++damaged_cases;

    EventLogReader reader(bytes);
    LogEvent e;
    std::vector<LogEvent> read;
    while (reader.Next(e)) {
      ASSERT_GE(e.offset, 0);
      ASSERT_LE(static_cast<std::size_t>(e.offset) + kHeaderBytes + e.channel.size() + e.data.size(), bytes.size());
      read.push_back(e);
    }
    const ReadReport& r = reader.report();
    ASSERT_EQ(r.event_bytes + r.skipped_bytes, static_cast<std::int64_t>(bytes.size())) << "iteration " << iteration;
    ASSERT_EQ(r.events, static_cast<std::int64_t>(read.size()));
    // Every untouched original is among the events read, at its offset, intact.
    std::size_t cursor = 0;
    for (const Original& o : events) {
      ++total_events;
      if (o.hit) {
        ++lost_events;
        continue;
      }
      while (cursor < read.size() && static_cast<std::size_t>(read[cursor].offset) < o.offset) ++cursor;
      ASSERT_LT(cursor, read.size()) << "iteration " << iteration << ": untouched event at " << o.offset
                                     << " not read; " << r.Describe();
      const LogEvent& got = read[cursor];
      ASSERT_EQ(static_cast<std::size_t>(got.offset), o.offset) << "iteration " << iteration << ": " << r.Describe();
      ASSERT_EQ(got.channel, o.channel) << "iteration " << iteration;
      ASSERT_EQ(got.timestamp, o.timestamp) << "iteration " << iteration;
      ASSERT_TRUE(std::equal(got.data.begin(), got.data.end(), o.data.begin(), o.data.end()))
          << "iteration " << iteration;
    }
  }
  RecordProperty("cases", damaged_cases);
  std::printf("%d damaged logs, %d events, %d hit by the damage; every other event read intact\n", damaged_cases,
              total_events, lost_events);
}

// Pure random input of every length up to a few kB: no crash, every byte accounted for.
TEST(EventLogFuzz, RandomBytesNeverCrashTheReader) {
  std::mt19937 rng(7);
  for (int iteration = 0; iteration < Iterations() / 3; ++iteration) {
    std::vector<std::uint8_t> bytes(rng() % 3000);
    for (auto& b : bytes) b = static_cast<std::uint8_t>(rng());
    // Plant sync words and plausible-looking headers so that the header checks are exercised.
    for (int k = 0; k < 5 && bytes.size() > 40; ++k) {
      const std::size_t p = rng() % (bytes.size() - 28);
      const std::uint8_t sync[4] = {0xED, 0xA1, 0xDA, 0x01};
      std::copy(sync, sync + 4, bytes.begin() + static_cast<std::ptrdiff_t>(p));
      bytes[p + 20] = bytes[p + 21] = bytes[p + 22] = 0;
      bytes[p + 23] = static_cast<std::uint8_t>(1 + rng() % 8);
      bytes[p + 24] = bytes[p + 25] = 0;
      bytes[p + 26] = static_cast<std::uint8_t>(rng() % 4);
    }
    EventLogReader reader(bytes);
    LogEvent e;
    while (reader.Next(e)) {
      ASSERT_LE(static_cast<std::size_t>(e.offset) + kHeaderBytes + e.channel.size() + e.data.size(), bytes.size());
    }
    ASSERT_EQ(reader.report().event_bytes + reader.report().skipped_bytes, static_cast<std::int64_t>(bytes.size()));
  }
}

}  // namespace
}  // namespace visco::replay

// The event log writer and reader: lcm-logger's format both ways (against LCM's own C API), a file that survives
// SIGKILL, counted drops, and the reader's reports on damaged files (truncated tail, flipped bits, a wrong sync
// word).

#include "replay/event_log.h"

#include <gtest/gtest.h>
#include <lcm/eventlog.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace visco::replay {
namespace {

struct Original {
  std::string channel;
  std::int64_t timestamp;
  std::vector<std::uint8_t> data;
};

std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("visco_event_log_" + std::to_string(::getpid()) + "_" + name))
      .string();
}

std::vector<std::uint8_t> ReadFile(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

std::vector<Original> Sample(int n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<Original> events;
  for (int i = 0; i < n; ++i) {
    Original e{"VISCO_CH" + std::to_string(rng() % 5), 1'700'000'000'000'000 + i * 1000, {}};
    e.data.resize(rng() % 400);
    for (auto& b : e.data) b = static_cast<std::uint8_t>(rng() % 0xEC);  // no 0xED: no sync word in payloads
    events.push_back(std::move(e));
  }
  return events;
}

std::vector<std::uint8_t> Encode(const std::vector<Original>& events) {
  std::vector<std::uint8_t> bytes;
  for (std::size_t i = 0; i < events.size(); ++i) {
    AppendEvent(bytes, static_cast<std::int64_t>(i), events[i].timestamp, events[i].channel, events[i].data);
  }
  return bytes;
}

std::vector<Original> ReadAll(EventLogReader& reader) {
  std::vector<Original> out;
  LogEvent e;
  while (reader.Next(e)) out.push_back({std::string(e.channel), e.timestamp, {e.data.begin(), e.data.end()}});
  return out;
}

void ExpectSame(const Original& a, const Original& b) {
  EXPECT_EQ(a.channel, b.channel);
  EXPECT_EQ(a.timestamp, b.timestamp);
  EXPECT_EQ(a.data, b.data);
}

TEST(EventLog, WriterOutputIsReadByLcmsOwnReader) {
  const std::string path = TempPath("writer.lcmlog");
  const auto events = Sample(50, 1);
  {
    EventLogWriter writer(path);
    for (const auto& e : events) ASSERT_TRUE(writer.Write(e.channel, e.timestamp, e.data));
    const WriterStats s = writer.Close();
    EXPECT_EQ(s.events_written, 50u);
    EXPECT_EQ(s.events_dropped, 0u);
    EXPECT_TRUE(s.error.empty());
  }
  lcm_eventlog_t* log = lcm_eventlog_create(path.c_str(), "r");
  ASSERT_NE(log, nullptr);
  int n = 0;
  while (lcm_eventlog_event_t* e = lcm_eventlog_read_next_event(log)) {
    ASSERT_LT(n, 50);
    EXPECT_EQ(e->eventnum, n);
    ExpectSame({std::string(e->channel, static_cast<std::size_t>(e->channellen)), e->timestamp,
                std::vector<std::uint8_t>(static_cast<std::uint8_t*>(e->data),
                                          static_cast<std::uint8_t*>(e->data) + e->datalen)},
               events[static_cast<std::size_t>(n)]);
    lcm_eventlog_free_event(e);
    ++n;
  }
  lcm_eventlog_destroy(log);
  EXPECT_EQ(n, 50);
  std::filesystem::remove(path);
}

TEST(EventLog, ReaderReadsWhatLcmsOwnWriterWrote) {
  const std::string path = TempPath("lcm.lcmlog");
  const auto events = Sample(40, 2);
  lcm_eventlog_t* log = lcm_eventlog_create(path.c_str(), "w");
  ASSERT_NE(log, nullptr);
  for (std::size_t i = 0; i < events.size(); ++i) {
    lcm_eventlog_event_t e{};
    e.eventnum = static_cast<std::int64_t>(i);
    e.timestamp = events[i].timestamp;
    e.channellen = static_cast<std::int32_t>(events[i].channel.size());
    e.datalen = static_cast<std::int32_t>(events[i].data.size());
    e.channel = const_cast<char*>(events[i].channel.c_str());
    e.data = const_cast<std::uint8_t*>(events[i].data.data());
    ASSERT_EQ(lcm_eventlog_write_event(log, &e), 0);
  }
  lcm_eventlog_destroy(log);
  EXPECT_EQ(ReadFile(path), Encode(events));  // byte for byte the same encoding
  EventLogReader reader(path);
  const auto read = ReadAll(reader);
  ASSERT_EQ(read.size(), events.size());
  for (std::size_t i = 0; i < read.size(); ++i) ExpectSame(read[i], events[i]);
  EXPECT_TRUE(reader.report().clean());
  EXPECT_EQ(reader.report().number_gaps, 0);
  std::filesystem::remove(path);
}

TEST(EventLog, PeriodicFlushMakesEventsVisibleBeforeClose) {
  const std::string path = TempPath("flush.lcmlog");
  WriterOptions o;
  o.flush_interval_s = 0.05;
  EventLogWriter writer(path, o);
  const auto events = Sample(10, 3);
  for (const auto& e : events) writer.Write(e.channel, e.timestamp, e.data);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EventLogReader reader(path);  // the writer is still open
  EXPECT_EQ(ReadAll(reader).size(), 10u);
  EXPECT_TRUE(reader.report().clean());
  writer.Close();
  std::filesystem::remove(path);
}

TEST(EventLog, SurvivesSigkillOfTheWritingProcess) {
  const std::string path = TempPath("killed.lcmlog");
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    WriterOptions o;
    o.flush_interval_s = 0.05;
    EventLogWriter writer(path, o);
    std::vector<std::uint8_t> data(3000, 7);
    for (std::int64_t i = 0;; ++i) {
      writer.Write("VISCO_CAMERA_IMAGE", 1'700'000'000'000'000 + i, data);
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status));
  EventLogReader reader(path);
  LogEvent e;
  std::int64_t n = 0;
  while (reader.Next(e)) {
    EXPECT_EQ(e.number, n);  // every event up to the last flush, in order, none lost in between
    EXPECT_EQ(e.timestamp, 1'700'000'000'000'000 + n);
    EXPECT_EQ(e.data.size(), 3000u);
    ++n;
  }
  EXPECT_GT(n, 100);  // ~0.4 s of flushed events at ~4 kHz
  const ReadReport& r = reader.report();
  EXPECT_EQ(r.event_bytes + r.skipped_bytes, r.file_bytes);
  // What is skipped is at most one cut event at the end.
  EXPECT_LE(r.skipped_ranges, 1);
  if (r.skipped_ranges == 1) {
    EXPECT_TRUE(r.truncated_tail);
  }
  std::filesystem::remove(path);
}

TEST(EventLog, AFullQueueDropsAndCountsInsteadOfBlocking) {
  const std::string path = TempPath("drops.lcmlog");
  WriterOptions o;
  o.max_queue_bytes = 2000;
  EventLogWriter writer(path, o);
  std::vector<std::uint8_t> data(500, 1);
  int accepted = 0;
  for (int i = 0; i < 2000; ++i) accepted += writer.Write("VISCO_X", i, data) ? 1 : 0;
  const WriterStats s = writer.Close();
  EXPECT_EQ(s.events_written + s.events_dropped, 2000u);
  EXPECT_EQ(s.events_written, static_cast<std::uint64_t>(accepted));
  EXPECT_GT(s.events_dropped, 0u);
  EXPECT_FALSE(writer.Write("VISCO_X", 0, data));  // closed
  EventLogReader reader(path);
  EXPECT_EQ(ReadAll(reader).size(), s.events_written);
  std::filesystem::remove(path);
}

TEST(EventLog, TruncatedTailIsReportedAndEverythingBeforeItRead) {
  const auto events = Sample(20, 4);
  auto bytes = Encode(events);
  const std::size_t last = bytes.size() - (kHeaderBytes + events.back().channel.size() + events.back().data.size());
  bytes.resize(last + 10);  // cut inside the last event's header
  EventLogReader reader(bytes);
  const auto read = ReadAll(reader);
  ASSERT_EQ(read.size(), 19u);
  for (std::size_t i = 0; i < read.size(); ++i) ExpectSame(read[i], events[i]);
  const ReadReport& r = reader.report();
  EXPECT_TRUE(r.truncated_tail);
  EXPECT_EQ(r.skipped_bytes, 10);
  EXPECT_NE(r.Describe().find("cut off by the end of the file"), std::string::npos) << r.Describe();
}

TEST(EventLog, WrongSyncWordSkipsThatEventOnly) {
  const auto events = Sample(20, 5);
  auto bytes = Encode(events);
  EventLogReader clean(bytes);
  std::vector<std::int64_t> offsets;
  LogEvent e;
  while (clean.Next(e)) offsets.push_back(e.offset);
  bytes[static_cast<std::size_t>(offsets[7])] = 0xEE;  // the 8th event's sync word
  EventLogReader reader(bytes);
  const auto read = ReadAll(reader);
  ASSERT_EQ(read.size(), 19u);
  for (std::size_t i = 0; i < read.size(); ++i) ExpectSame(read[i], events[i < 7 ? i : i + 1]);
  const ReadReport& r = reader.report();
  EXPECT_EQ(r.skipped_ranges, 1);
  EXPECT_EQ(r.skipped[0].offset, offsets[7]);
  EXPECT_EQ(r.skipped[0].offset + r.skipped[0].bytes, offsets[8]);
  EXPECT_NE(r.skipped[0].reason.find("no sync word"), std::string::npos);
  EXPECT_EQ(r.number_gaps, 1);
  EXPECT_EQ(r.missing_numbers, 1);
  EXPECT_FALSE(r.truncated_tail);
}

TEST(EventLog, FlippedLengthBitIsCaughtByTheNextSyncWord) {
  const auto events = Sample(20, 6);
  auto bytes = Encode(events);
  EventLogReader clean(bytes);
  std::vector<std::int64_t> offsets;
  LogEvent e;
  while (clean.Next(e)) offsets.push_back(e.offset);
  // Event 5's data length grows by 2^12 bytes: it would swallow the events after it.
  bytes[static_cast<std::size_t>(offsets[5]) + 26] ^= 0x10;
  EventLogReader reader(bytes);
  const auto read = ReadAll(reader);
  ASSERT_EQ(read.size(), 19u);
  for (std::size_t i = 0; i < read.size(); ++i) ExpectSame(read[i], events[i < 5 ? i : i + 1]);
  EXPECT_EQ(reader.report().skipped_ranges, 1);
  EXPECT_EQ(reader.report().skipped[0].offset, offsets[5]);
}

TEST(EventLog, FlippedPayloadBitChangesOnlyThatEvent) {
  const auto events = Sample(20, 7);
  auto bytes = Encode(events);
  std::size_t at = 0;
  for (std::size_t i = 0; i < 10; ++i) at += kHeaderBytes + events[i].channel.size() + events[i].data.size();
  ASSERT_GT(events[10].data.size(), 2u);
  bytes[at + kHeaderBytes + events[10].channel.size() + events[10].data.size() / 2] ^= 0x04;  // event 10's data
  EventLogReader reader(bytes);
  const auto read = ReadAll(reader);
  ASSERT_EQ(read.size(), 20u);
  int changed = 0;
  for (std::size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read[i].channel, events[i].channel);
    changed += read[i].data != events[i].data || read[i].timestamp != events[i].timestamp ? 1 : 0;
  }
  EXPECT_EQ(changed, 1);  // the format has no checksum: the damage shows up where the message is decoded
  EXPECT_TRUE(reader.report().clean());
}

TEST(EventLog, GarbageAndEmptyFilesGiveNoEventAndAReport) {
  std::vector<std::uint8_t> garbage(5000);
  std::mt19937 rng(8);
  for (auto& b : garbage) b = static_cast<std::uint8_t>(rng());
  EventLogReader reader(garbage);
  LogEvent e;
  int n = 0;
  while (reader.Next(e)) ++n;
  EXPECT_EQ(reader.report().event_bytes + reader.report().skipped_bytes, 5000);
  EXPECT_EQ(n, reader.report().events);
  EXPECT_GT(reader.report().skipped_bytes, 4000);
  std::vector<std::uint8_t> empty;
  EventLogReader none(empty);
  EXPECT_FALSE(none.Next(e));
  EXPECT_TRUE(none.report().clean());
  EXPECT_THROW(EventLogReader("/nonexistent/visco.lcmlog"), std::exception);
}

}  // namespace
}  // namespace visco::replay

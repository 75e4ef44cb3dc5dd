#pragma once
// LCM event logs in lcm-logger's format, so that lcm-logger, lcm-logplayer and lcm-logplayer-gui read what visco
// writes and visco reads what they write. One event on disk (all integers big-endian):
//
//   uint32 sync word 0xEDA1DA01 | int64 event number | int64 timestamp (receive time, microseconds since the epoch)
//   | int32 channel length | int32 data length | channel bytes (no terminator) | data bytes (the LCM message)
//
// The writer copies events into a bounded queue and a thread of its own writes them (the caller never blocks on the
// disk); a full queue drops the event and counts it. The file is flushed every `flush_interval_s`, so a process
// killed with SIGKILL leaves a log that ends with at most that much missing and possibly one cut event.
// LCM's own reader (lcm_eventlog_read_next_event) stops at the first bad event; this reader resynchronises on the
// next sync word and reports every byte it skipped and why, so a log with a truncated tail, flipped bits or a wrong
// sync word still gives everything that is intact.

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

namespace visco::replay {

inline constexpr std::uint32_t kSyncWord = 0xEDA1DA01;
inline constexpr std::size_t kHeaderBytes = 28;           // sync, number, timestamp, two lengths
inline constexpr std::int32_t kMaxChannelBytes = 256;     // LCM's channel limit is 63; larger is corruption
inline constexpr std::int64_t kMaxDataBytes = 1LL << 30;  // larger than any message visco sends: corruption

/// Encodes one event in the log format and appends it to `out`. Not real-time safe (allocates).
void AppendEvent(std::vector<std::uint8_t>& out, std::int64_t number, std::int64_t timestamp, std::string_view channel,
                 std::span<const std::uint8_t> data);

struct WriterOptions {
  std::size_t max_queue_bytes = 256u << 20;  // events waiting for the disk beyond this are dropped (and counted)
  double flush_interval_s = 0.1;             // s, the longest time an event stays in user-space buffers
};

struct WriterStats {
  std::uint64_t events_written = 0;
  std::uint64_t bytes_written = 0;
  std::uint64_t events_dropped = 0;  // the queue was full, or the disk failed
  std::uint64_t bytes_dropped = 0;
  std::string error;  // the first I/O error, empty if none
};

/// Writes an event log from any number of threads. The writing itself happens on the writer's own thread.
class EventLogWriter {
 public:
  /// Creates (truncates) `path`. Not real-time safe. @throws InputError if the file cannot be created.
  explicit EventLogWriter(const std::string& path, const WriterOptions& options = {});
  ~EventLogWriter();
  EventLogWriter(const EventLogWriter&) = delete;
  EventLogWriter& operator=(const EventLogWriter&) = delete;

  /// Queues one event (copies `data`); `timestamp` is the receive time in microseconds since the epoch. Returns false
  /// when the event was dropped (queue full or writer closed). Thread-safe; not real-time safe (allocates, locks).
  bool Write(std::string_view channel, std::int64_t timestamp, std::span<const std::uint8_t> data);
  /// Writes everything queued, flushes and closes the file; later writes are dropped. Idempotent.
  WriterStats Close();
  WriterStats stats() const;
  const std::string& path() const { return path_; }

 private:
  struct Pending {
    std::string channel;
    std::int64_t timestamp;
    std::vector<std::uint8_t> data;
  };
  void Run();

  std::string path_;
  WriterOptions options_;
  std::FILE* file_ = nullptr;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Pending> queue_;
  std::size_t queued_bytes_ = 0;
  bool closing_ = false;
  bool closed_ = false;
  WriterStats stats_;
  std::int64_t next_number_ = 0;
  std::thread thread_;
};

/// One event as read: views into the reader's buffer, valid while the reader lives.
struct LogEvent {
  std::int64_t number = 0;
  std::int64_t timestamp = 0;  // receive time, microseconds since the epoch
  std::string_view channel;
  std::span<const std::uint8_t> data;
  std::int64_t offset = 0;  // byte offset of the event's sync word in the file
};

/// A stretch of the file the reader could not use.
struct SkippedRange {
  std::int64_t offset = 0;
  std::int64_t bytes = 0;
  std::string reason;
};

struct ReadReport {
  std::int64_t file_bytes = 0;
  std::int64_t events = 0;       // events returned
  std::int64_t event_bytes = 0;  // bytes of the events returned (headers included)
  std::int64_t skipped_bytes = 0;
  std::vector<SkippedRange> skipped;  // in file order (the first 100; skipped_ranges counts all)
  std::int64_t skipped_ranges = 0;
  bool truncated_tail = false;       // the last skipped range is an event cut off by the end of the file
  std::int64_t number_gaps = 0;      // times the event number did not follow the previous one (events lost or dropped)
  std::int64_t missing_numbers = 0;  // events missing according to the numbering (when it increases)

  bool clean() const { return skipped_ranges == 0; }
  /// One paragraph for users: what was read and every range skipped (at most `max_ranges` listed).
  std::string Describe(std::size_t max_ranges = 10) const;
};

/// Reads an event log with resynchronisation. Not thread-safe.
class EventLogReader {
 public:
  /// Maps `path` read-only. @throws InputError if it cannot be opened.
  explicit EventLogReader(const std::string& path);
  /// Reads from memory the caller keeps alive (tests, fuzzing).
  explicit EventLogReader(std::span<const std::uint8_t> bytes);
  ~EventLogReader();
  EventLogReader(const EventLogReader&) = delete;
  EventLogReader& operator=(const EventLogReader&) = delete;

  /// The next intact event, skipping (and reporting) anything that is not one. False at the end of the file.
  bool Next(LogEvent& event);
  /// Starts again from the beginning (the report is reset).
  void Rewind();
  const ReadReport& report() const { return report_; }

 private:
  // Whether a plausible event header starts at `pos`; fills its total size.
  bool PlausibleHeader(std::size_t pos, std::size_t& total) const;
  std::size_t FindSync(std::size_t from) const;
  void Skip(std::size_t from, std::size_t to, std::string reason);

  const std::uint8_t* bytes_ = nullptr;
  std::size_t size_ = 0;
  void* mapping_ = nullptr;
  std::size_t pos_ = 0;
  bool have_previous_number_ = false;
  std::int64_t previous_number_ = 0;
  ReadReport report_;
};

}  // namespace visco::replay

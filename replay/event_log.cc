#include "replay/event_log.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>

#include "common/error.h"

namespace visco::replay {
namespace {

void PutBe32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(static_cast<std::uint8_t>(v >> shift));
}
void PutBe64(std::vector<std::uint8_t>& out, std::uint64_t v) {
  for (int shift = 56; shift >= 0; shift -= 8) out.push_back(static_cast<std::uint8_t>(v >> shift));
}

std::string Hex(std::int64_t v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "0x%llx", static_cast<unsigned long long>(v));
  return buffer;
}

}  // namespace

void AppendEvent(std::vector<std::uint8_t>& out, std::int64_t number, std::int64_t timestamp, std::string_view channel,
                 std::span<const std::uint8_t> data) {
  out.reserve(out.size() + kHeaderBytes + channel.size() + data.size());
  PutBe32(out, kSyncWord);
  PutBe64(out, static_cast<std::uint64_t>(number));
  PutBe64(out, static_cast<std::uint64_t>(timestamp));
  PutBe32(out, static_cast<std::uint32_t>(channel.size()));
  PutBe32(out, static_cast<std::uint32_t>(data.size()));
  out.insert(out.end(), channel.begin(), channel.end());
  out.insert(out.end(), data.begin(), data.end());
}

// ---------------------------------------------------------------------------------------------------------------
// Writer

EventLogWriter::EventLogWriter(const std::string& path, const WriterOptions& options) : path_(path), options_(options) {
  file_ = std::fopen(path.c_str(), "wb");
  if (file_ == nullptr) {
    throw InputError(path, "", std::string("cannot create the event log: ") + std::strerror(errno));
  }
  thread_ = std::thread([this] { Run(); });
}

EventLogWriter::~EventLogWriter() { Close(); }

bool EventLogWriter::Write(std::string_view channel, std::int64_t timestamp, std::span<const std::uint8_t> data) {
  const std::size_t bytes = kHeaderBytes + channel.size() + data.size();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (closing_ || queued_bytes_ + bytes > options_.max_queue_bytes) {
      ++stats_.events_dropped;
      stats_.bytes_dropped += bytes;
      return false;
    }
    queue_.push_back(Pending{std::string(channel), timestamp, std::vector<std::uint8_t>(data.begin(), data.end())});
    queued_bytes_ += bytes;
  }
  wake_.notify_one();
  return true;
}

void EventLogWriter::Run() {
  using Clock = std::chrono::steady_clock;
  const auto interval = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(options_.flush_interval_s > 0 ? options_.flush_interval_s : 0.1));
  auto last_flush = Clock::now();
  std::deque<Pending> batch;
  std::vector<std::uint8_t> buffer;
  bool dirty = false;
  for (;;) {
    bool closing = false;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait_for(lock, interval, [this] { return closing_ || !queue_.empty(); });
      batch.swap(queue_);
      queued_bytes_ = 0;
      closing = closing_;
    }
    for (Pending& p : batch) {
      buffer.clear();
      AppendEvent(buffer, next_number_, p.timestamp, p.channel, p.data);
      const bool ok = stats_.error.empty() && std::fwrite(buffer.data(), 1, buffer.size(), file_) == buffer.size();
      std::lock_guard<std::mutex> lock(mutex_);
      if (ok) {
        ++next_number_;
        ++stats_.events_written;
        stats_.bytes_written += buffer.size();
        dirty = true;
      } else {
        if (stats_.error.empty()) stats_.error = std::string("write failed: ") + std::strerror(errno);
        ++stats_.events_dropped;
        stats_.bytes_dropped += buffer.size();
      }
    }
    batch.clear();
    // Periodic flush: a process killed with SIGKILL loses at most the last interval (the kernel keeps what was
    // flushed; an fsync, which this does not do, would be needed against power loss).
    if (dirty && (closing || Clock::now() - last_flush >= interval)) {
      std::fflush(file_);
      last_flush = Clock::now();
      dirty = false;
    }
    if (closing) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (queue_.empty()) return;
    }
  }
}

WriterStats EventLogWriter::Close() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (closed_) return stats_;
    closing_ = true;
  }
  wake_.notify_one();
  if (thread_.joinable()) thread_.join();
  std::lock_guard<std::mutex> lock(mutex_);
  if (file_ != nullptr) {
    if (std::fclose(file_) != 0 && stats_.error.empty()) stats_.error = std::string("close failed: ") + strerror(errno);
    file_ = nullptr;
  }
  closed_ = true;
  return stats_;
}

WriterStats EventLogWriter::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

// ---------------------------------------------------------------------------------------------------------------
// Reader

namespace {

std::uint32_t Be32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | std::uint32_t{p[3]};
}
std::uint64_t Be64(const std::uint8_t* p) { return (std::uint64_t{Be32(p)} << 32) | Be32(p + 4); }

bool PrintableChannel(const std::uint8_t* p, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    if (p[i] < 0x21 || p[i] > 0x7e) return false;
  }
  return true;
}

}  // namespace

EventLogReader::EventLogReader(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw InputError(path, "", std::string("cannot open the event log: ") + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw InputError(path, "", "is not a regular file");
  }
  size_ = static_cast<std::size_t>(st.st_size);
  if (size_ > 0) {
    mapping_ = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd, 0);
    if (mapping_ == MAP_FAILED) {
      mapping_ = nullptr;
      ::close(fd);
      throw InputError(path, "", std::string("cannot map the event log: ") + std::strerror(errno));
    }
    bytes_ = static_cast<const std::uint8_t*>(mapping_);
  }
  ::close(fd);
  report_.file_bytes = static_cast<std::int64_t>(size_);
}

EventLogReader::EventLogReader(std::span<const std::uint8_t> bytes) : bytes_(bytes.data()), size_(bytes.size()) {
  report_.file_bytes = static_cast<std::int64_t>(size_);
}

EventLogReader::~EventLogReader() {
  if (mapping_ != nullptr) ::munmap(mapping_, size_);
}

void EventLogReader::Rewind() {
  pos_ = 0;
  have_previous_number_ = false;
  previous_number_ = 0;
  report_ = ReadReport{};
  report_.file_bytes = static_cast<std::int64_t>(size_);
}

std::size_t EventLogReader::FindSync(std::size_t from) const {
  std::size_t pos = from;
  while (pos + 4 <= size_) {
    const void* hit = std::memchr(bytes_ + pos, 0xED, size_ - pos - 3);
    if (hit == nullptr) break;
    pos = static_cast<std::size_t>(static_cast<const std::uint8_t*>(hit) - bytes_);
    if (Be32(bytes_ + pos) == kSyncWord) return pos;
    ++pos;
  }
  return size_;
}

bool EventLogReader::PlausibleHeader(std::size_t pos, std::size_t& total) const {
  if (pos + kHeaderBytes > size_ || Be32(bytes_ + pos) != kSyncWord) return false;
  const auto channel = static_cast<std::int32_t>(Be32(bytes_ + pos + 20));
  const auto data = static_cast<std::int32_t>(Be32(bytes_ + pos + 24));
  if (channel < 1 || channel > kMaxChannelBytes || data < 0 || data > kMaxDataBytes) return false;
  total = kHeaderBytes + static_cast<std::size_t>(channel) + static_cast<std::size_t>(data);
  if (total > size_ - pos) return false;
  return PrintableChannel(bytes_ + pos + kHeaderBytes, static_cast<std::size_t>(channel));
}

void EventLogReader::Skip(std::size_t from, std::size_t to, std::string reason) {
  if (to <= from) return;
  const auto bytes = static_cast<std::int64_t>(to - from);
  report_.skipped_bytes += bytes;
  if (!report_.skipped.empty()) {
    SkippedRange& last = report_.skipped.back();
    if (last.offset + last.bytes == static_cast<std::int64_t>(from)) {
      last.bytes += bytes;  // contiguous with the previous range: one range, its first reason
      return;
    }
  }
  ++report_.skipped_ranges;
  if (report_.skipped.size() < 100) {
    report_.skipped.push_back({static_cast<std::int64_t>(from), bytes, std::move(reason)});
  }
}

bool EventLogReader::Next(LogEvent& event) {
  while (pos_ < size_) {
    const std::size_t rest = size_ - pos_;
    if (rest < 4) {
      Skip(pos_, size_, std::to_string(rest) + " stray byte(s) at the end of the file");
      report_.truncated_tail = true;
      pos_ = size_;
      break;
    }
    if (Be32(bytes_ + pos_) != kSyncWord) {
      const std::size_t next = FindSync(pos_ + 1);
      Skip(pos_, next,
           next == size_ ? "no sync word (0xEDA1DA01) from here to the end of the file"
                         : "no sync word (0xEDA1DA01) where an event should start (found " + Hex(Be32(bytes_ + pos_)) +
                               "); resynchronised on the next one");
      pos_ = next;
      continue;
    }
    if (rest < kHeaderBytes) {
      Skip(pos_, size_,
           "event header cut off by the end of the file (" + std::to_string(rest) + " of " +
               std::to_string(kHeaderBytes) + " bytes)");
      report_.truncated_tail = true;
      pos_ = size_;
      break;
    }
    const auto channel_bytes = static_cast<std::int32_t>(Be32(bytes_ + pos_ + 20));
    const auto data_bytes = static_cast<std::int32_t>(Be32(bytes_ + pos_ + 24));
    if (channel_bytes < 1 || channel_bytes > kMaxChannelBytes || data_bytes < 0 || data_bytes > kMaxDataBytes) {
      const std::size_t next = FindSync(pos_ + 1);
      Skip(pos_, next,
           "event header with impossible lengths (channel " + std::to_string(channel_bytes) + ", data " +
               std::to_string(data_bytes) + " bytes); resynchronised on the next sync word");
      pos_ = next;
      continue;
    }
    const std::size_t total =
        kHeaderBytes + static_cast<std::size_t>(channel_bytes) + static_cast<std::size_t>(data_bytes);
    if (total > rest) {
      const std::size_t next = FindSync(pos_ + 1);
      if (next == size_) {
        Skip(pos_, size_,
             "event cut off by the end of the file (" + std::to_string(total) + " bytes, " + std::to_string(rest) +
                 " left)");
        report_.truncated_tail = true;
        pos_ = size_;
        break;
      }
      Skip(pos_, next,
           "event length (" + std::to_string(total) + " bytes) runs past the end of the file (" + std::to_string(rest) +
               " left): corrupt header; resynchronised on the next sync word");
      pos_ = next;
      continue;
    }
    if (!PrintableChannel(bytes_ + pos_ + kHeaderBytes, static_cast<std::size_t>(channel_bytes))) {
      const std::size_t next = FindSync(pos_ + 1);
      Skip(pos_, next, "channel name is not printable ASCII: corrupt event; resynchronised on the next sync word");
      pos_ = next;
      continue;
    }
    const std::size_t end = pos_ + total;
    // The next event must start where this one ends. If it does not, and a plausible event starts inside this one,
    // this event's length field is what is damaged: skip to that event. Otherwise the damage is after this event.
    // Even when it does, a chain of plausible events inside this one that ends exactly where it ends means a damaged
    // length swallowed them (a payload holding whole events that end where it ends does not occur in practice).
    const bool next_is_event = end == size_ || (end + 4 <= size_ && Be32(bytes_ + end) == kSyncWord);
    std::size_t inner = end;  // where to resynchronise: the first plausible event inside, if this one is corrupt
    std::size_t first_plausible = end;
    std::size_t inner_total = 0;
    for (std::size_t candidate = FindSync(pos_ + 1); candidate < end; candidate = FindSync(candidate + 1)) {
      if (!PlausibleHeader(candidate, inner_total)) continue;
      if (first_plausible == end) first_plausible = candidate;
      if (!next_is_event) {
        inner = first_plausible;
        break;
      }
      std::size_t chain = candidate;
      std::size_t step = 0;
      while (chain < end && PlausibleHeader(chain, step)) chain += step;
      if (chain == end) {
        inner = first_plausible;
        break;
      }
    }
    if (inner < end) {
      Skip(pos_, inner,
           next_is_event ? "event length covers whole events after it: corrupt header; resynchronised"
                         : "event length inconsistent with the following data (no sync word at its end, an event "
                           "inside it): corrupt header; resynchronised");
      pos_ = inner;
      continue;
    }
    event.offset = static_cast<std::int64_t>(pos_);
    event.number = static_cast<std::int64_t>(Be64(bytes_ + pos_ + 4));
    event.timestamp = static_cast<std::int64_t>(Be64(bytes_ + pos_ + 12));
    event.channel = std::string_view(reinterpret_cast<const char*>(bytes_ + pos_ + kHeaderBytes),
                                     static_cast<std::size_t>(channel_bytes));
    event.data = std::span<const std::uint8_t>(bytes_ + pos_ + kHeaderBytes + channel_bytes,
                                               static_cast<std::size_t>(data_bytes));
    // Damaged numbers can be anything: no signed overflow in the bookkeeping.
    std::int64_t step = 0;
    const bool overflow = __builtin_sub_overflow(event.number, previous_number_, &step);
    if (have_previous_number_ && (overflow || step != 1)) {
      ++report_.number_gaps;
      if (!overflow && step > 1 && !__builtin_add_overflow(report_.missing_numbers, step - 1, &step)) {
        report_.missing_numbers = step;
      }
    }
    have_previous_number_ = true;
    previous_number_ = event.number;
    ++report_.events;
    report_.event_bytes += static_cast<std::int64_t>(total);
    pos_ = end;
    return true;
  }
  return false;
}

std::string ReadReport::Describe(std::size_t max_ranges) const {
  std::string s = std::to_string(events) + " event(s) in " + std::to_string(file_bytes) + " bytes";
  if (skipped_ranges == 0) {
    s += "; nothing skipped";
  } else {
    s += "; skipped " + std::to_string(skipped_bytes) + " byte(s) in " + std::to_string(skipped_ranges) + " range(s)";
    if (truncated_tail) s += " (the file ends in a cut-off event)";
    s += ":";
    for (std::size_t i = 0; i < skipped.size() && i < max_ranges; ++i) {
      s += "\n  at byte " + std::to_string(skipped[i].offset) + ", " + std::to_string(skipped[i].bytes) +
           " byte(s): " + skipped[i].reason;
    }
    if (static_cast<std::int64_t>(max_ranges) < skipped_ranges) {
      s += "\n  ... " + std::to_string(skipped_ranges - static_cast<std::int64_t>(max_ranges)) + " more";
    }
  }
  if (number_gaps > 0) {
    s += "\n  event numbers jump " + std::to_string(number_gaps) + " time(s) (" + std::to_string(missing_numbers) +
         " event(s) missing by their numbers: lost by the writer or in a skipped range)";
  }
  return s;
}

}  // namespace visco::replay

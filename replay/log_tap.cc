#include "replay/log_tap.h"

#include <atomic>
#include <cstdlib>
#include <lcm/lcm-cpp.hpp>
#include <thread>

#include "common/error.h"

namespace visco::replay {
namespace {

// What a log writer says when it closes: events and bytes written, events dropped, the error if any.
std::string Report(const std::string& path, const WriterStats& s) {
  return "event log " + path + ": " + std::to_string(s.events_written) + " event(s), " +
         std::to_string(s.bytes_written) + " bytes written; " + std::to_string(s.events_dropped) + " dropped" +
         (s.error.empty() ? "" : " (" + s.error + ")");
}

class LcmEventLogTap : public EventLogTap {
 public:
  LcmEventLogTap(const std::string& path, const std::string& url) : url_(TapUrl(url)), lcm_(url_), writer_(path) {
    if (!lcm_.good()) {
      writer_.Close();
      throw InputError("command line", "--log", "cannot open the LCM bus '" + url_ + "' to record it");
    }
    // LCM queues 30 messages per subscription by default and drops the rest without a word; the handler only
    // copies, so a deep queue costs nothing unless the writer falls behind.
    lcm_.subscribeFunction(".*", &LcmEventLogTap::Handle, this)->setQueueCapacity(10000);
    thread_ = std::thread([this] {
      while (running_.load(std::memory_order_acquire)) lcm_.handleTimeout(20);
    });
  }
  ~LcmEventLogTap() override { Close(); }

  bool Write(const std::string& channel, std::int64_t timestamp, const std::uint8_t* data, std::size_t size) override {
    return writer_.Write(channel, timestamp, std::span<const std::uint8_t>(data, size));
  }

  std::string Close() override {
    if (running_.exchange(false)) {
      if (thread_.joinable()) thread_.join();
      // What the process published last may still be on its way through the loopback: take everything that
      // arrives until the bus has been quiet for 50 ms (at most 1 s).
      for (int i = 0; i < 100 && lcm_.handleTimeout(50) > 0; ++i) {
      }
      const WriterStats s = writer_.Close();
      report_ = Report(writer_.path(), s);
    }
    return report_;
  }

 private:
  static void Handle(const lcm::ReceiveBuffer* rbuf, const std::string& channel, LcmEventLogTap* self) {
    self->writer_.Write(channel, rbuf->recv_utime,
                        std::span<const std::uint8_t>(static_cast<const std::uint8_t*>(rbuf->data), rbuf->data_size));
  }

  std::string url_;
  lcm::LCM lcm_;
  EventLogWriter writer_;
  std::atomic<bool> running_{true};
  std::thread thread_;
  std::string report_;
};

// A log of no bus: what the process writes itself (a lockstep simulation's messages, on its simulated clock). The
// writer's thread only writes the file, in the order of the Write calls.
class FileEventLog : public EventLogTap {
 public:
  explicit FileEventLog(const std::string& path) : writer_(path, Options()) {}
  ~FileEventLog() override { Close(); }
  bool Write(const std::string& channel, std::int64_t timestamp, const std::uint8_t* data, std::size_t size) override {
    return writer_.Write(channel, timestamp, std::span<const std::uint8_t>(data, size));
  }
  std::string Close() override {
    if (report_.empty()) {
      const WriterStats s = writer_.Close();
      report_ = Report(writer_.path(), s);
    }
    return report_;
  }

 private:
  static WriterOptions Options() {
    WriterOptions o;
    o.max_queue_bytes = std::size_t{1} << 30;  // the producer is not real-time: room rather than drops
    return o;
  }
  EventLogWriter writer_;
  std::string report_;
};

}  // namespace

std::unique_ptr<EventLogTap> OpenFileEventLog(const std::string& path) { return std::make_unique<FileEventLog>(path); }

std::string TapUrl(const std::string& lcm_url) {
  std::string url = lcm_url;
  if (url.empty()) {
    const char* env = std::getenv("LCM_DEFAULT_URL");
    url = env != nullptr && env[0] != '\0' ? env : "udpm://239.255.76.67:7667?ttl=0";
  }
  if (url.rfind("udpm://", 0) == 0 && url.find("recv_buf_size") == std::string::npos) {
    url += (url.find('?') == std::string::npos ? "?" : "&");
    url += "recv_buf_size=8388608";
  }
  return url;
}

std::unique_ptr<EventLogTap> OpenLcmEventLog(const std::string& path, const std::string& lcm_url) {
  return std::make_unique<LcmEventLogTap>(path, lcm_url);
}

void InstallEventLog() {
  InstalledEventLogOpener() = &OpenLcmEventLog;
  InstalledEventLogFileOpener() = &OpenFileEventLog;
}

}  // namespace visco::replay

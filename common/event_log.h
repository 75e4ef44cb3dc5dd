#pragma once
// The seam through which a process writes an LCM event log (`--log FILE`) without depending on the library that
// implements it: the processes (`visco run`, `sim`, `track`, `driver`) live in control/, vision/ and drivers/, the
// log format in replay/, which sits above them. The program (app/) installs replay's implementation at start-up;
// a program that installs none (visco-rt) refuses `--log` with a clear message.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "common/error.h"

namespace visco {

/// A running event log: it records every message on the process's LCM bus until closed.
class EventLogTap {
 public:
  virtual ~EventLogTap() = default;
  /// Stops recording, writes what is queued and closes the file. Returns the one-line report (events written,
  /// dropped, errors) for the process's log. Idempotent. Not real-time safe.
  virtual std::string Close() = 0;
  /// Adds an event that is not on the bus (e.g. the controller's per-period records); `timestamp` in microseconds
  /// since the epoch. Returns false if it was dropped (counted in the report). Thread-safe; not real-time safe.
  virtual bool Write(const std::string& channel, std::int64_t timestamp, const std::uint8_t* data,
                     std::size_t size) = 0;
};

/// Opens a log at `path` recording the LCM bus `lcm_url` ("" = LCM's default). @throws InputError.
using EventLogOpener = std::unique_ptr<EventLogTap> (*)(const std::string& path, const std::string& lcm_url);

/// The installed opener (null until the program installs one). Not thread-safe: set it before any command runs.
inline EventLogOpener& InstalledEventLogOpener() {
  static EventLogOpener opener = nullptr;
  return opener;
}

/// Opens a log at `path` that records no bus: only what is written to it with EventLogTap::Write (a lockstep
/// simulation logs its own bus, stamped with its simulated clock). @throws InputError.
using EventLogFileOpener = std::unique_ptr<EventLogTap> (*)(const std::string& path);

/// The installed file-only opener (null until the program installs one). Set it before any command runs.
inline EventLogFileOpener& InstalledEventLogFileOpener() {
  static EventLogFileOpener opener = nullptr;
  return opener;
}

/// Opens a file-only event log with the installed implementation, or returns null when `path` is empty.
/// @throws InputError if `path` is given but this program cannot write logs, or the log cannot be created.
inline std::unique_ptr<EventLogTap> OpenEventLogFile(const std::string& path) {
  if (path.empty()) return nullptr;
  if (InstalledEventLogFileOpener() == nullptr) {
    throw InputError("command line", "--log", "this program cannot write event logs (use `visco`, not `visco-rt`)");
  }
  return InstalledEventLogFileOpener()(path);
}

/// Opens an event log with the installed implementation, or returns null when `path` is empty.
/// @throws InputError if `path` is given but this program cannot write logs, or the log cannot be created.
inline std::unique_ptr<EventLogTap> OpenEventLog(const std::string& path, const std::string& lcm_url) {
  if (path.empty()) return nullptr;
  if (InstalledEventLogOpener() == nullptr) {
    throw InputError("command line", "--log", "this program cannot write event logs (use `visco`, not `visco-rt`)");
  }
  return InstalledEventLogOpener()(path, lcm_url);
}

}  // namespace visco

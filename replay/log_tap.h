#pragma once
// `--log FILE` of visco's processes: an in-process lcm-logger. It opens its own LCM instance on the process's bus,
// subscribes to every channel and hands each message, stamped with LCM's receive time, to an EventLogWriter, whose
// thread writes the file. Nothing of it runs on a real-time thread. On a UDP multicast bus the process hears its
// own publications (multicast loopback) as well as everything it receives, so the log holds every channel the
// process publishes and receives (and whatever else shares the bus). memq:// buses are private to one LCM instance:
// a tap on them hears nothing, so the processes' --log needs a udpm:// bus.

#include <memory>
#include <string>

#include "common/event_log.h"
#include "replay/event_log.h"

namespace visco::replay {

/// Adds `recv_buf_size` to a udpm:// URL that has none (an image_t frame is larger than the kernel's default UDP
/// receive buffer) and resolves "" to LCM_DEFAULT_URL or LCM's default. Other URLs are returned unchanged.
std::string TapUrl(const std::string& lcm_url);

/// Starts a tap. @throws InputError if the file cannot be created or the bus cannot be opened.
std::unique_ptr<EventLogTap> OpenLcmEventLog(const std::string& path, const std::string& lcm_url);

/// Starts a log of no bus (EventLogTap::Write only). @throws InputError if the file cannot be created.
std::unique_ptr<EventLogTap> OpenFileEventLog(const std::string& path);

/// Installs OpenLcmEventLog and OpenFileEventLog as the program's event log implementation (common/event_log.h).
void InstallEventLog();

}  // namespace visco::replay

#pragma once
// A raw SocketCAN socket (CAN_RAW) with what a robot link needs: kernel-side id filters (CAN_RAW_FILTER), error
// frames (CAN_RAW_ERR_FILTER), drop counting (SO_RXQ_OVFL), receive timestamps (SO_TIMESTAMP), non-blocking I/O,
// and a send-only mode that receives nothing. Linux headers stay in socketcan.cc.

#include <cstdint>
#include <string>
#include <vector>

#include "drivers/can_protocol.h"

namespace visco::drivers {

/// One kernel receive filter: a frame passes if (frame.id & mask) == (id & mask) (SocketCAN semantics).
struct CanFilter {
  std::uint32_t id = 0;
  std::uint32_t mask = 0;
};

struct CanSocketOptions {
  std::string interface;           // e.g. "vcan0"
  bool receive = true;             // false: a send-only socket (empty filter list, smallest receive buffer)
  std::vector<CanFilter> filters;  // ignored when receive is false; empty = receive every data frame
  std::uint32_t error_mask = 0;    // CAN_ERR_* classes to receive as error frames (0 = none)
  int receive_buffer_bytes = 0;    // SO_RCVBUF, 0 = the kernel's default
};

/// Result of one socket operation (real-time calls never throw).
enum class CanIo : std::uint8_t {
  kOk = 0,
  kWouldBlock,  // nothing to read / transmit queue full (EAGAIN, ENOBUFS)
  kNetDown,     // the interface is down (ENETDOWN, ENXIO, ENODEV)
  kError,       // another errno (see CanSocket::last_errno())
};

/// A received frame with its kernel timestamp.
struct ReceivedFrame {
  can::Frame frame;
  std::int64_t utime = 0;  // SO_TIMESTAMP: wall-clock microseconds when the kernel received it
};

/// What a CAN link reads and writes: a CanSocket, or frames in memory (tests and fuzzers on machines without CAN).
/// All three calls are real-time safe and never block.
class CanPort {
 public:
  virtual ~CanPort() = default;
  virtual CanIo Write(const can::Frame& frame) = 0;
  virtual CanIo Read(ReceivedFrame& out) = 0;
  /// Frames dropped before they could be read since the port was opened (the kernel's SO_RXQ_OVFL count).
  virtual std::uint32_t dropped() const = 0;
};

class CanSocket final : public CanPort {
 public:
  /// Opens, configures and binds a raw CAN socket. Not real-time safe.
  /// @throws visco::JobFailed naming the interface and the failing call with its errno text (e.g. when AF_CAN is
  /// not supported by the kernel or the interface does not exist).
  explicit CanSocket(const CanSocketOptions& options);
  ~CanSocket() override;
  CanSocket(const CanSocket&) = delete;
  CanSocket& operator=(const CanSocket&) = delete;

  /// Writes one frame without blocking. Real-time safe.
  CanIo Write(const can::Frame& frame) override;
  /// Reads one frame without blocking (kWouldBlock when none is queued). Updates dropped(). Real-time safe.
  CanIo Read(ReceivedFrame& out) override;
  /// Waits up to `timeout_us` for a frame to read (poll(2)); true if one is ready. Blocking: not for the
  /// controller's loop.
  bool WaitReadable(std::int64_t timeout_us);

  /// Frames the kernel dropped for this socket since it was opened (SO_RXQ_OVFL; the newest count seen).
  std::uint32_t dropped() const override { return dropped_; }
  int last_errno() const { return last_errno_; }
  int fd() const { return fd_; }
  const std::string& interface() const { return interface_; }

 private:
  int fd_ = -1;
  std::string interface_;
  std::uint32_t dropped_ = 0;
  int last_errno_ = 0;
};

/// The SocketCAN error classes a link listens to: bus-off, restarted, controller problems (passive/warning/
/// overflow), tx timeout, protocol and bus errors, no-ack.
std::uint32_t DefaultErrorMask();

}  // namespace visco::drivers

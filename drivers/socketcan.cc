#include "drivers/socketcan.h"

#include <errno.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cstring>

#include "common/error.h"

namespace visco::drivers {

static_assert(can::kEffFlag == CAN_EFF_FLAG && can::kRtrFlag == CAN_RTR_FLAG && can::kErrFlag == CAN_ERR_FLAG);
static_assert(can::kErrBusOff == CAN_ERR_BUSOFF && can::kErrRestarted == CAN_ERR_RESTARTED &&
              can::kErrCrtl == CAN_ERR_CRTL && can::kErrProt == CAN_ERR_PROT && can::kErrAck == CAN_ERR_ACK &&
              can::kErrTxTimeout == CAN_ERR_TX_TIMEOUT && can::kErrLostArb == CAN_ERR_LOSTARB &&
              can::kErrTrx == CAN_ERR_TRX && can::kErrBusError == CAN_ERR_BUSERROR);
static_assert(can::kCrtlRxPassive == CAN_ERR_CRTL_RX_PASSIVE && can::kCrtlTxPassive == CAN_ERR_CRTL_TX_PASSIVE &&
              can::kCrtlRxWarning == CAN_ERR_CRTL_RX_WARNING && can::kCrtlTxWarning == CAN_ERR_CRTL_TX_WARNING &&
              can::kCrtlActive == CAN_ERR_CRTL_ACTIVE && can::kCrtlRxOverflow == CAN_ERR_CRTL_RX_OVERFLOW);

namespace {

[[noreturn]] void Fail(const std::string& interface, const char* call, int error) {
  throw JobFailed("CAN interface '" + interface + "': " + call + ": " + std::strerror(error));
}

CanIo Classify(int error) {
  switch (error) {
    case EAGAIN:
    case ENOBUFS:
      return CanIo::kWouldBlock;
    case ENETDOWN:
    case ENXIO:
    case ENODEV:
      return CanIo::kNetDown;
    default:
      return CanIo::kError;
  }
}

}  // namespace

std::uint32_t DefaultErrorMask() {
  return CAN_ERR_TX_TIMEOUT | CAN_ERR_CRTL | CAN_ERR_PROT | CAN_ERR_TRX | CAN_ERR_ACK | CAN_ERR_BUSOFF |
         CAN_ERR_BUSERROR | CAN_ERR_RESTARTED;
}

CanSocket::CanSocket(const CanSocketOptions& options) : interface_(options.interface) {
  if (options.interface.empty() || options.interface.size() >= IFNAMSIZ) {
    throw InputError("command line", "--can", "'" + options.interface + "' is not a network interface name");
  }
  fd_ = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd_ < 0) Fail(interface_, "socket(PF_CAN, SOCK_RAW, CAN_RAW)", errno);
  try {
    if (!options.receive) {
      // A send-only socket: no filter matches, so the kernel never queues a frame for it.
      if (setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, nullptr, 0) != 0) Fail(interface_, "CAN_RAW_FILTER", errno);
      const int small = 0;  // the kernel rounds up to its minimum
      setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &small, sizeof(small));
    } else {
      if (!options.filters.empty()) {
        std::vector<can_filter> filters;
        for (const CanFilter& f : options.filters) filters.push_back(can_filter{f.id, f.mask});
        if (setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, filters.data(),
                       static_cast<socklen_t>(filters.size() * sizeof(can_filter))) != 0) {
          Fail(interface_, "CAN_RAW_FILTER", errno);
        }
      }
      const can_err_mask_t mask = options.error_mask;
      if (setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &mask, sizeof(mask)) != 0) {
        Fail(interface_, "CAN_RAW_ERR_FILTER", errno);
      }
      const int on = 1;
      if (setsockopt(fd_, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof(on)) != 0) Fail(interface_, "SO_RXQ_OVFL", errno);
      if (setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMP, &on, sizeof(on)) != 0) Fail(interface_, "SO_TIMESTAMP", errno);
      if (options.receive_buffer_bytes > 0) {
        setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &options.receive_buffer_bytes, sizeof(options.receive_buffer_bytes));
      }
    }
    ifreq ifr{};
    std::strncpy(ifr.ifr_name, interface_.c_str(), IFNAMSIZ - 1);
    if (ioctl(fd_, SIOCGIFINDEX, &ifr) != 0) Fail(interface_, "no such interface (SIOCGIFINDEX)", errno);
    sockaddr_can addr{};
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifr.ifr_ifindex;
    if (bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) Fail(interface_, "bind", errno);
  } catch (...) {
    close(fd_);
    fd_ = -1;
    throw;
  }
}

CanSocket::~CanSocket() {
  if (fd_ >= 0) close(fd_);
}

CanIo CanSocket::Write(const can::Frame& frame) {
  can_frame out{};
  out.can_id = frame.id;
  out.len = frame.dlc > 8 ? 8 : frame.dlc;
  std::memcpy(out.data, frame.data, 8);
  const ssize_t n = write(fd_, &out, sizeof(out));
  if (n == static_cast<ssize_t>(sizeof(out))) return CanIo::kOk;
  last_errno_ = n < 0 ? errno : EIO;
  return Classify(last_errno_);
}

CanIo CanSocket::Read(ReceivedFrame& out) {
  can_frame in{};
  iovec iov{&in, sizeof(in)};
  // Room for SO_TIMESTAMP (struct timeval) and SO_RXQ_OVFL (uint32) control messages, on the stack.
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timeval)) + CMSG_SPACE(sizeof(std::uint32_t)) + 64];
  msghdr msg{};
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  msg.msg_control = control;
  msg.msg_controllen = sizeof(control);
  const ssize_t n = recvmsg(fd_, &msg, MSG_DONTWAIT);
  if (n < 0) {
    last_errno_ = errno;
    return Classify(last_errno_);
  }
  if (n != static_cast<ssize_t>(sizeof(in))) {
    last_errno_ = EMSGSIZE;  // a CAN FD frame on a classic socket cannot happen; treat as an error
    return CanIo::kError;
  }
  out.utime = 0;
  for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
    if (c->cmsg_level != SOL_SOCKET) continue;
    if (c->cmsg_type == SO_TIMESTAMP) {
      timeval tv{};
      std::memcpy(&tv, CMSG_DATA(c), sizeof(tv));
      out.utime = static_cast<std::int64_t>(tv.tv_sec) * 1'000'000 + tv.tv_usec;
    } else if (c->cmsg_type == SO_RXQ_OVFL) {
      std::memcpy(&dropped_, CMSG_DATA(c), sizeof(dropped_));
    }
  }
  out.frame.id = in.can_id;
  out.frame.dlc = in.len > 8 ? 8 : in.len;
  std::memcpy(out.frame.data, in.data, 8);
  return CanIo::kOk;
}

bool CanSocket::WaitReadable(std::int64_t timeout_us) {
  pollfd p{fd_, POLLIN, 0};
  timespec ts{static_cast<time_t>(timeout_us / 1'000'000), static_cast<long>((timeout_us % 1'000'000) * 1000)};
  return ppoll(&p, 1, timeout_us < 0 ? nullptr : &ts, nullptr) > 0 && (p.revents & (POLLIN | POLLERR)) != 0;
}

}  // namespace visco::drivers

#pragma once
// A CanPort in memory for tests and fuzzers of the controller's CAN link on machines without CAN: the frames a test
// queues are read one at a time, and the frames the link writes are kept.

#include <deque>
#include <vector>

#include "drivers/can_protocol.h"
#include "drivers/socketcan.h"

namespace visco::drivers::testing {

class MemoryPort final : public CanPort {
 public:
  CanIo Write(const can::Frame& frame) override {
    written.push_back(frame);
    return CanIo::kOk;
  }
  CanIo Read(ReceivedFrame& out) override {
    if (queue.empty()) return CanIo::kWouldBlock;
    out = queue.front();
    queue.pop_front();
    return CanIo::kOk;
  }
  std::uint32_t dropped() const override { return 0; }
  std::deque<ReceivedFrame> queue;  // read next
  std::vector<can::Frame> written;  // what the link wrote
};

}  // namespace visco::drivers::testing

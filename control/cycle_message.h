#pragma once
// The codec of the controller's period records: control::CycleRecord <-> controller_cycle_t, the message `visco run
// --log` and lockstep runs write on VISCO_CONTROLLER_CYCLE and `visco replay` reads back. Writer and reader use these
// two functions, so the record and its message cannot drift apart (tests/control/message_codec_test.cc: round trips
// on seeded random values). Not real-time safe (the message's arrays allocate): records are encoded on the logger's
// side of the loop's queue.

#include "control/control_loop.h"
#include "visco/controller_cycle_t.hpp"

namespace visco::control {

/// One period's record as the log's message: the executor's inputs, its command, mode, step and hold.
controller_cycle_t ToCycleMessage(const CycleRecord& record);

/// The record back from the message. What the message does not carry is what the loop would have: the command's
/// `utime` is the period's (the executor stamps its command so), its `seq` is 0 (not recorded). A message with more
/// observations than a frame holds keeps the first kMaxVisualObservations.
CycleRecord FromCycleMessage(const controller_cycle_t& message);

}  // namespace visco::control

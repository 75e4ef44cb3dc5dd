#pragma once
// The codec of the controller's faults: control::FaultEvent <-> fault_t (source "controller"), the message the
// controller's bridge publishes on VISCO_FAULT and `visco replay` produces and compares. Writer and reader use these
// two functions, so they cannot drift apart (tests/control/message_codec_test.cc). Not real-time safe (the message's
// strings allocate): the loop hands FaultEvents over through its outbox and the bridge encodes them.

#include "control/executor.h"
#include "visco/fault_t.hpp"

namespace visco::control {

/// The source name of the controller's faults in fault_t.
inline constexpr char kControllerFaultSource[] = "controller";

/// The fault as the controller publishes it: source "controller", no EMCY code, no driver fault bits.
fault_t ToFaultMessage(const FaultEvent& fault);

/// The fault back from a message (of any source: the source, EMCY code and fault bits are not FaultEvent's). A
/// message longer than FaultEvent::message is cut.
FaultEvent FromFaultMessage(const fault_t& message);

}  // namespace visco::control

#include "control/fault_message.h"

namespace visco::control {

fault_t ToFaultMessage(const FaultEvent& fault) {
  fault_t m{};
  m.utime = fault.utime;
  m.source = kControllerFaultSource;
  m.code = static_cast<std::int32_t>(fault.code);
  m.severity = fault.severity;
  m.robot_stopped = fault.robot_stopped;
  m.cleared = fault.cleared;
  m.message = fault.message;
  return m;
}

FaultEvent FromFaultMessage(const fault_t& m) {
  FaultEvent fault;
  fault.utime = m.utime;
  fault.code = static_cast<FaultCode>(m.code);
  fault.severity = m.severity;
  fault.robot_stopped = m.robot_stopped;
  fault.cleared = m.cleared;
  CopyText(fault.message, m.message.c_str());
  return fault;
}

}  // namespace visco::control

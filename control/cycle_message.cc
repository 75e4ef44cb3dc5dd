#include "control/cycle_message.h"

#include <algorithm>
#include <cstddef>

namespace visco::control {

controller_cycle_t ToCycleMessage(const CycleRecord& r) {
  controller_cycle_t m{};
  const ExecutorInput& in = r.input;
  m.utime = in.now_utime;
  m.now_ns = in.now_ns;
  m.cycle = r.cycle;
  m.have_status = in.have_status;
  m.status_receive_ns = in.status.receive_ns;
  m.status_utime = in.status.utime;
  m.status_seq = in.status.seq;
  m.status_command_seq = in.status.command_seq;
  m.status_position[0] = in.status.position.x, m.status_position[1] = in.status.position.y;
  m.status_velocity[0] = in.status.velocity.x, m.status_velocity[1] = in.status.velocity.y;
  m.status_contact = in.status.contact;
  m.status_contact_force[0] = in.status.contact_force.x, m.status_contact_force[1] = in.status.contact_force.y;
  m.status_state = in.status.state;
  m.status_fault_bits = in.status.fault_bits;
  m.heartbeat_ns = in.heartbeat_ns;
  m.peer_lost = in.peer_lost;
  m.link_fault_code = in.link_fault_code;
  m.link_fault = in.link_fault;
  m.have_frame = in.have_frame;
  m.frame_capture_ns = in.frame.capture_ns;
  m.frame_seq = in.frame.frame_seq;
  m.num_observations = in.frame.count;
  for (int i = 0; i < in.frame.count; ++i) {
    const VisualObservation& o = in.frame.items[i];
    m.ray.push_back(o.ray);
    m.state.push_back(o.state);
    m.crossed.push_back(o.crossed);
    m.signed_distance_px.push_back(o.signed_distance_px);
    m.stddev_px.push_back(o.stddev_px);
  }
  m.have_estimate = in.have_estimate;
  m.estimate_capture_ns = in.estimate.capture_ns;
  m.estimate_frame_seq = in.estimate.frame_seq;
  m.estimate_valid = in.estimate.valid;
  m.estimate_position[0] = in.estimate.position.x, m.estimate_position[1] = in.estimate.position.y;
  m.estimate_stddev = in.estimate.stddev;
  m.estop = in.estop;
  m.command_velocity[0] = r.command.velocity.x, m.command_velocity[1] = r.command.velocity.y;
  m.command_estop = r.command.estop;
  m.command_reset = r.command.reset;
  m.command_quick_stop = r.command.quick_stop;
  m.mode = static_cast<std::int8_t>(r.mode);
  m.step_index = r.step_index;
  m.holding = r.holding;
  return m;
}

CycleRecord FromCycleMessage(const controller_cycle_t& m) {
  CycleRecord r;
  r.cycle = m.cycle;
  ExecutorInput& in = r.input;
  in.now_ns = m.now_ns;
  in.now_utime = m.utime;
  in.have_status = m.have_status;
  in.status.receive_ns = m.status_receive_ns;
  in.status.utime = m.status_utime;
  in.status.seq = m.status_seq;
  in.status.command_seq = m.status_command_seq;
  in.status.position = {m.status_position[0], m.status_position[1]};
  in.status.velocity = {m.status_velocity[0], m.status_velocity[1]};
  in.status.contact = m.status_contact;
  in.status.contact_force = {m.status_contact_force[0], m.status_contact_force[1]};
  in.status.state = m.status_state;
  in.status.fault_bits = m.status_fault_bits;
  in.heartbeat_ns = m.heartbeat_ns;
  in.peer_lost = m.peer_lost;
  in.link_fault_code = m.link_fault_code;
  CopyText(in.link_fault, m.link_fault.c_str());
  in.have_frame = m.have_frame;
  in.frame.capture_ns = m.frame_capture_ns;
  in.frame.frame_seq = m.frame_seq;
  in.frame.count = std::min<std::int32_t>(m.num_observations, kMaxVisualObservations);
  for (int i = 0; i < in.frame.count; ++i) {
    const auto k = static_cast<std::size_t>(i);
    VisualObservation& o = in.frame.items[i];
    o.ray = m.ray[k];
    o.state = m.state[k];
    o.crossed = m.crossed[k];
    o.signed_distance_px = m.signed_distance_px[k];
    o.stddev_px = m.stddev_px[k];
  }
  in.have_estimate = m.have_estimate;
  in.estimate.capture_ns = m.estimate_capture_ns;
  in.estimate.frame_seq = m.estimate_frame_seq;
  in.estimate.valid = m.estimate_valid;
  in.estimate.position = {m.estimate_position[0], m.estimate_position[1]};
  in.estimate.stddev = m.estimate_stddev;
  in.estop = m.estop;
  r.command.utime = m.utime;
  r.command.velocity = {m.command_velocity[0], m.command_velocity[1]};
  r.command.estop = m.command_estop;
  r.command.reset = m.command_reset;
  r.command.quick_stop = m.command_quick_stop;
  r.mode = static_cast<Mode>(m.mode);
  r.step_index = m.step_index;
  r.holding = m.holding;
  return r;
}

}  // namespace visco::control

#pragma once
// One filled-in example of every visco LCM type (values chosen so that every field differs from its default).
// A type added to lcmtypes/ without a Fill() overload here fails to compile the tests: none can be forgotten.

#include "visco/all_lcm_types.h"

namespace visco::testing {

inline void Fill(image_t& m) {
  m.utime = 1700000000000001;
  m.seq = 42;
  m.camera = "cam0";
  m.width = 4;
  m.height = 3;
  m.row_stride = 4;
  m.pixel_format = image_t::PIXEL_FORMAT_GRAY8;
  m.data.resize(12);
  for (int i = 0; i < 12; ++i) m.data[i] = static_cast<uint8_t>(i * 17);
  m.size = 12;
}
inline void Fill(camera_info_t& m) {
  m.utime = 1700000000000011;
  m.camera = "cam0";
  m.source = "cam0.yaml";
  m.width = 640;
  m.height = 480;
  m.px = 600.5;
  m.py = 601.5;
  m.u0 = 319.5;
  m.v0 = 239.5;
  m.distortion_model = camera_info_t::DISTORTION_OPENCV;
  m.distortion = {-0.1, 0.01, 0.001, -0.002, 0.0005};
  m.num_distortion = 5;
  m.has_extrinsics = true;
  m.position[0] = 0.1;
  m.position[1] = -0.45;
  m.position[2] = 0.5;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m.rotation[r][c] = r == c ? 1.0 : 0.0;
  }
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) m.extrinsics_covariance[r][c] = r == c ? 1e-6 * (r + 1) : 0.0;
  }
}
inline void Fill(tag_detection_t& m) {
  m.utime = 1700000000000002;
  m.family = "tag36h11";
  m.id = 7;
  for (int i = 0; i < 4; ++i) {
    m.corners[i][0] = 100.5 + i;
    m.corners[i][1] = 200.25 - i;
  }
  m.decision_margin = 55.5;
  m.hamming = 1;
  m.position[0] = 0.1;
  m.position[1] = -0.2;
  m.position[2] = 0.9;
  m.orientation[0] = 0.5;
  m.orientation[1] = 0.5;
  m.orientation[2] = -0.5;
  m.orientation[3] = 0.5;
  m.reprojection_error = 0.12;
  m.tracked = true;
}
inline void Fill(tag_detections_t& m) {
  m.utime = 1700000000000003;
  m.frame_utime = 1700000000000000;
  m.frame_seq = 9;
  m.camera = "cam0";
  m.processing_time_s = 0.011;
  m.pixel_digest = -4417276706812531889;
  m.detections.resize(2);
  Fill(m.detections[0]);
  Fill(m.detections[1]);
  m.detections[1].id = 8;
  m.num_detections = 2;
}
inline void Fill(object_pose_t& m) {
  m.utime = 1700000000000004;
  m.object_id = "peg";
  m.position[0] = 1.0;
  m.position[1] = 2.0;
  m.position[2] = 0.05;
  m.orientation[0] = 1.0;
  m.position_stddev = 0.002;
  m.orientation_stddev = 0.01;
  m.contact_refined = true;
  m.pose_decision = object_pose_t::POSE_DECISION_EXPECTED_UP;
  m.ambiguous = true;
  m.tags_used = 3;
  m.rms_error_px = 0.27;
  m.model_tracked = true;
}
inline void Fill(object_poses_t& m) {
  m.utime = 1700000000000005;
  m.frame_utime = 1700000000000000;
  m.poses.resize(1);
  Fill(m.poses[0]);
  m.num_poses = 1;
}
inline void Fill(visual_event_t& m) {
  m.utime = 1700000000000006;
  m.cvc_ray = "vc3.cm1";
  m.cm_vertex = 1;
  m.signed_distance_px = -3.5;
  m.distance_stddev_px = 0.4;
  m.state = visual_event_t::STATE_NEGATIVE;
  m.crossed = true;
}
inline void Fill(visual_events_t& m) {
  m.utime = 1700000000000007;
  m.frame_utime = 1700000000000000;
  m.frame_seq = 9;
  m.latency_s = 0.013;
  m.events.resize(1);
  Fill(m.events[0]);
  m.num_events = 1;
}
inline void Fill(robot_estimate_t& m) {
  m.utime = 1700000000000008;
  m.frame_seq = 9;
  m.valid = true;
  m.position[0] = 3.25;
  m.position[1] = 4.5;
  m.position_stddev = 0.003;
  m.heading = 0.1;
}
inline void Fill(motion_step_t& m) {
  m.theta = -1.5707963267948966;
  m.active_rays = {"vc0.cm0", "vc2.cm1"};
  m.num_active_rays = 2;
  m.terminate_kind = motion_step_t::TERMINATE_VC;
  m.terminate_ref = "vc2.cm1";
  m.timeout_s = 12.5;
}
inline void Fill(motion_strategy_t& m) {
  m.utime = 1700000000000009;
  m.scene = "slot";
  m.feasible = true;
  m.speed = 0.05;
  m.steps.resize(2);
  Fill(m.steps[0]);
  Fill(m.steps[1]);
  m.steps[1].terminate_kind = motion_step_t::TERMINATE_GOAL;
  m.num_steps = 2;
}
inline void Fill(velocity_command_t& m) {
  m.utime = 1700000000000010;
  m.node_id = 5;
  m.session = 0x1234ABCD;
  m.seq = 123;
  m.velocity[0] = 0.01;
  m.velocity[1] = -0.05;
  m.estop = false;
  m.reset = true;
  m.quick_stop = true;
}
inline void Fill(robot_status_t& m) {
  m.utime = 1700000000000011;
  m.node_id = 5;
  m.session = 0x1234ABCD;
  m.seq = 77;
  m.command_seq = 123;
  m.position[0] = 3.0;
  m.position[1] = 4.0;
  m.velocity[0] = 0.01;
  m.velocity[1] = -0.04;
  m.contact = true;
  m.contact_force[1] = 2.5;
  m.state = robot_status_t::STATE_MOVING;
  m.fault_bits = int32_t{robot_status_t::FAULT_SEQUENCE} | int32_t{robot_status_t::FAULT_BUS};
}
inline void Fill(heartbeat_t& m) {
  m.utime = 1700000000000012;
  m.sender = "driver";
  m.node_id = 5;
  m.counter = 1000;
  m.state = heartbeat_t::STATE_OPERATIONAL;
  m.session = 0x1234ABCD;
}
inline void Fill(fault_t& m) {
  m.utime = 1700000000000013;
  m.source = "controller";
  m.code = fault_t::CODE_VISION_STALE;
  m.severity = fault_t::SEVERITY_ERROR;
  m.robot_stopped = true;
  m.cleared = false;
  m.message = "robot estimate 25 ms old (> 10 ms)";
  m.emcy_code = 0x8250;
  m.fault_bits = 1;
}
inline void Fill(controller_telemetry_t& m) {
  m.utime = 1700000000000014;
  m.step_index = 1;
  m.mode = controller_telemetry_t::MODE_VISUAL_COMPLIANT;
  m.stop_reason = "";
  m.command[0] = 0.02;
  m.command[1] = -0.03;
  m.estimate[0] = 2.0;
  m.estimate[1] = 1.0;
  m.estimate_age_s = 0.004;
  m.period_s = 0.002;
  m.cycles = 5000;
  m.overruns = 2;
  m.jitter_min_s = 1e-6;
  m.jitter_mean_s = 2e-5;
  m.jitter_max_s = 3e-4;
  for (int i = 0; i < 16; ++i) m.jitter_histogram[i] = i * 3;
}

inline void Fill(controller_cycle_t& m) {
  m.utime = 1700000000000015;
  m.now_ns = 123456789;
  m.cycle = 77;
  m.have_status = true;
  m.status_receive_ns = 123000000;
  m.status_utime = 1700000000000016;
  m.status_seq = 5;
  m.status_command_seq = 4;
  m.status_position[0] = 1.5;
  m.status_position[1] = 2.5;
  m.status_velocity[0] = 0.1;
  m.status_velocity[1] = -0.1;
  m.status_contact = true;
  m.status_contact_force[0] = 3;
  m.status_contact_force[1] = -4;
  m.status_state = 2;
  m.status_fault_bits = 8;
  m.heartbeat_ns = 122000000;
  m.peer_lost = true;
  m.link_fault_code = 4;
  m.link_fault = "driver heartbeat lost";
  m.have_frame = true;
  m.frame_capture_ns = 120000000;
  m.frame_seq = 31;
  m.num_observations = 2;
  m.ray = {0, 3};
  m.state = {1, 3};
  m.crossed = {false, true};
  m.signed_distance_px = {-2.5, 7.25};
  m.stddev_px = {0.3, 0.4};
  m.have_estimate = true;
  m.estimate_capture_ns = 119000000;
  m.estimate_frame_seq = 31;
  m.estimate_valid = true;
  m.estimate_position[0] = 1.49;
  m.estimate_position[1] = 2.51;
  m.estimate_stddev = 0.002;
  m.estop = true;
  m.command_velocity[0] = 0.05;
  m.command_velocity[1] = -0.02;
  m.command_estop = true;
  m.command_reset = true;
  m.command_quick_stop = true;
  m.mode = controller_telemetry_t::MODE_STOPPED;
  m.step_index = 1;
  m.holding = true;
}
inline void Fill(log_annotation_t& m) {
  m.utime = 1700000000000017;
  m.source = "run";
  m.kind = "controller_config";
  m.text = "{\"rate_hz\": 500}";
}

inline void Fill(sim_truth_t& m) {
  m.utime = 1700000000000021;
  m.node_id = 3;
  m.position[0] = 4.25;
  m.position[1] = -2.5;
  m.velocity[0] = 0.125;
  m.velocity[1] = -0.375;
  m.contact = true;
  m.mode = sim_truth_t::MODE_SLIDING;
}

}  // namespace visco::testing

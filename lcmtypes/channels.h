#pragma once
// LCM channel names used by visco. One place, so that every process, lcm-spy session and replay agrees.

namespace visco::channels {

inline constexpr char kCameraImage[] = "VISCO_CAMERA_IMAGE";      // visco::image_t
inline constexpr char kCameraInfo[] = "VISCO_CAMERA_INFO";        // visco::camera_info_t: the images' calibration
inline constexpr char kTagDetections[] = "VISCO_TAG_DETECTIONS";  // visco::tag_detections_t
inline constexpr char kObjectPoses[] = "VISCO_OBJECT_POSES";      // visco::object_poses_t
inline constexpr char kRobotEstimate[] = "VISCO_ROBOT_ESTIMATE";  // visco::robot_estimate_t
inline constexpr char kVisualEvents[] = "VISCO_VISUAL_EVENTS";    // visco::visual_events_t
inline constexpr char kStrategy[] = "VISCO_STRATEGY";             // visco::motion_strategy_t
inline constexpr char kCommand[] = "VISCO_COMMAND";               // visco::velocity_command_t
inline constexpr char kStatus[] = "VISCO_STATUS";                 // visco::robot_status_t
inline constexpr char kTelemetry[] = "VISCO_TELEMETRY";           // visco::controller_telemetry_t
inline constexpr char kFault[] = "VISCO_FAULT";                   // visco::fault_t
inline constexpr char kEstop[] = "VISCO_ESTOP";  // visco::fault_t: an e-stop request (source, message = who, why)
inline constexpr char kHeartbeatController[] = "VISCO_HEARTBEAT_CONTROLLER";  // visco::heartbeat_t
inline constexpr char kHeartbeatDriver[] = "VISCO_HEARTBEAT_DRIVER";          // visco::heartbeat_t
inline constexpr char kHeartbeatVision[] = "VISCO_HEARTBEAT_VISION";          // visco::heartbeat_t
// Simulation only: the simulated robot's true state, for a simulated camera in another process.
inline constexpr char kSimTruth[] = "VISCO_SIM_TRUTH";  // visco::sim_truth_t
// Simulation only: each frame a simulated camera wrote to a V4L2 output device (its sequence number, when it was
// rendered and written, the digest of its pixels), to follow a frame through the real capture path.
inline constexpr char kSimFrame[] = "VISCO_SIM_FRAME";  // visco::log_annotation_t, kind "sim_frame" (JSON)

}  // namespace visco::channels

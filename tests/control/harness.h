#pragma once
// Closed-loop harness for executor tests: an Executor driven period by period against TestPlant, with a driver
// that reports status and heartbeat every period and a synthetic camera at its own rate and latency.

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "control/executor.h"
#include "control/synthetic_camera.h"
#include "tests/control/test_plant.h"
#include "visco/robot_status_t.hpp"

namespace visco::control::testing {

inline CvcRay MakeRay(const std::string& id, Vec2 from, Vec2 to, int cm_vertex, Vec2 cm_offset) {
  CvcRay ray;
  ray.id = id;
  ray.vc_ray = id + ".vc";
  ray.cm_vertex = cm_vertex;
  ray.from = from;
  ray.to = to;
  ray.direction = (1.0 / Norm(to - from)) * (to - from);
  ray.cm_offset = cm_offset;
  ray.has_cm_offset = true;
  return ray;
}

inline Polygon Square(Vec2 center, double half) {
  return Polygon{{{center.x - half, center.y - half},
                  {center.x + half, center.y - half},
                  {center.x + half, center.y + half},
                  {center.x - half, center.y + half}}};
}

inline void IndexRays(Task& task) {
  task.ray_index.clear();
  for (std::size_t i = 0; i < task.rays.size(); ++i) task.ray_index[task.rays[i].id] = static_cast<int>(i);
}

class Harness {
 public:
  /// `true_camera`: the camera that measures (default: the planar model of config.servo.focal_px).
  Harness(Task task, ExecutorConfig config, Vec2 start, std::uint64_t seed = 1,
          const ServoCamera* true_camera = nullptr)
      : task_(std::move(task)),
        config_(config),
        executor_(task_, config_),
        camera_config_{config.servo.focal_px, 1.0, 0.0},
        camera_(task_, camera_config_, seed) {
    plant.position = start;
    if (true_camera != nullptr) camera_.UseCamera(*true_camera);
  }

  // Knobs.
  TestPlant plant;
  double camera_period_s = 1.0 / 30.0;
  double camera_latency_s = 0.02;
  bool camera_on = true;
  bool estimate_on = true;
  bool driver_alive = true;
  std::int32_t driver_fault_bits = 0;
  bool estop = false;

  void Start() { executor_.Start(now_ns_); }

  /// One control period: driver status, camera, executor, plant.
  const ExecutorOutput& Tick() {
    const std::int64_t period_ns = static_cast<std::int64_t>(config_.period_s * 1e9);
    now_ns_ += period_ns;
    in_.now_ns = now_ns_;
    in_.now_utime = 1'700'000'000'000'000 + now_ns_ / 1000;
    if (driver_alive) {
      in_.have_status = true;
      in_.status.receive_ns = now_ns_;
      in_.status.position = plant.position;
      in_.status.velocity = plant.velocity;
      in_.status.contact = plant.contact;
      in_.status.fault_bits = driver_fault_bits;
      in_.status.state = (driver_fault_bits & robot_status_t::FAULT_ESTOP) != 0
                             ? std::int32_t{robot_status_t::STATE_ESTOP}
                         : (driver_fault_bits & ~std::int32_t{robot_status_t::FAULT_BUS}) != 0
                             ? std::int32_t{robot_status_t::STATE_STOPPED}
                             : (Norm(plant.velocity) > 0 ? std::int32_t{robot_status_t::STATE_MOVING}
                                                         : std::int32_t{robot_status_t::STATE_READY});
      in_.heartbeat_ns = now_ns_;
    }
    // A frame captured at time c arrives at c + latency.
    const std::int64_t camera_period_ns = static_cast<std::int64_t>(camera_period_s * 1e9);
    const std::int64_t latency_ns = static_cast<std::int64_t>(camera_latency_s * 1e9);
    if (now_ns_ >= next_capture_ns_) {
      pending_capture_ns_ = now_ns_;
      pending_position_ = plant.position;
      pending_ = true;
      next_capture_ns_ += camera_period_ns;
    }
    if (pending_ && now_ns_ >= pending_capture_ns_ + latency_ns) {
      pending_ = false;
      ++frame_seq_;
      if (camera_on) {
        camera_.Observe(pending_position_, frame_seq_, pending_capture_ns_, in_.frame);
        in_.have_frame = true;
      }
      if (estimate_on) {
        in_.have_estimate = true;
        in_.estimate.capture_ns = pending_capture_ns_;
        in_.estimate.valid = true;
        in_.estimate.position = pending_position_;
      }
    }
    in_.estop = estop;
    executor_.Update(in_, out_);
    for (int i = 0; i < out_.num_faults; ++i) faults.push_back(out_.faults[i]);
    plant.Step(out_.command.velocity, config_.period_s);
    return out_;
  }

  /// Ticks until the executor finishes or `max_s` elapse. Returns the number of ticks.
  int RunUntilFinished(double max_s) {
    const int max_ticks = static_cast<int>(max_s / config_.period_s);
    int ticks = 0;
    while (!executor_.finished() && ticks < max_ticks) {
      Tick();
      ++ticks;
    }
    return ticks;
  }

  Executor& executor() { return executor_; }
  SyntheticCamera& camera() { return camera_; }
  const Task& task() const { return task_; }
  ExecutorInput& input() { return in_; }
  std::int64_t now_ns() const { return now_ns_; }
  std::vector<FaultEvent> faults;

 private:
  Task task_;
  ExecutorConfig config_;
  Executor executor_;
  SyntheticCameraConfig camera_config_;
  SyntheticCamera camera_;
  ExecutorInput in_;
  ExecutorOutput out_;
  std::int64_t now_ns_ = 1'000'000'000;
  std::int64_t next_capture_ns_ = 1'000'000'000;  // the first capture at the first tick
  std::int64_t pending_capture_ns_ = 0;
  Vec2 pending_position_;
  bool pending_ = false;
  std::int64_t frame_seq_ = 0;
};

}  // namespace visco::control::testing

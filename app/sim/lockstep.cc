#include "app/sim/lockstep.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <lcm/lcm-cpp.hpp>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <vector>

#include "app/sim/world.h"
#include "common/error.h"
#include "common/even_odd.h"
#include "control/control_loop.h"
#include "control/cycle_message.h"
#include "control/lcm_bridge.h"
#include "control/run.h"
#include "drivers/driver_transport.h"
#include "drivers/robot_link.h"
#include "lcmtypes/channels.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "visco/log_annotation_t.hpp"
#include "visco/sim_truth_t.hpp"
#include "vision/camera_info.h"
#include "vision/pipeline.h"
#include "vision/pipeline_config.h"

namespace visco::sim {
namespace {

// The simulated monotonic clock starts at 1 s (0 means "never" to some of the loop's timers).
constexpr std::int64_t kStartUs = 1'000'000;

// Every message on the bus into the log, stamped with the simulated time it was published at (the bus is served
// at that same instant). The first subscriber, so that it sees each message before anyone reacts to it.
class BusLog {
 public:
  BusLog(EventLogTap* log, const std::int64_t& utime) : log_(log), utime_(utime) {}
  void Handle(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    ++messages;
    if (log_ != nullptr) {
      log_->Write(channel, utime_, static_cast<const std::uint8_t*>(rbuf->data), rbuf->data_size);
    }
  }
  std::int64_t messages = 0;

 private:
  EventLogTap* log_;
  const std::int64_t& utime_;
};

double DistanceToPolygon(const std::vector<Eigen::Vector2d>& ring, const Eigen::Vector2d& p) {
  if (ring.empty()) return std::numeric_limits<double>::infinity();
  if (InsideEvenOdd(ring, p)) return 0.0;
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < ring.size(); ++i) {
    const Eigen::Vector2d a = ring[i], b = ring[(i + 1) % ring.size()];
    const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
    best = std::min(best, (a + t * (b - a) - p).norm());
  }
  return best;
}

template <class M>
void WriteRecord(EventLogTap& log, const char* channel, std::int64_t utime, const M& m) {
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  log.Write(channel, utime, bytes.data(), bytes.size());
}

// Microseconds of a rate's period, at least 1.
std::int64_t PeriodUs(double hz) { return std::max<std::int64_t>(1, std::llround(1e6 / hz)); }

void CheckOptions(const LockstepOptions& o) {
  if (!(o.camera_hz > 0 && o.camera_hz <= 1000))
    throw InputError("command line", "--camera-hz", "must be in (0, 1000]");
  if (!(o.truth_hz > 0 && o.truth_hz <= 1000)) throw InputError("command line", "--truth-hz", "must be in (0, 1000]");
  if (!(o.rate_hz >= 10 && o.rate_hz <= 2000)) throw InputError("command line", "--rate", "must be in [10, 2000] Hz");
  if (!(o.telemetry_hz > 0 && o.telemetry_hz <= o.rate_hz)) {
    throw InputError("command line", "--telemetry-hz", "must be in (0, rate]");
  }
  if (!(o.latency_s >= 0 && o.latency_s < 1.0 / o.camera_hz)) {
    throw InputError("command line", "--latency-ms", "must be >= 0 and below the camera period");
  }
  if (!(o.max_duration_s > 0 && o.max_duration_s <= 3600)) {
    throw InputError("command line", "--duration", "a lockstep run needs a positive limit of simulated seconds");
  }
  if (o.strategy_path.empty()) throw InputError("command line", "--strategy", "--lockstep needs the strategy to run");
  if (o.rays_path.empty()) throw InputError("command line", "--rays", "--lockstep needs the CVC rays (visco vcrays)");
  if (o.render.objects_path.empty() || o.render.calibration_path.empty() || o.render.extrinsics_path.empty()) {
    throw InputError("command line", "--objects",
                     "--lockstep renders images for the vision pipeline: give --objects, --camera and --extrinsics");
  }
}

}  // namespace

control::ExecutorConfig DemoExecutorConfig() {
  control::ExecutorConfig c;
  c.limits.max_speed = 1.0;
  c.limits.max_accel = 4.0;
  c.max_vision_age_s = 0.4;
  c.max_hold_s = 4.0;
  c.startup_timeout_s = 30.0;
  c.heartbeat_timeout_s = 0.5;
  return c;
}

std::string LockstepResult::ToJson() const {
  nlohmann::json j;
  j["result"] = mode == control::Mode::kDone ? "done" : (mode == control::Mode::kStopped ? "stopped" : ToString(mode));
  j["reason"] = reason;
  j["reached"] = reached();
  j["steps_completed"] = steps_completed;
  j["num_steps"] = num_steps;
  j["cycles"] = cycles;
  j["commands_sent"] = commands_sent;
  j["statuses_received"] = statuses_received;
  j["faults_published"] = faults_published;
  j["images"] = images;
  j["frames_processed"] = frames_processed;
  j["messages"] = messages;
  j["records"] = records;
  j["position"] = {position.x, position.y};
  j["contact"] = contact;
  j["goal_error_m"] = std::isfinite(goal_error_m) ? nlohmann::json(goal_error_m) : nlohmann::json();
  j["simulated_s"] = simulated_s;
  j["wall_s"] = wall_s;
  j["driver"] = {{"state", driver_state},
                 {"commands_applied", driver.commands_applied},
                 {"sessions", driver.sessions},
                 {"watchdog_stops", driver.watchdog_stops},
                 {"quick_stops", driver.quick_stops},
                 {"statuses_sent", driver.statuses_sent}};
  return j.dump();
}

LockstepResult RunLockstep(const LockstepOptions& o) {
  CheckOptions(o);
  const auto wall_start = std::chrono::steady_clock::now();
  // The simulated clocks: monotonic microseconds `t`, and the epoch time that goes with it.
  std::int64_t t = kStartUs;
  std::int64_t utime = o.start_utime;
  auto now_utime = [&] { return utime; };

  const planning::Scene scene = planning::LoadScene(o.scene_path);
  control::Vec2 start = o.start;
  if (!o.have_start) {
    if (!scene.start) throw InputError(o.scene_path, "start", "the scene has no start region: give --start X Y");
    const Eigen::Vector2d c = StartRegionCentroid(scene);
    start = {c.x(), c.y()};
  }
  drivers::SimulatedRobotConfig robot_config = o.robot;
  robot_config.start = {start.x, start.y};
  robot_config.world = MakeMotionWorld(scene);
  robot_config.velocity_cone = scene.uncertainty.velocity_cone_rad;
  drivers::SimulatedRobot robot(robot_config);

  control::RunOptions run;  // the controller's files, as `visco run` takes them (and names them in the log)
  run.strategy_path = o.strategy_path;
  run.scene_path = o.scene_path;
  run.rays_path = o.rays_path;
  const control::Task task = control::LoadTask(run);

  RenderedCameraConfig render = o.render;
  render.seed = o.robot.seed ^ 0x1a9e5ULL;  // as `visco sim`
  RenderedCamera camera(render);
  vision::PipelineConfig pipeline_config;
  pipeline_config.camera = render.calibration_path;
  pipeline_config.camera_name = render.camera_name;
  pipeline_config.extrinsics = render.extrinsics_path;
  pipeline_config.objects = render.objects_path;
  const vision::LoadedPipeline loaded = vision::LoadPipelineConfig(pipeline_config);
  vision::PipelineOptions pipeline_options = loaded.options;
  pipeline_options.clock = now_utime;
  vision::VisionPipeline pipeline(loaded.camera, loaded.wMc, loaded.models, pipeline_options);
  visco::log_annotation_t config{};
  config.source = "sim";
  config.kind = vision::kVisionConfigKind;
  config.text = vision::VisionConfigToJson(loaded);
  std::int64_t next_config_utime = std::numeric_limits<std::int64_t>::min();

  // The bus, and the log of everything on it (subscribed first).
  lcm::LCM bus("memq://");
  if (!bus.good()) throw JobFailed("LCM: cannot initialise the in-process provider memq://");
  BusLog bus_log(o.log, utime);
  lcm::Subscription* log_subscription = bus.subscribe(".*", &BusLog::Handle, &bus_log);
  auto serve = [&bus] {
    while (bus.handleTimeout(0) > 0) {
    }
  };
  const drivers::LockstepBus lockstep{&bus, now_utime};

  drivers::DriverTransportConfig transport_config;
  transport_config.node_id = o.node_id;
  transport_config.lockstep = lockstep;
  const std::unique_ptr<drivers::DriverTransport> transport = drivers::MakeLcmDriverTransport(transport_config);
  drivers::DriverConfig driver_config = o.driver;
  if (driver_config.session_seed == 0) driver_config.session_seed = (o.robot.seed ^ 0x5e55104ULL) | 1;
  drivers::Driver driver(driver_config, *transport, robot);

  drivers::RobotLinkConfig link_config;
  link_config.node_id = o.node_id;
  link_config.heartbeat_timeout_us = static_cast<std::int64_t>(o.heartbeat_timeout_s * 1e6);
  link_config.lockstep = lockstep;
  const std::unique_ptr<drivers::RobotLink> link = drivers::MakeLcmRobotLink(link_config);

  control::ExecutorConfig executor_config = o.executor;
  executor_config.period_s = 1.0 / o.rate_hz;
  // The servo law's interaction from the rendered camera's calibration and pose (docs/control.md).
  if (!executor_config.servo.camera.valid) executor_config.servo.camera = ServoCameraFromFiles(o.render);
  control::Executor executor(task, executor_config);
  control::Outbox outbox;
  control::ControllerBridge bridge(bus, task, outbox, control::BridgeClock{[&t] { return t * 1000; }, now_utime});
  control::CycleRecordQueue records;
  control::LoopConfig loop_config;
  loop_config.period_s = 1.0 / o.rate_hz;
  loop_config.telemetry_every = std::max(1, static_cast<int>(std::lround(o.rate_hz / o.telemetry_hz)));
  loop_config.realtime = false;
  const control::LoopSources sources{link.get(), &bridge.frames(), &bridge.estimates(), &bridge.estop(), &records};
  control::ControlLoop loop(executor, sources, loop_config, outbox);

  spdlog::info(
      "sim --lockstep: scene {}, robot at ({:.3f}, {:.3f}), seed {}, camera {:.0f} Hz {}x{}, controller "
      "{:.0f} Hz, {} step(s); simulated clock from {} us",
      scene.name, start.x, start.y, o.robot.seed, o.camera_hz, camera.width(), camera.height(), o.rate_hz,
      task.steps.size(), o.start_utime);

  LockstepResult result;
  std::int64_t records_written = 0;
  auto write_records = [&] {
    control::CycleRecord r;
    while (records.TryPop(r)) {
      if (o.log != nullptr) WriteRecord(*o.log, control::kCycleChannel, r.input.now_utime, control::ToCycleMessage(r));
      ++records_written;
    }
  };

  // The schedule: every part at its own period; parts due at the same instant run in this order -- the driver
  // (the robot moves up to now), the camera's capture, the image's publication and vision, the truth, the
  // controller's period -- and the bus is served after each, so that a message published now is received now.
  const std::int64_t driver_period = driver_config.period_us;
  const std::int64_t loop_period = PeriodUs(o.rate_hz);
  const std::int64_t truth_period = PeriodUs(o.truth_hz);
  const std::int64_t latency = std::llround(o.latency_s * 1e6);
  const std::int64_t end_us = kStartUs + std::llround(o.max_duration_s * 1e6);
  const std::int64_t hard_end_us = end_us + 10'000'000;  // after the e-stop the controller needs a few periods
  std::int64_t next_driver = kStartUs, next_loop = kStartUs + loop_period, next_truth = kStartUs;
  std::int64_t frame_index = 0;
  auto capture_time = [&](std::int64_t k) {
    return kStartUs + std::llround(static_cast<double>(k) * 1e6 / o.camera_hz);
  };
  std::int64_t next_capture = capture_time(0);
  bool image_pending = false;
  std::int64_t pending_publish = 0;
  image_t image;
  std::int64_t seq = 0;
  bool estop_sent = false;
  int linger = -1;  // periods left after the executor finished (-1: not finished)

  auto set_time = [&](std::int64_t new_t) {
    t = new_t;
    utime = o.start_utime + (t - kStartUs);
  };
  set_time(kStartUs);
  driver.Start(t);
  serve();
  const std::int64_t start_ns = t * 1000;
  executor.Start(start_ns);

  while (true) {
    std::int64_t next = std::min({next_driver, next_loop, next_truth, next_capture});
    if (image_pending) next = std::min(next, pending_publish);
    set_time(next);
    if (t == next_driver) {
      driver.Update(t);
      serve();
      next_driver += driver_period;
    }
    if (t == next_capture) {
      // The camera sees the robot where the driver's last step left it.
      const MotionState& s = robot.state();
      camera.Capture({s.position.x(), s.position.y()}, utime, ++seq, CaptureConditions{}, image);
      image_pending = true;
      pending_publish = t + latency;
      next_capture = capture_time(++frame_index);
    }
    if (image_pending && t == pending_publish) {
      image_pending = false;
      if (utime >= next_config_utime) {
        // Vision's configuration and calibration, as `visco track` publishes them: at start and every second
        // (docs/replay.md).
        config.utime = utime;
        bus.publish(vision::kVisionConfigChannel, &config);
        const visco::camera_info_t info = vision::EncodeCameraInfo(loaded.calibration, utime);
        bus.publish(channels::kCameraInfo, &info);
        next_config_utime = utime + 1000000;
      }
      bus.publish(channels::kCameraImage, &image);
      serve();
      ++result.images;
      // Vision as `visco track --lcm` and `visco replay` run it: the frame, on the clock of its arrival.
      vision::Frame frame;
      std::string error;
      vision::PipelineOutput out;
      if (!vision::DecodeImageMessage(image, frame, error)) {
        out.faults.push_back(pipeline.BadFrame(frame, error));
      } else {
        out = pipeline.Process(frame, utime);
      }
      if (out.processed) ++result.frames_processed;
      vision::ForEachMessage(out, [&](const char* channel, const auto& message) { bus.publish(channel, &message); });
      serve();
    }
    if (t == next_truth) {
      const drivers::RobotFeedback f = robot.Read();
      sim_truth_t m;
      m.utime = utime;
      m.node_id = o.node_id;
      for (int i = 0; i < 2; ++i) {
        m.position[i] = f.position[i];
        m.velocity[i] = f.velocity[i];
      }
      m.contact = f.contact;
      m.mode = static_cast<std::int8_t>(robot.state().mode);
      bus.publish(channels::kSimTruth, &m);
      serve();
      next_truth += truth_period;
    }
    if (t == next_loop) {
      if (!estop_sent && ((o.stop != nullptr && o.stop->load()) || t >= end_us)) {
        spdlog::warn("sim --lockstep: {}: e-stop",
                     t >= end_us ? "the simulated time limit (--duration) reached" : "stop requested (signal)");
        bridge.estop().store(true);
        estop_sent = true;
      }
      loop.RunCycle(t * 1000, utime);
      serve();  // the command reaches the driver's transport (applied at the driver's next update)
      write_records();
      bridge.Drain();  // faults, telemetry, the controller's heartbeat
      serve();
      next_loop += loop_period;
      if (executor.finished() && linger < 0) linger = 5;  // as ControlLoop::Run: the final zero command goes out
      if (linger >= 0 && linger-- == 0) break;
      if (t >= hard_end_us) break;
    }
  }
  write_records();
  if (o.log != nullptr) {
    const log_annotation_t a = control::ControllerConfigAnnotation(run, executor_config, start_ns, loop.cycles(),
                                                                   records_written, records.dropped(), utime);
    WriteRecord(*o.log, control::kAnnotationChannel, a.utime, a);
  }
  bus.unsubscribe(log_subscription);

  result.mode = executor.mode();
  result.reason = executor.stop_reason();
  result.num_steps = static_cast<int>(task.steps.size());
  result.steps_completed =
      executor.mode() == control::Mode::kDone ? result.num_steps : std::max(0, executor.step_index());
  result.cycles = loop.cycles();
  const drivers::LinkCounters counters = link->counters();
  result.commands_sent = counters.commands_sent;
  result.statuses_received = counters.statuses_received;
  result.faults_published = bridge.counters().faults.load();
  result.messages = bus_log.messages;
  result.records = records_written;
  const drivers::RobotFeedback f = robot.Read();
  result.position = {f.position[0], f.position[1]};
  result.contact = f.contact;
  result.goal_error_m = DistanceToPolygon(scene.goal.polygon.vertices, Eigen::Vector2d(f.position[0], f.position[1]));
  result.simulated_s = static_cast<double>(t - kStartUs) * 1e-6;
  result.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  result.driver_state = drivers::ToString(driver.state());
  result.driver = driver.stats();
  if (result.mode == control::Mode::kDone) {
    spdlog::info("sim --lockstep: {} ({:.3f} s simulated in {:.1f} s)", result.reason, result.simulated_s,
                 result.wall_s);
  } else {
    spdlog::error("sim --lockstep: stopped: {}", result.reason);
  }
  return result;
}

}  // namespace visco::sim

#include "app/sim/session.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <lcm/lcm-cpp.hpp>
#include <mutex>
#include <nlohmann/json.hpp>
#include <random>

#include "app/sim/world.h"
#include "common/error.h"
#include "control/control_loop.h"
#include "drivers/driver_transport.h"
#include "lcmtypes/channels.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "visco/log_annotation_t.hpp"
#include "visco/robot_estimate_t.hpp"
#include "visco/sim_truth_t.hpp"
#include "visco/visual_events_t.hpp"
#include "vision/image.h"
#include "vision/v4l2_output.h"

namespace visco::sim {

struct SimSession::Impl {
  planning::Scene scene;
  std::unique_ptr<drivers::SimulatedRobot> robot;
  std::unique_ptr<drivers::DriverTransport> transport;
  std::unique_ptr<drivers::Driver> driver;
  std::unique_ptr<UdpPlant> plant;  // --plant: the robot moved by drives in other processes
  std::thread plant_thread;
  std::unique_ptr<lcm::LCM> lcm;
  std::unique_ptr<control::SyntheticCamera> camera;
  std::unique_ptr<RenderedCamera> rendered;
  std::unique_ptr<vision::V4l2Output> output;  // --v4l2-output: the rendered frames go to this device
  // --no-driver: the robot is simulated by a driver process; its truth arrives on VISCO_SIM_TRUTH.
  std::unique_ptr<lcm::LCM> truth_lcm;
  LatestValue<drivers::RobotTruth> remote_truth;
  std::atomic<std::uint64_t> truths{0};
  std::mutex last_mutex;
  drivers::RobotTruth last_truth;  // for Summary()
  std::thread truth_thread;
  int truth_node = 1;

  void OnTruth(const lcm::ReceiveBuffer*, const std::string&, const sim_truth_t* m) {
    if (m->node_id != truth_node) return;
    drivers::RobotTruth t;
    t.time_ns = control::MonotonicNs() - (control::WallUtime() - m->utime) * 1000;
    for (int i = 0; i < 2; ++i) {
      t.position[i] = m->position[i];
      t.velocity[i] = m->velocity[i];
    }
    t.contact = m->contact;
    t.mode = static_cast<std::uint8_t>(m->mode);
    remote_truth.Publish(t);
    truths.fetch_add(1);
    std::lock_guard<std::mutex> lock(last_mutex);
    last_truth = t;
  }
};

std::string SimSummary::ToJson() const {
  nlohmann::json j;
  j["position"] = {position.x, position.y};
  j["contact"] = contact;
  j["frames"] = frames;
  j["dropped_frames"] = dropped_frames;
  j["camera"] = rendered ? "rendered" : "events";
  if (rendered) j["mean_render_ms"] = mean_render_ms;
  if (!v4l2_output.empty()) {
    j["v4l2_output"] = {{"device", v4l2_output}, {"written", frames}, {"write_failures", write_failures}};
  }
  if (plant) {
    j["plant"] = {{"steps", plant_stats.steps},
                  {"datagrams", plant_stats.datagrams},
                  {"malformed", plant_stats.malformed},
                  {"axis_losses", plant_stats.axis_losses}};
    return j.dump();
  }
  if (!have_driver) {
    j["truth_messages"] = truths;  // the robot was simulated by a driver process
    return j.dump();
  }
  j["driver"] = {{"state", driver_state},
                 {"commands_applied", driver.commands_applied},
                 {"bad_commands", driver.bad_commands},
                 {"out_of_sequence", driver.out_of_sequence},
                 {"wrong_session", driver.wrong_session},
                 {"sessions", driver.sessions},
                 {"refused_resets", driver.refused_resets},
                 {"operator_releases", driver.operator_releases},
                 {"watchdog_stops", driver.watchdog_stops},
                 {"bounds_stops", driver.bounds_stops},
                 {"estops", driver.estops},
                 {"resets", driver.resets},
                 {"statuses_sent", driver.statuses_sent}};
  return j.dump();
}

SimSession::SimSession(const SimOptions& options) : impl_(std::make_unique<Impl>()), options_(options) {
  const SimOptions& o = options_;
  if (!(o.camera_hz > 0 && o.camera_hz <= 1000))
    throw InputError("command line", "--camera-hz", "must be in (0, 1000]");
  if (!(o.latency_s >= 0 && o.latency_s < 1.0 / o.camera_hz)) {
    throw InputError("command line", "--latency-ms", "must be >= 0 and below the camera period");
  }
  if (!(o.drop_rate >= 0 && o.drop_rate <= 1)) throw InputError("command line", "--drop-rate", "must be in [0, 1]");
  if (!(o.noise_px >= 0) || !(o.position_noise_m >= 0)) throw InputError("command line", "--noise", "must be >= 0");
  impl_->scene = planning::LoadScene(o.scene_path);
  const planning::Scene& scene = impl_->scene;
  control::Vec2 start = o.start;
  if (!o.have_start && !o.no_driver) {  // the camera alone needs no start: the driver process has the robot
    if (!scene.start) throw InputError(o.scene_path, "start", "the scene has no start region: give --start X Y");
    const Eigen::Vector2d c = StartRegionCentroid(scene);
    start = {c.x(), c.y()};
  }
  if (!o.no_driver) {
    drivers::SimulatedRobotConfig robot_config = o.robot;
    robot_config.start = {start.x, start.y};
    robot_config.world = MakeMotionWorld(scene);
    robot_config.velocity_cone = scene.uncertainty.velocity_cone_rad;
    impl_->robot = std::make_unique<drivers::SimulatedRobot>(robot_config);
  }

  if (!o.rays_path.empty()) {
    const control::SceneInfo info = control::LoadScene(o.scene_path);
    control::CheckMadeFor(control::ReadSceneIdentity(o.rays_path), "rays", o.rays_path, info, o.scene_path);
    rays_.rays = control::LoadRays(o.rays_path);
    for (std::size_t i = 0; i < rays_.rays.size(); ++i) rays_.ray_index[rays_.rays[i].id] = static_cast<int>(i);
    control::AttachScene(rays_, info, o.scene_path);
    if (rays_.rays.size() > static_cast<std::size_t>(control::kMaxVisualObservations)) {
      throw InputError(o.rays_path, "cvc_rays", "more rays than the simulated camera's capacity");
    }
  }
  for (const FaultWindow* w : {&o.occlude, &o.blackout, &o.stale}) {
    if (w->start_s >= 0 && !(w->duration_s > 0)) {
      throw InputError("command line", "--occlude/--blackout/--stale", "the duration must be positive");
    }
  }
  if (!(o.stale_s > 0)) throw InputError("command line", "--stale-ms", "must be positive");
  if (!o.render.objects_path.empty()) {
    RenderedCameraConfig render = o.render;
    render.seed = o.robot.seed ^ 0x1a9e5ULL;
    impl_->rendered = std::make_unique<RenderedCamera>(render);
  }
  if (!o.v4l2_output.empty()) {
    // The device stamps and numbers the frames and can inject its own faults: none are simulated on this side.
    if (!impl_->rendered) {
      throw InputError("command line", "--v4l2-output",
                       "needs the rendered camera (--objects, --camera, --extrinsics): only images go to a device");
    }
    const std::pair<bool, const char*> refused[] = {{o.render.png_level >= 0, "--png-level"},
                                                    {o.drop_rate != 0, "--drop-rate"},
                                                    {o.blackout.start_s >= 0, "--blackout"},
                                                    {o.stale.start_s >= 0, "--stale"}};
    for (const auto& [given, option] : refused) {
      if (given) {
        throw InputError("command line", option,
                         "not with --v4l2-output (the capture process stamps, numbers and encodes the frames; inject "
                         "camera faults at the device, e.g. vivid's controls, docs/camera.md)");
      }
    }
    vision::V4l2OutputOptions out;
    out.device = o.v4l2_output;
    out.output = o.v4l2_output_index;
    out.pixel_format = o.v4l2_output_format;
    out.width = impl_->rendered->width();
    out.height = impl_->rendered->height();
    impl_->output = std::make_unique<vision::V4l2Output>(out);
  }
  control::SyntheticCameraConfig camera_config{o.focal_px, o.on_line_band_px, o.noise_px};
  impl_->camera = std::make_unique<control::SyntheticCamera>(rays_, camera_config, o.robot.seed ^ 0x5eedcafeULL);

  if (impl_->robot && !o.plant.address.empty()) {
    impl_->plant = std::make_unique<UdpPlant>(o.plant, *impl_->robot);
  } else if (impl_->robot) {
    drivers::DriverTransportConfig transport_config;
    transport_config.node_id = o.node_id;
    transport_config.lcm_url = o.lcm_url;
    transport_config.can_interface = o.can_interface;
    impl_->transport = o.can_interface.empty() ? drivers::MakeLcmDriverTransport(transport_config)
                                               : drivers::MakeSocketCanDriverTransport(transport_config);
    impl_->driver = std::make_unique<drivers::Driver>(o.driver, *impl_->transport, *impl_->robot);
  } else {
    impl_->truth_lcm = std::make_unique<lcm::LCM>(o.lcm_url);
    if (!impl_->truth_lcm->good()) throw JobFailed("LCM: cannot initialise provider '" + o.lcm_url + "'");
    impl_->truth_node = o.node_id;
    impl_->truth_lcm->subscribe(channels::kSimTruth, &Impl::OnTruth, impl_.get());
  }
  impl_->lcm = std::make_unique<lcm::LCM>(o.lcm_url);
  if (!impl_->lcm->good()) throw JobFailed("LCM: cannot initialise provider '" + o.lcm_url + "'");
  if (impl_->plant) {
    spdlog::info("sim: the plant of simulated drives on UDP {} (port {})", o.plant.address, impl_->plant->port());
  }
  spdlog::info("sim: scene {}, {}, cone {:.1f} deg, seed {}, {} CVC ray(s), camera {:.0f} Hz ({})", scene.name,
               impl_->robot ? fmt::format("{} C-obstacle part(s), robot at ({:.3f}, {:.3f})",
                                          impl_->robot->model().world().obstacles.size(), start.x, start.y)
                            : fmt::format("the robot simulated elsewhere (its truth from {}, node {})",
                                          channels::kSimTruth, o.node_id),
               scene.uncertainty.velocity_cone_rad * 180 / M_PI, o.robot.seed, rays_.rays.size(), o.camera_hz,
               impl_->rendered ? "rendered " + std::to_string(impl_->rendered->width()) + "x" +
                                     std::to_string(impl_->rendered->height()) + " images " +
                                     (impl_->output ? "to " + o.v4l2_output + " ('" + impl_->output->card() + "', " +
                                                          impl_->output->fourcc() + ")"
                                                    : std::string("on ") + channels::kCameraImage)
                               : std::string("synthetic visual events"));
}

SimSession::~SimSession() { Stop(); }

void SimSession::Start() {
  if (impl_->plant) {
    impl_->plant_thread = std::thread([this] { impl_->plant->Run(stop_driver_); });
  } else if (impl_->driver) {
    driver_thread_ = std::thread([this] { impl_->driver->Run(stop_driver_); });
  } else {
    impl_->truth_thread = std::thread([this] {
      while (!stop_camera_.load()) impl_->truth_lcm->handleTimeout(50);
    });
  }
  camera_thread_ = std::thread([this] { CameraLoop(); });
}

void SimSession::ReleaseEStop() {
  if (impl_->driver) impl_->driver->RequestOperatorRelease();
}

void SimSession::KillDriver() {
  stop_driver_.store(true);
  if (driver_thread_.joinable()) driver_thread_.join();
  if (impl_->plant_thread.joinable()) impl_->plant_thread.join();
}

void SimSession::Stop() {
  stop_camera_.store(true);
  if (camera_thread_.joinable()) camera_thread_.join();
  if (impl_->truth_thread.joinable()) impl_->truth_thread.join();
  KillDriver();
}

SimSummary SimSession::Summary() const {
  SimSummary s;
  // The driver's thread steps the robot and updates the driver while the session runs: read both through the
  // driver's snapshot (lock-free), never the robot or the driver's own variables.
  s.frames = frames_.load();
  s.dropped_frames = dropped_.load();
  s.rendered = impl_->rendered != nullptr;
  s.mean_render_ms = s.frames > 0 ? static_cast<double>(render_us_.load()) / 1e3 / s.frames : 0.0;
  s.v4l2_output = options_.v4l2_output;
  s.write_failures = write_failures_.load();
  if (impl_->plant) {
    s.have_driver = false;
    s.plant = true;
    s.plant_stats = impl_->plant->Stats();
    s.position = {s.plant_stats.last.position[0], s.plant_stats.last.position[1]};
    s.contact = s.plant_stats.last.contact;
    return s;
  }
  if (!impl_->driver) {
    std::lock_guard<std::mutex> lock(impl_->last_mutex);
    s.position = {impl_->last_truth.position[0], impl_->last_truth.position[1]};
    s.contact = impl_->last_truth.contact;
    s.have_driver = false;
    s.truths = impl_->truths.load();
    return s;
  }
  const drivers::DriverSnapshot d = impl_->driver->Snapshot();
  s.position = {d.robot.position[0], d.robot.position[1]};
  s.contact = d.robot.contact;
  s.driver = d.stats;
  s.driver_state = drivers::ToString(d.state);
  return s;
}

void SimSession::WriteToDevice(const image_t& image, std::int64_t render_utime) {
  const vision::GrayImageView picture{image.data.data(), image.width, image.height, image.row_stride};
  std::string error;
  // A free buffer comes back within a frame of the device's; a second without one is a stuck device.
  if (!impl_->output->Write(picture, 1000, error)) {
    if (write_failures_.fetch_add(1) % 100 == 0) spdlog::warn("sim camera: frame {} not written: {}", image.seq, error);
    return;
  }
  frames_.fetch_add(1);
  // The frame's record, to follow it through capture and vision (the capture process numbers frames its own way;
  // the pixel digest, which vision records per frame, identifies it).
  nlohmann::json record = {{"seq", image.seq},
                           {"render_utime", render_utime},
                           {"written_utime", control::WallUtime()},
                           {"pixel_digest", static_cast<std::int64_t>(vision::PixelDigest(picture))}};
  log_annotation_t m;
  m.utime = control::WallUtime();
  m.source = "sim";
  m.kind = "sim_frame";
  m.text = record.dump();
  impl_->lcm->publish(channels::kSimFrame, &m);
}

void SimSession::CameraLoop() {
  const SimOptions& o = options_;
  std::mt19937_64 rng(o.robot.seed ^ 0xca3e7aULL);
  std::bernoulli_distribution drop(o.drop_rate);
  std::normal_distribution<double> noise(0.0, 1.0);
  using Clock = std::chrono::steady_clock;
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / o.camera_hz));
  const auto latency = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(o.latency_s));
  const auto t0 = Clock::now();
  auto next = t0;
  drivers::RobotTruth truth;
  bool have_truth = false;
  std::int64_t seq = 0;
  control::VisualFrame frame;
  image_t image;
  bool occlusion_logged = false, blackout_logged = false, stale_logged = false;
  auto log_window = [](bool active, bool& logged, const char* what) {
    if (active != logged) spdlog::warn("sim camera: {} {}", what, active ? "begins" : "ends");
    logged = active;
  };
  while (!stop_camera_.load()) {
    next += period;
    const auto now = Clock::now();
    if (next < now - period) next = now;  // fell behind (slow rendering): no burst of catch-up frames
    std::this_thread::sleep_until(next);
    have_truth |= impl_->robot ? impl_->robot->truth().TryTake(truth) : impl_->remote_truth.TryTake(truth);
    if (!have_truth || !camera_on_.load()) continue;
    const double t = std::chrono::duration<double>(Clock::now() - t0).count();
    const bool occluded = o.occlude.Active(t), blackout = o.blackout.Active(t), stale = o.stale.Active(t);
    log_window(occluded, occlusion_logged, "the robot is occluded");
    log_window(blackout, blackout_logged, "black-out (no frames)");
    log_window(stale, stale_logged, "stale frames");
    ++seq;
    if (drop(rng) || blackout) {
      dropped_.fetch_add(1);
      continue;
    }
    const auto capture_time = Clock::now();
    const std::int64_t capture_utime =
        control::WallUtime() - (stale ? static_cast<std::int64_t>(o.stale_s * 1e6) : std::int64_t{0});
    if (impl_->rendered) {
      impl_->rendered->Capture({truth.position[0], truth.position[1]}, capture_utime, seq, CaptureConditions{occluded},
                               image);
      render_us_.fetch_add(static_cast<std::uint64_t>(
          std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - capture_time).count()));
      std::this_thread::sleep_until(capture_time + latency);
      if (impl_->output) {
        WriteToDevice(image, capture_utime);
        continue;
      }
      impl_->lcm->publish(channels::kCameraImage, &image);
      frames_.fetch_add(1);
      continue;
    }
    impl_->camera->Observe({truth.position[0], truth.position[1]}, seq, control::MonotonicNs(), frame);
    std::this_thread::sleep_until(capture_time + latency);
    const std::int64_t now_utime = control::WallUtime();
    if (!rays_.rays.empty()) {
      visual_events_t events;
      events.utime = now_utime;
      events.frame_utime = capture_utime;
      events.frame_seq = seq;
      events.latency_s = static_cast<double>(now_utime - capture_utime) * 1e-6;
      for (int i = 0; i < frame.count; ++i) {
        const control::VisualObservation& obs = frame.items[i];
        visual_event_t e;
        e.utime = capture_utime;
        e.cvc_ray = rays_.rays[static_cast<std::size_t>(obs.ray)].id;
        e.cm_vertex = rays_.rays[static_cast<std::size_t>(obs.ray)].cm_vertex;
        e.signed_distance_px = occluded ? 0.0 : obs.signed_distance_px;
        e.distance_stddev_px = o.noise_px;
        e.state = occluded ? visual_event_t::STATE_UNKNOWN : obs.state;
        e.crossed = occluded ? false : obs.crossed;
        events.events.push_back(e);
      }
      events.num_events = static_cast<std::int32_t>(events.events.size());
      impl_->lcm->publish(channels::kVisualEvents, &events);
    }
    robot_estimate_t estimate;
    estimate.utime = capture_utime;
    estimate.frame_seq = seq;
    estimate.valid = !occluded;
    estimate.position[0] = truth.position[0] + o.position_noise_m * noise(rng);
    estimate.position[1] = truth.position[1] + o.position_noise_m * noise(rng);
    estimate.position_stddev = o.position_noise_m;
    estimate.heading = 0.0;
    impl_->lcm->publish(channels::kRobotEstimate, &estimate);
    frames_.fetch_add(1);
  }
}

}  // namespace visco::sim

#include "app/demo/closed_loop.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <thread>
#include <utility>

#include "app/demo/processes.h"

namespace visco::app::demo {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// A time limit of the demo's processes on a machine `a.slow` times slower than the 2-core reference.
std::string Slowed(const Options& a, double value) { return fmt::format("{}", value * a.slow); }
// A rate of the demo's processes on such a machine, at least `floor`.
std::string Rate(const Options& a, double hz, double floor = 1) {
  return fmt::format("{}", std::max(floor, hz / a.slow));
}

double DistanceToPolygon(const planning::Polygon& poly, const Eigen::Vector2d& p) {
  if (planning::InsideEvenOdd(poly.vertices, p)) return 0.0;
  double best = INFINITY;
  for (size_t i = 0; i < poly.vertices.size(); ++i) {
    const Eigen::Vector2d a = poly.vertices[i], b = poly.vertices[(i + 1) % poly.vertices.size()];
    const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
    best = std::min(best, (a + t * (b - a) - p).norm());
  }
  return best;
}

// The outcome of a run from the controller's summary (`run_json`: result, reason, steps, commands, faults), the robot's
// true final position (`driver_json`: position) and the run's log.
RunOutcome Outcome(const Setup& su, int r, std::uint64_t seed, const Eigen::Vector2d& start, const fs::path& rd,
                   const nlohmann::json& run_json, const nlohmann::json& driver_json, double run_s,
                   const nlohmann::json& commands) {
  RunOutcome out;
  out.trace = ReadTrace(rd / "run.lcmlog");
  const Trace& trace = out.trace;
  Eigen::Vector2d final_pos(NAN, NAN);
  if (driver_json.contains("position")) {
    final_pos = Eigen::Vector2d(driver_json["position"][0].get<double>(), driver_json["position"][1].get<double>());
  }
  const double error = std::isfinite(final_pos.x()) ? DistanceToPolygon(su.scene->goal.polygon, final_pos) : INFINITY;
  const bool done = run_json.value("result", "") == "done";
  out.ok = done && error == 0.0;
  auto number_or_null = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); };
  out.item = {{"run", r},
              {"seed", seed},
              {"start", {start.x(), start.y()}},
              {"result", run_json.value("result", "no result")},
              {"reason", run_json.value("reason", "")},
              {"steps_completed", run_json.value("steps_completed", 0)},
              {"commands_sent", run_json.value("commands_sent", 0)},
              {"faults_published", run_json.value("faults_published", 0)},
              {"visual_events", trace.events},
              {"contacts", trace.contacts.size()},
              {"logged_messages", trace.messages},
              {"time_s", run_s},
              {"motion_s", number_or_null(trace.motion_s)},
              {"final_position",
               std::isfinite(final_pos.x()) ? nlohmann::json({final_pos.x(), final_pos.y()}) : nlohmann::json()},
              {"goal_error_m", number_or_null(error)},
              {"success", out.ok},
              {"commands", commands}};
  return out;
}

// One closed-loop run in lockstep: `visco sim --lockstep`, one process on a simulated clock (the driver and the
// simulated robot, the rendered camera, vision and the controller with the demo's settings), which writes run.lcmlog
// (every message, the controller's records) and its summary (lockstep.json: the controller's result and the robot's
// true final position).
RunOutcome ExecuteLockstepRun(const Setup& su, int r, std::uint64_t seed, const Eigen::Vector2d& start,
                              const fs::path& rd, std::mutex& print) {
  const Options& a = *su.options;
  const fs::path& dir = su.dir;
  std::vector<std::string> args = {(dir / "scene.json").string(),
                                   "--lockstep",
                                   "--strategy",
                                   (dir / "plan.json").string(),
                                   "--rays",
                                   (dir / "rays.json").string(),
                                   "--start",
                                   fmt::format("{}", start.x()),
                                   fmt::format("{}", start.y()),
                                   "--seed",
                                   std::to_string(seed),
                                   "--watchdog-ms",
                                   Slowed(a, 500),
                                   "--duration",
                                   fmt::format("{}", a.timeout_s * a.slow),
                                   "--log",
                                   (rd / "run.lcmlog").string()};
  args.insert(args.end(), su.cam.begin(), su.cam.end());
  args.insert(args.end(), {"--camera-hz", fmt::format("{}", std::max(2.0, std::round(15 / a.slow))), "--supersample",
                           a.slow > 1 ? "1" : "2", "--latency-ms", "5", "--image-noise",
                           fmt::format("{}", a.image_noise), "--blur-px", fmt::format("{}", a.blur_px)});
  if (a.png_level >= 0) args.insert(args.end(), {"--png-level", std::to_string(a.png_level)});
  fs::create_directories(rd / "params");
  const std::vector<std::string> argv = WithParameterFile(su.self, "sim", args, rd / "params" / "lockstep.json");
  nlohmann::json commands = {{"lockstep", argv}};
  Child child = Spawn("lockstep", argv, rd / "lockstep.json", rd / "lockstep.log");
  const auto started = Clock::now();
  int last_report = -1;
  while (!Poll(child) && !su.stop->load()) {
    const double elapsed = std::chrono::duration<double>(Clock::now() - started).count();
    if (a.runs == 1 && static_cast<int>(elapsed) / 5 != last_report) {
      last_report = static_cast<int>(elapsed) / 5;
      std::lock_guard<std::mutex> lock(print);
      std::fprintf(stderr, "visco demo: executing in lockstep (simulated clock), %.0f s\n", elapsed);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  std::vector<Child> all = {child};
  Stop(all);
  const double run_s = std::chrono::duration<double>(Clock::now() - started).count();
  nlohmann::json summary = ReadJson(rd / "lockstep.json");
  const bool have_summary = !summary.empty();
  RunOutcome out = Outcome(su, r, seed, start, rd, summary, summary, run_s, commands);
  out.item["simulated_s"] = summary.value("simulated_s", 0.0);
  if (!have_summary)
    out.item["reason"] = "the lockstep run ended without a summary (see " + (rd / "lockstep.log").string() + ")";
  if (a.runs > 1 && out.ok && !a.keep_logs) fs::remove(rd / "run.lcmlog");
  out.item["logs_kept"] = fs::exists(rd / "run.lcmlog");
  return out;
}

}  // namespace

RunOutcome ExecuteRun(const Setup& su, int r, std::uint64_t seed, const Eigen::Vector2d& start, const fs::path& rd,
                      const std::string& url, const NetnsHosts* hosts, std::mutex& print) {
  const Options& a = *su.options;
  const fs::path& dir = su.dir;
  // Every process on the bus receives the camera's images (300 kB each) whether it subscribes or not: without a
  // large receive buffer the kernel drops the datagrams behind them, commands and statuses included (measured: 19
  // commands in a row lost by the driver, a sequence fault, with two runs at once).
  const std::string bus = url + "&recv_buf_size=4194304";
  fs::create_directories(rd);
  if (a.lockstep) return ExecuteLockstepRun(su, r, seed, start, rd, print);
  // The host each process runs on (with --netns).
  const std::vector<std::pair<std::string, std::string>> host_of = {{"lcm-logger", "logger"}, {"driver", "robot"},
                                                                    {"camera", "camera"},     {"capture", "camera"},
                                                                    {"track", "vision"},      {"run", "controller"}};
  auto on_host = [&](const std::string& name, const std::vector<std::string>& argv) {
    if (hosts == nullptr) return argv;
    for (const auto& [process, host] : host_of) {
      if (process == name) return hosts->Wrap(host, argv);
    }
    return argv;
  };
  std::vector<Child> children;
  nlohmann::json commands = nlohmann::json::object();  // what ran, for summary.json (repeatable by hand)
  auto spawn = [&commands](const std::string& name, const std::vector<std::string>& argv, const fs::path& out,
                           const fs::path& err) {
    commands[name] = argv;
    return Spawn(name, argv, out, err);
  };
  children.push_back(spawn(
      "lcm-logger",
      on_host("lcm-logger", {"lcm-logger", "--lcm-url=" + bus, "--quiet", "--force", (rd / "run.lcmlog").string()}),
      rd / "logger.out", rd / "logger.log"));
  // The robot: the driver process (the real-time binary) driving the simulated robot among the scene's C-obstacles
  // (the world file), publishing the robot's true state for the camera.
  std::vector<std::string> driver = {"--world",
                                     (dir / "world.json").string(),
                                     "--start",
                                     fmt::format("{}", start.x()),
                                     fmt::format("{}", start.y()),
                                     "--seed",
                                     std::to_string(seed),
                                     "--lcm-url",
                                     bus,
                                     "--duration",
                                     fmt::format("{}", a.timeout_s * a.slow + 30),
                                     "--watchdog-ms",
                                     Slowed(a, 500),
                                     "--truth-hz",
                                     Rate(a, 200)};
  // The real-time loops at the machine's pace too: on an emulated CPU the driver's 1 kHz robot update and the
  // controller's 500 Hz loop (each command answered by a status) would take the CPU the camera and vision need.
  if (a.slow > 1) driver.insert(driver.end(), {"--period-us", fmt::format("{:.0f}", 1000 * a.slow)});
  if (a.can) {
    driver.push_back("--can");
    driver.push_back("vcan0");
  }
  fs::create_directories(rd / "params");
  children.push_back(spawn("driver",
                           on_host("driver", WithParameterFile(su.rt, "driver", driver, rd / "params" / "driver.json")),
                           rd / "driver.json", rd / "driver.log"));
  // The camera: renders the tags at the robot's true pose (or, for other scenes, reports visual events directly).
  std::vector<std::string> camera = {(dir / "scene.json").string(),
                                     "--no-driver",
                                     "--rays",
                                     (dir / "rays.json").string(),
                                     "--seed",
                                     std::to_string(seed),
                                     "--lcm-url",
                                     bus,
                                     "--duration",
                                     fmt::format("{}", a.timeout_s * a.slow + 30)};
  // On a slow machine fewer frames, rendered without supersampling, so that vision keeps up with them.
  const double camera_hz = std::max(2.0, std::round(15 / a.slow));
  const bool v4l2 = !a.v4l2_output.empty();
  if (su.rendered) {
    camera.insert(camera.end(), su.cam.begin(), su.cam.end());
    camera.insert(camera.end(),
                  {"--camera-hz", fmt::format("{}", camera_hz), "--supersample", a.slow > 1 ? "1" : "2", "--latency-ms",
                   "5", "--image-noise", fmt::format("{}", a.image_noise), "--blur-px", fmt::format("{}", a.blur_px)});
    if (v4l2) camera.insert(camera.end(), {"--v4l2-output", a.v4l2_output});
    if (a.png_level >= 0 && !v4l2) camera.insert(camera.end(), {"--png-level", std::to_string(a.png_level)});
  }
  if (v4l2) {
    // The camera process of a real camera: it captures what the rendered camera wrote to the output device and
    // publishes it with the calibration. The device's loop may run faster than the renderer (vivid's HDMI at
    // 59.94 Hz): twice the rendering rate keeps every rendered frame without flooding the bus with repeats. On a
    // slow machine the rendering rate: vision could not take twice as many frames (some rendered frame may then be
    // skipped, another captured twice).
    const double capture_hz = a.slow > 1 ? camera_hz : 2 * camera_hz;
    std::vector<std::string> capture = {"--device",       a.v4l2_capture,
                                        "--width",        std::to_string(su.image_width),
                                        "--height",       std::to_string(su.image_height),
                                        "--pixel-format", "GREY",
                                        "--max-fps",      fmt::format("{}", capture_hz),
                                        "--timeout-ms",   Slowed(a, 1000),
                                        "--lcm-url",      bus};
    if (a.v4l2_input >= 0) capture.insert(capture.end(), {"--input", std::to_string(a.v4l2_input)});
    capture.insert(capture.end(), su.cam.begin(), su.cam.begin() + 4);  // --camera, --extrinsics
    if (a.png_level >= 0) capture.insert(capture.end(), {"--png-level", std::to_string(a.png_level)});
    children.push_back(spawn(
        "capture", on_host("capture", WithParameterFile(su.self, "capture", capture, rd / "params" / "capture.json")),
        rd / "capture.jsonl", rd / "capture.log"));
  }
  children.push_back(spawn("camera",
                           on_host("camera", WithParameterFile(su.self, "sim", camera, rd / "params" / "camera.json")),
                           rd / "camera.json", rd / "camera.log"));
  if (su.rendered) {
    std::vector<std::string> track = {"--lcm", "--lcm-url", bus};
    track.insert(track.end(), su.cam.begin(), su.cam.end());
    // On a slow machine the full detections find the quads at half resolution (about 3x faster).
    if (a.slow > 1) track.insert(track.end(), {"--decimate", "2"});
    children.push_back(spawn("track",
                             on_host("track", WithParameterFile(su.self, "track", track, rd / "params" / "track.json")),
                             rd / "track.jsonl", rd / "track.log"));
  }
  std::vector<std::string> run = {(dir / "plan.json").string(),
                                  "--scene",
                                  (dir / "scene.json").string(),
                                  "--rays",
                                  (dir / "rays.json").string(),
                                  "--lcm-url",
                                  bus,
                                  "--max-speed",
                                  "1.0",
                                  "--max-accel",
                                  "4",
                                  "--max-vision-age-ms",
                                  Slowed(a, 400),
                                  "--max-hold",
                                  Slowed(a, 4),
                                  "--startup-timeout",
                                  Slowed(a, 30),
                                  "--status-timeout-ms",
                                  Slowed(a, 500),
                                  "--heartbeat-timeout-ms",
                                  Slowed(a, 1000),
                                  "--rate",
                                  Rate(a, 500, 10),  // visco run's lowest
                                  "--telemetry-hz",
                                  Rate(a, 50),
                                  "--no-realtime",
                                  "--log",
                                  (rd / "controller.lcmlog").string()};
  // The servo law's interaction from the camera's calibration and pose (the files vision reads).
  if (su.rendered) run.insert(run.end(), su.cam.begin(), su.cam.end());
  if (a.can) {
    run.push_back("--can");
    run.push_back("vcan0");
  }
  Child controller = spawn("run", on_host("run", WithParameterFile(su.self, "run", run, rd / "params" / "run.json")),
                           rd / "run.json", rd / "run.log");
  const auto started = Clock::now();
  int last_report = -1;
  bool failed_early = false;
  // With --netns: the network namespace each process was seen in, once it had time to enter its own.
  std::map<std::string, std::uint64_t> seen_in;
  while (!Poll(controller) && !su.stop->load()) {
    const double elapsed = std::chrono::duration<double>(Clock::now() - started).count();
    if (hosts != nullptr && seen_in.empty() && elapsed > 1.5) {
      for (const Child& c : children) seen_in[c.name] = NetnsHosts::ProcessNamespaceInode(c.pid);
      seen_in[controller.name] = NetnsHosts::ProcessNamespaceInode(controller.pid);
    }
    if (elapsed > a.timeout_s * a.slow) break;
    for (auto& c : children) {
      if (Poll(c) && c.name != "lcm-logger") failed_early = true;
    }
    if (failed_early) break;
    if (a.runs == 1 && static_cast<int>(elapsed) / 5 != last_report) {
      last_report = static_cast<int>(elapsed) / 5;
      std::lock_guard<std::mutex> lock(print);
      std::fprintf(stderr, "visco demo: executing, %.0f s\n", elapsed);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  std::vector<Child> all = children;
  all.push_back(controller);
  Stop(all);
  const double run_s = std::chrono::duration<double>(Clock::now() - started).count();
  const nlohmann::json run_json = ReadJson(rd / "run.json");
  const nlohmann::json driver_json = ReadJson(rd / "driver.json");  // the robot's true final position
  RunOutcome out = Outcome(su, r, seed, start, rd, run_json, driver_json, run_s, commands);
  if (run_json.empty()) out.item["reason"] = "visco run wrote no summary (see run.log in " + rd.string() + ")";
  if (v4l2) {
    // What went through the devices: frames written, captured, dropped by the driver, held back.
    const nlohmann::json camera_json = ReadJson(rd / "camera.json");
    out.item["v4l2_output"] = camera_json.value("v4l2_output", nlohmann::json());
    nlohmann::json capture = nlohmann::json();
    const std::string lines = ReadText(rd / "capture.jsonl");
    const std::size_t at = lines.rfind("{\"summary\"");
    if (at != std::string::npos) {
      try {
        capture = nlohmann::json::parse(lines.substr(at)).at("summary");
      } catch (const std::exception&) {
      }
    }
    out.item["capture"] = capture;
  }
  if (failed_early) out.item["reason"] = "a process ended early (see its log in " + rd.string() + ")";
  if (hosts != nullptr) {
    // Where each process ran: its host's namespace (name, address, inode) and the namespace it was seen in.
    nlohmann::json netns = nlohmann::json::object();
    for (const auto& [process, host] : host_of) {
      if (seen_in.count(process) == 0) continue;
      netns[process] = {{"host", host},
                        {"namespace", hosts->Namespace(host)},
                        {"address", hosts->Address(host)},
                        {"namespace_inode", NetnsHosts::NamespaceInode(hosts->Namespace(host))},
                        {"seen_in_inode", seen_in[process]}};
    }
    out.item["netns"] = netns;
    out.item["demo_netns_inode"] = NetnsHosts::ProcessNamespaceInode(getpid());
  }
  // Monte Carlo keeps the logs of the runs to debug (failures), not of every success (tens of MB each, images).
  if (a.runs > 1 && out.ok && !a.keep_logs) {
    fs::remove(rd / "run.lcmlog");
    fs::remove(rd / "controller.lcmlog");
  }
  out.item["logs_kept"] = fs::exists(rd / "run.lcmlog");
  return out;
}

}  // namespace visco::app::demo

// `visco demo`: the whole system on the embedded default scene (or --scene FILE). It plans (`visco plan`), then
// executes the strategy in closed loop as separate processes talking LCM, as on real hardware:
//   visco-rt driver  the robot driver driving the simulated robot (drivers/simulated_robot.h: the motion model of
//                docs/semantics.md with a seeded adversary) among the scene's C-obstacles (DIR/world.json), with
//                the robot's true state on VISCO_SIM_TRUTH;
//   visco sim --no-driver  the rendered camera (the AprilTags of robot and obstacles at that true state, as images);
//   visco track  the vision pipeline (detection, tracking, poses, CM vertices, visual events);
//   visco run    the controller (visual guarded and compliant motions, contact, goal);
//   lcm-logger   every channel into DIR/run.lcmlog.
// The demo supervises them: Ctrl-C or any failure stops all of them (they also die with the demo: PR_SET_PDEATHSIG).
// Outputs in DIR: scene.json, world.json, rays.json, plan.json, plan.svg, run.svg, run.lcmlog, summary.json, and each
// process's output and log.

#include "app/demo.h"

#include <fmt/format.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "app/netns_hosts.h"
#include "app/parameter_file.h"
#include "app/paths.h"
#include "app/sim/world.h"
#include "common/error.h"
#include "common/write_output.h"
#include "drivers/simulated_robot_options.h"
#include "lcmtypes/channels.h"
#include "planning/cspace.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "planning/strategy.h"
#include "planning/svg.h"
#include "planning/vc_rays.h"
#include "visco/robot_estimate_t.hpp"
#include "visco/robot_status_t.hpp"
#include "visco/velocity_command_t.hpp"
#include "visco/visual_events_t.hpp"

#ifndef VISCO_SOURCE_DATA_DIR
#define VISCO_SOURCE_DATA_DIR "data"
#endif

namespace visco::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::atomic<int> g_signal{0};
void OnSignal(int sig) { g_signal = sig; }

struct Args {
  std::string out;
  std::string scene;
  std::uint64_t seed = 1;
  bool can = false;
  int runs = 1;
  int jobs = 1;
  bool keep_logs = false;
  double timeout_s = 120;
  double speed = 0.6;
  bool netns = false;
  bool lockstep = false;  // one process on a simulated clock (`visco sim --lockstep`) instead of the five
  double slow = 1;        // --slow-machine: time limits times this, camera rate and speed divided by it
};

// A time limit of the demo's processes on a machine `a.slow` times slower than the 2-core reference.
std::string Slowed(const Args& a, double value) { return fmt::format("{}", value * a.slow); }

struct Child {
  std::string name;
  pid_t pid = -1;
  int status = -1;
  bool exited = false;
};

// Starts `argv` with stdout and stderr redirected; the child dies with the demo.
Child Spawn(const std::string& name, const std::vector<std::string>& argv, const fs::path& out, const fs::path& err) {
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) throw JobFailed("cannot start " + name + ": fork failed");
  if (pid == 0) {
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() != parent) _exit(126);
    if (!freopen(out.c_str(), "w", stdout) || !freopen(err.c_str(), "w", stderr)) _exit(126);
    std::vector<char*> cargv;
    for (const auto& a : argv) cargv.push_back(const_cast<char*>(a.c_str()));
    cargv.push_back(nullptr);
    execvp(cargv[0], cargv.data());
    std::fprintf(stderr, "cannot execute %s\n", cargv[0]);
    _exit(127);
  }
  return {name, pid, -1, false};
}

// The command line of `exe command args...` that takes its options from a parameter file (app/parameter_file.h),
// written to `params`: the positionals stay on the command line. A user repeats the run from these files.
std::vector<std::string> WithParameterFile(const std::string& exe, const std::string& command,
                                           const std::vector<std::string>& args, const fs::path& params) {
  WriteTextOutput(ParameterFileJson(command, args), params.string());
  std::vector<std::string> argv = {exe, command};
  for (const std::string& a : args) {
    if (a.rfind("--", 0) == 0) break;
    argv.push_back(a);
  }
  argv.push_back("--config");
  argv.push_back(params.string());
  return argv;
}

bool Poll(Child& c) {
  if (c.exited) return true;
  int status = 0;
  if (waitpid(c.pid, &status, WNOHANG) == c.pid) {
    c.exited = true;
    c.status = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }
  return c.exited;
}

// SIGINT, then SIGKILL after `grace`: no orphans.
void Stop(std::vector<Child>& children, std::chrono::milliseconds grace = std::chrono::milliseconds(4000)) {
  for (auto& c : children) {
    if (!Poll(c)) kill(c.pid, SIGINT);
  }
  const auto deadline = Clock::now() + grace;
  for (auto& c : children) {
    while (!Poll(c) && Clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (!Poll(c)) {
      kill(c.pid, SIGKILL);
      int status = 0;
      waitpid(c.pid, &status, 0);
      c.exited = true;
      c.status = 128 + SIGKILL;
    }
  }
}

std::string ReadText(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A process's JSON output, or an empty object when it wrote none or only part of one (it was killed, or failed
// early): the run is then reported as failed with "no result", never as an exception from the fields read.
nlohmann::json ReadJson(const fs::path& p) {
  try {
    nlohmann::json j = nlohmann::json::parse(ReadText(p));
    return j.is_object() ? j : nlohmann::json::object();
  } catch (const std::exception&) {
    return nlohmann::json::object();
  }
}

// The trajectory (vision's estimates), visual events and contacts from the LCM log (lcm-logger's format).
struct Trace {
  std::vector<Eigen::Vector2d> path;
  std::vector<Eigen::Vector2d> crossings;  // where a visual event reported a crossing
  std::vector<Eigen::Vector2d> contacts;   // where contact started
  int events = 0;
  int messages = 0;
  double motion_s = NAN;  // first to last non-zero velocity command (the log's receive times)
};

// LCM's generated decoders store doubles through integer pointers; with a value-initialised message ({}) GCC at -O2
// may keep the zeros it knows of (measured: every position read back as 0). Decode into a default-initialised one:
// the decoder writes every field.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
template <typename Message>
bool Decode(const lcm::LogEvent& e, Message* out) {
  return out->decode(e.data, 0, e.datalen) >= 0;
}

Trace ReadTrace(const fs::path& log) {
  Trace t;
  lcm::LogFile file(log.string(), "r");
  if (!file.good()) return t;
  bool in_contact = false;
  Eigen::Vector2d last(NAN, NAN);
  std::int64_t first_move = -1, last_move = -1;
  while (const lcm::LogEvent* e = file.readNextEvent()) {
    ++t.messages;
    if (e->channel == channels::kCommand) {
      velocity_command_t c;
      if (!Decode(*e, &c) || (c.velocity[0] == 0 && c.velocity[1] == 0)) continue;
      if (first_move < 0) first_move = e->timestamp;
      last_move = e->timestamp;
    } else if (e->channel == channels::kRobotEstimate) {
      // The trajectory as vision saw it (the driver's status carries odometry, zero in the simulation).
      robot_estimate_t s;
      if (!Decode(*e, &s) || !s.valid) continue;
      const Eigen::Vector2d p(s.position[0], s.position[1]);
      if (t.path.empty() || (p - t.path.back()).norm() > 0.01) t.path.push_back(p);
      last = p;
    } else if (e->channel == channels::kStatus) {
      robot_status_t s;
      if (!Decode(*e, &s)) continue;
      if (s.contact && !in_contact && std::isfinite(last.x())) t.contacts.push_back(last);
      in_contact = s.contact;
    } else if (e->channel == channels::kVisualEvents) {
      visual_events_t v;
      if (!Decode(*e, &v)) continue;
      for (const auto& ev : v.events) {
        if (ev.crossed && std::isfinite(last.x())) {
          ++t.events;
          t.crossings.push_back(last);
        }
      }
    }
  }
  if (first_move >= 0) t.motion_s = static_cast<double>(last_move - first_move) * 1e-6;
  return t;
}
#pragma GCC diagnostic pop

std::string RunSvg(const planning::Scene& scene, const planning::CSpace& cspace, const planning::Strategy& strategy,
                   const Trace& trace) {
  // The plan's picture underneath, the executed trajectory over it.
  planning::SvgCanvas c(scene.bounds.min, scene.bounds.max, 700);
  planning::DrawStrategy(c, scene, cspace, strategy);
  for (size_t i = 1; i < trace.path.size(); ++i) {
    c.Line(trace.path[i - 1], trace.path[i], "class=\"trajectory\" stroke=\"#c00\" stroke-width=\"2.5\"");
  }
  for (const auto& p : trace.crossings)
    c.Circle(p, 6, "class=\"vc-event\" fill=\"none\" stroke=\"#90c\" stroke-width=\"3\"");
  for (const auto& p : trace.contacts) c.Circle(p, 4, "class=\"contact\" fill=\"#f80\" stroke=\"none\"");
  if (!trace.path.empty()) c.Circle(trace.path.back(), 5, "class=\"end\" fill=\"#c00\" stroke=\"black\"");
  c.TextPx(10, 18,
           fmt::format("{}: the executed trajectory over the plan (steps numbered from 0, as in the logs)", scene.name),
           13, "fill=\"black\"");
  auto legend = planning::StrategyLegend(strategy);
  legend.push_back({{"━", "#c00", "executed trajectory (vision's estimates)"},
                    {"○", "#90c", "visual event"},
                    {"●", "#f80", "contact"},
                    {"●", "#c00", "where it ended"}});
  c.Legend(legend);
  return c.Finish();
}

// Absolute: the parameter files and summary.json name the outputs, and must work from any directory.
fs::path FreshDir(const std::string& requested) {
  if (!requested.empty()) {
    fs::create_directories(requested);
    return fs::absolute(requested).lexically_normal();
  }
  for (int k = 1;; ++k) {
    const fs::path p = fmt::format("visco-demo-{}", k);
    if (!fs::exists(p)) {
      fs::create_directories(p);
      return fs::absolute(p).lexically_normal();
    }
  }
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

void Progress(const char* what) {
  std::fprintf(stderr, "visco demo: %s\n", what);
  std::fflush(stderr);
}

// What every run of one demo shares.
struct Setup {
  const Args* args = nullptr;
  const planning::Scene* scene = nullptr;
  const planning::CSpace* cspace = nullptr;
  const planning::Strategy* strategy = nullptr;
  fs::path dir;
  std::string self;  // this visco executable
  std::string rt;    // visco-rt beside it (the driver process)
  bool rendered = false;
  std::vector<std::string> cam;  // camera files of the rendered default scene
};

struct RunOutcome {
  nlohmann::json item;
  Trace trace;
  bool ok = false;
};

// The starts: the start region's centroid for one run; for Monte Carlo, seeded points of the start region, every
// fourth on its boundary (the strategy is guaranteed for the closed region, its boundary included).
std::vector<Eigen::Vector2d> SampleStarts(const planning::Polygon& region, int runs, std::uint64_t seed) {
  const auto& sv = region.vertices;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (const auto& v : sv) centroid += v / static_cast<double>(sv.size());
  if (runs == 1) return {centroid};
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  Eigen::Vector2d lo = sv[0], hi = sv[0];
  for (const auto& v : sv) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
  double perimeter = 0;
  for (size_t i = 0; i < sv.size(); ++i) perimeter += (sv[(i + 1) % sv.size()] - sv[i]).norm();
  std::vector<Eigen::Vector2d> starts;
  for (int r = 0; r < runs; ++r) {
    Eigen::Vector2d q = centroid;
    if (r % 4 == 3) {
      double along = u(rng) * perimeter;
      for (size_t i = 0; i < sv.size(); ++i) {
        const Eigen::Vector2d a = sv[i], b = sv[(i + 1) % sv.size()];
        const double len = (b - a).norm();
        if (along <= len || i + 1 == sv.size()) {
          q = a + (b - a) * std::clamp(along / len, 0.0, 1.0);
          break;
        }
        along -= len;
      }
    } else {
      for (int k = 0; k < 1000; ++k) {
        const Eigen::Vector2d p(lo.x() + u(rng) * (hi.x() - lo.x()), lo.y() + u(rng) * (hi.y() - lo.y()));
        if (planning::InsideEvenOdd(sv, p)) {
          q = p;
          break;
        }
      }
    }
    starts.push_back(q);
  }
  return starts;
}

// The outcome of a run from the controller's summary (`run_json`: result, reason, steps, commands, faults), the robot's
// true final position (`driver_json`: position) and the run's log.
RunOutcome Outcome(const Setup& su, int r, std::uint64_t seed, const Eigen::Vector2d& start, const fs::path& rd,
                   const nlohmann::json& run_json, const nlohmann::json& driver_json, double run_s,
                   const nlohmann::json& commands) {
  const Args& a = *su.args;
  RunOutcome out;
  out.trace = ReadTrace(rd / "run.lcmlog");
  const Trace& trace = out.trace;
  if (a.runs == 1) WriteTextOutput(RunSvg(*su.scene, *su.cspace, *su.strategy, trace), (rd / "run.svg").string());
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
  const Args& a = *su.args;
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
                           a.slow > 1 ? "1" : "2", "--latency-ms", "5", "--image-noise", "2", "--blur-px", "0.5"});
  fs::create_directories(rd / "params");
  const std::vector<std::string> argv = WithParameterFile(su.self, "sim", args, rd / "params" / "lockstep.json");
  nlohmann::json commands = {{"lockstep", argv}};
  Child child = Spawn("lockstep", argv, rd / "lockstep.json", rd / "lockstep.log");
  const auto started = Clock::now();
  int last_report = -1;
  while (!Poll(child) && g_signal == 0) {
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

// One closed-loop run: the processes, supervised until the controller ends, the run's timeout, a process that ends
// early, or Ctrl-C; then the outcome from their outputs and the log.
// With `hosts`, each process runs on a host of its own (a network namespace; NetnsHosts).
RunOutcome ExecuteRun(const Setup& su, int r, std::uint64_t seed, const Eigen::Vector2d& start, const fs::path& rd,
                      const std::string& url, const app::NetnsHosts* hosts, std::mutex& print) {
  const Args& a = *su.args;
  const fs::path& dir = su.dir;
  // Every process on the bus receives the camera's images (300 kB each) whether it subscribes or not: without a
  // large receive buffer the kernel drops the datagrams behind them, commands and statuses included (measured: 19
  // commands in a row lost by the driver, a sequence fault, with two runs at once).
  const std::string bus = url + "&recv_buf_size=4194304";
  fs::create_directories(rd);
  if (a.lockstep) return ExecuteLockstepRun(su, r, seed, start, rd, print);
  // The host each process runs on (with --netns).
  const std::vector<std::pair<std::string, std::string>> host_of = {
      {"lcm-logger", "logger"}, {"driver", "robot"}, {"camera", "camera"}, {"track", "vision"}, {"run", "controller"}};
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
                                     "200"};
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
  if (su.rendered) {
    camera.insert(camera.end(), su.cam.begin(), su.cam.end());
    // On a slow machine fewer frames, rendered without supersampling, so that vision keeps up with them.
    camera.insert(camera.end(),
                  {"--camera-hz", fmt::format("{}", std::max(2.0, std::round(15 / a.slow))), "--supersample",
                   a.slow > 1 ? "1" : "2", "--latency-ms", "5", "--image-noise", "2", "--blur-px", "0.5"});
  }
  children.push_back(spawn("camera",
                           on_host("camera", WithParameterFile(su.self, "sim", camera, rd / "params" / "camera.json")),
                           rd / "camera.json", rd / "camera.log"));
  if (su.rendered) {
    std::vector<std::string> track = {"--lcm", "--lcm-url", bus};
    track.insert(track.end(), su.cam.begin(), su.cam.end());
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
  while (!Poll(controller) && g_signal == 0) {
    const double elapsed = std::chrono::duration<double>(Clock::now() - started).count();
    if (hosts != nullptr && seen_in.empty() && elapsed > 1.5) {
      for (const Child& c : children) seen_in[c.name] = app::NetnsHosts::ProcessNamespaceInode(c.pid);
      seen_in[controller.name] = app::NetnsHosts::ProcessNamespaceInode(controller.pid);
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
  if (failed_early) out.item["reason"] = "a process ended early (see its log in " + rd.string() + ")";
  if (hosts != nullptr) {
    // Where each process ran: its host's namespace (name, address, inode) and the namespace it was seen in.
    nlohmann::json netns = nlohmann::json::object();
    for (const auto& [process, host] : host_of) {
      if (seen_in.count(process) == 0) continue;
      netns[process] = {{"host", host},
                        {"namespace", hosts->Namespace(host)},
                        {"address", hosts->Address(host)},
                        {"namespace_inode", app::NetnsHosts::NamespaceInode(hosts->Namespace(host))},
                        {"seen_in_inode", seen_in[process]}};
    }
    out.item["netns"] = netns;
    out.item["demo_netns_inode"] = app::NetnsHosts::ProcessNamespaceInode(getpid());
  }
  // Monte Carlo keeps the logs of the runs to debug (failures), not of every success (tens of MB each, images).
  if (a.runs > 1 && out.ok && !a.keep_logs) {
    fs::remove(rd / "run.lcmlog");
    fs::remove(rd / "controller.lcmlog");
  }
  out.item["logs_kept"] = fs::exists(rd / "run.lcmlog");
  return out;
}

double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const double at = q * static_cast<double>(v.size() - 1);
  const size_t i = static_cast<size_t>(std::floor(at));
  const size_t j = std::min(i + 1, v.size() - 1);
  return v[i] + (v[j] - v[i]) * (at - static_cast<double>(i));
}

// A histogram panel: `values` in `bins` bins over [min, max] of the values; bars, axis, ticks, the median.
planning::SvgCanvas HistogramPanel(const std::vector<double>& values, const std::string& title, const std::string& unit,
                                   int bins = 20) {
  // World frame of the panel: x in [0, 1] along the values, y in [0, 0.75] along the counts.
  planning::SvgCanvas c({-0.08, -0.12}, {1.04, 0.85}, 380);
  c.TextPx(10, 18, title, 13, "fill=\"black\"");
  if (values.empty()) {
    c.Text({0.5, 0.4}, "no values", 12, "fill=\"#666\" text-anchor=\"middle\"");
    return c;
  }
  const double lo = *std::min_element(values.begin(), values.end());
  double hi = *std::max_element(values.begin(), values.end());
  if (hi - lo < 1e-9) hi = lo + 1;
  std::vector<int> count(static_cast<size_t>(bins), 0);
  for (double v : values) {
    const int b = std::clamp(static_cast<int>((v - lo) / (hi - lo) * bins), 0, bins - 1);
    ++count[static_cast<size_t>(b)];
  }
  const int top = *std::max_element(count.begin(), count.end());
  for (int b = 0; b < bins; ++b) {
    if (count[static_cast<size_t>(b)] == 0) continue;
    const double x0 = static_cast<double>(b) / bins, x1 = static_cast<double>(b + 1) / bins;
    const double h = 0.75 * count[static_cast<size_t>(b)] / top;
    planning::Polygon bar;
    bar.vertices = {{x0, 0}, {x1, 0}, {x1, h}, {x0, h}};
    c.Polygon(bar, "class=\"bar\" fill=\"#4a7\" stroke=\"white\" stroke-width=\"1\"");
  }
  c.Line({0, 0}, {1, 0}, "stroke=\"black\" stroke-width=\"1\"");
  c.Line({0, 0}, {0, 0.75}, "stroke=\"black\" stroke-width=\"1\"");
  for (int k = 0; k <= 4; ++k) {
    const double x = k / 4.0;
    c.Line({x, 0}, {x, -0.015}, "stroke=\"black\" stroke-width=\"1\"");
    c.Text({x, -0.015}, fmt::format("{:.3g}", lo + x * (hi - lo)), 11, "fill=\"black\" text-anchor=\"middle\"", 0, 13);
  }
  c.Text({1.0, -0.015}, unit, 11, "fill=\"black\" text-anchor=\"end\"", 0, 27);
  c.Text({0, 0.75}, std::to_string(top), 11, "fill=\"black\" text-anchor=\"end\"", -4, 4);
  const double median = Quantile(values, 0.5);
  const double mx = (median - lo) / (hi - lo);
  c.Line({mx, 0}, {mx, 0.78}, "class=\"median\" stroke=\"#c00\" stroke-width=\"1.5\" stroke-dasharray=\"4 3\"");
  c.Text({mx, 0.78}, fmt::format("median {:.3g}", median), 11, "fill=\"#c00\" text-anchor=\"middle\"", 0, -4);
  return c;
}

// The Monte Carlo figure: every run's trajectory over the plan (green: reached the goal, red: did not; dots: starts),
// and histograms of the motion time and the commands sent.
std::string MonteCarloSvg(const Setup& su, const std::vector<RunOutcome>& outcomes) {
  planning::SvgCanvas plan(su.scene->bounds.min, su.scene->bounds.max, 520);
  planning::DrawStrategy(plan, *su.scene, *su.cspace, *su.strategy);
  std::vector<double> times, commands;
  int ok = 0;
  for (const auto& o : outcomes) {
    const std::string colour = o.ok ? "#2a2" : "#d00";
    for (size_t i = 1; i < o.trace.path.size(); ++i) {
      plan.Line(o.trace.path[i - 1], o.trace.path[i],
                "class=\"trajectory\" stroke=\"" + colour + "\" stroke-width=\"1\" stroke-opacity=\"0.5\"");
    }
    const Eigen::Vector2d s(o.item["start"][0].get<double>(), o.item["start"][1].get<double>());
    plan.Circle(s, 2.5, "class=\"start\" fill=\"" + colour + "\" stroke=\"none\"");
    ok += o.ok;
    if (o.ok && o.item["motion_s"].is_number()) times.push_back(o.item["motion_s"].get<double>());
    if (o.ok) commands.push_back(o.item["commands_sent"].get<double>());
  }
  plan.TextPx(10, 18,
              fmt::format("{}: {} of {} runs reached the goal ({:.1f} %)", su.scene->name, ok, outcomes.size(),
                          100.0 * ok / static_cast<double>(outcomes.size())),
              13, "fill=\"black\"");
  const planning::SvgCanvas time_panel = HistogramPanel(times, "time in motion (successful runs)", "s");
  const planning::SvgCanvas command_panel = HistogramPanel(commands, "velocity commands sent", "commands");
  return planning::SideBySide({{"runs", &plan}, {"motion-time", &time_panel}, {"commands", &command_panel}});
}

int Run(const Args& a) {
  if (a.runs < 1) throw InputError("command line", "--runs", "must be at least 1");
  if (!(a.speed > 0) || a.speed > 1.0) throw InputError("command line", "--speed", "must be in (0, 1] m/s");
  if (!(a.slow >= 1) || a.slow > 100) throw InputError("command line", "--slow-machine", "must be in [1, 100]");
  if (a.jobs < 1 || a.jobs > 8) throw InputError("command line", "--jobs", "must be between 1 and 8");
  if (a.lockstep && (a.can || a.netns)) {
    throw InputError("command line", a.can ? "--can" : "--netns",
                     "not with --lockstep (one process on a simulated clock, its bus in memory)");
  }
  if (a.lockstep && !a.scene.empty()) {
    throw InputError("command line", "--lockstep",
                     "runs the rendered camera, which only the embedded default scene has (data/sim/); not with "
                     "--scene");
  }
  if (a.can && !fs::exists("/sys/class/net/vcan0")) {
    throw InputError("command line", "--can",
                     "no vcan0 interface on this machine: create one (modprobe vcan; ip link add vcan0 type vcan; ip "
                     "link set up vcan0) or use the HIL VM (README, \"Hardware-in-the-loop on virtual CAN\")");
  }
  if (a.can && a.jobs > 1) throw InputError("command line", "--jobs", "runs over --can share vcan0: use --jobs 1");
  if (a.netns) {
    std::string why;
    if (!app::NetnsHosts::Available(&why)) throw InputError("command line", "--netns", why);
    if (a.can)
      throw InputError("command line", "--netns", "cannot be combined with --can (vcan0 lives in one namespace)");
  }
  const auto t0 = Clock::now();
  const fs::path dir = FreshDir(a.out);
  // The scene: the embedded default (no file needed) or the user's.
  std::string scene_text = a.scene.empty() ? std::string(planning::DefaultSceneJson()) : ReadText(a.scene);
  if (!a.scene.empty() && scene_text.empty()) throw InputError(a.scene, "", "cannot read the scene file");
  const planning::Scene scene = a.scene.empty() ? planning::DefaultScene() : planning::LoadScene(a.scene);
  if (!scene.start)
    throw InputError(a.scene.empty() ? "<embedded slot.json>" : a.scene, "start", "the demo needs a start region");
  WriteTextOutput(scene_text, (dir / "scene.json").string());
  const planning::CSpace cspace(scene);
  planning::VcRays rays;
  if (scene.camera) rays = planning::ComputeVcRays(scene, cspace);
  WriteTextOutput(planning::VcRaysToJson(scene, rays), (dir / "rays.json").string());

  Progress("planning (visco plan)");
  planning::PlanOptions po;
  po.threads = 2;
  const planning::Strategy strategy = planning::PlanStrategy(scene, po);
  WriteTextOutput(planning::StrategyToJson(scene, strategy, a.speed / a.slow), (dir / "plan.json").string());
  WriteTextOutput(planning::StrategyToSvg(scene, cspace, strategy), (dir / "plan.svg").string());
  if (!strategy.feasible) throw JobFailed("no strategy: " + strategy.reason);
  const double plan_s = std::chrono::duration<double>(Clock::now() - t0).count();
  std::fprintf(stderr, "visco demo: %zu step(s), planned in %.1f s\n", strategy.steps.size(), plan_s);

  Setup su;
  su.args = &a;
  su.scene = &scene;
  su.cspace = &cspace;
  su.strategy = &strategy;
  su.dir = dir;
  su.self = (ExecutableDir() / "visco").string();
  su.rt = (ExecutableDir() / "visco-rt").string();
  WriteTextOutput(drivers::WorldFileJson(sim::MakeWorldFile(scene)), (dir / "world.json").string());
  // The rendered camera for the default scene; other scenes get the synthetic camera (visual events without images).
  const fs::path data = VISCO_SOURCE_DATA_DIR;
  su.rendered = a.scene.empty() && fs::exists(data / "sim" / "slot_camera.xml");
  if (su.rendered) {
    su.cam = {"--camera",     (data / "sim" / "slot_camera.xml").string(),
              "--extrinsics", (data / "sim" / "slot_extrinsics.json").string(),
              "--objects",    (data / "sim" / "slot_objects.json").string()};
  }
  signal(SIGINT, OnSignal);
  signal(SIGTERM, OnSignal);

  // Starts are drawn before any run, so the outcome of run k does not depend on --jobs.
  const std::vector<Eigen::Vector2d> starts = SampleStarts(scene.start->polygon, a.runs, a.seed);
  std::vector<RunOutcome> outcomes(static_cast<size_t>(a.runs));
  std::vector<bool> finished(static_cast<size_t>(a.runs), false);
  std::atomic<int> next{0};
  std::mutex print;
  int completed = 0, successes = 0;
  // --netns: per job, a host per process (made here, on the main thread: a failure is an error, not a crash).
  std::vector<std::unique_ptr<app::NetnsHosts>> job_hosts(static_cast<size_t>(std::min(a.jobs, a.runs)));
  if (a.netns) {
    for (size_t j = 0; j < job_hosts.size(); ++j) {
      job_hosts[j] = std::make_unique<app::NetnsHosts>(
          fmt::format("visco{}j{}", getpid(), j),
          std::vector<std::string>{"robot", "camera", "vision", "controller", "logger"}, static_cast<int>(j) + 1);
    }
    std::fprintf(stderr,
                 "visco demo: every process on a host of its own (network namespaces such as %s at %s, LCM "
                 "multicast over a bridge, ttl=1)\n",
                 job_hosts[0]->Namespace("robot").c_str(), job_hosts[0]->Address("robot").c_str());
  }
  auto worker = [&](int job) {
    // Each job talks on its own multicast port, so simultaneous runs do not hear each other. Across hosts the
    // datagrams must leave the host: ttl=1 (one link; ttl=0 keeps them on the host).
    const std::string url =
        fmt::format("udpm://239.255.76.67:{}?ttl={}", 20000 + (getpid() % 5000) * 8 + job, a.netns ? 1 : 0);
    const app::NetnsHosts* hosts = job_hosts[static_cast<size_t>(job)].get();
    if (!a.lockstep) {  // (a lockstep run's bus is in its process's memory)
      std::lock_guard<std::mutex> lock(print);
      std::fprintf(stderr, "visco demo: %s talks LCM on %s (watch it: visco spy --lcm-url '%s')\n",
                   a.runs == 1 ? "the run" : fmt::format("job {}", job + 1).c_str(), url.c_str(), url.c_str());
    }
    for (int r = next++; r < a.runs && g_signal == 0; r = next++) {
      const std::uint64_t seed = a.seed + static_cast<std::uint64_t>(r);
      const fs::path rd = a.runs == 1 ? dir : dir / fmt::format("run{:03d}", r);
      RunOutcome o = ExecuteRun(su, r, seed, starts[static_cast<size_t>(r)], rd, url, hosts, print);
      std::lock_guard<std::mutex> lock(print);
      ++completed;
      successes += o.ok;
      if (a.runs > 1) {
        std::fprintf(stderr, "visco demo: run %d/%d (seed %llu): %s in %.1f s; %d of %d reached the goal so far\n",
                     completed, a.runs, static_cast<unsigned long long>(seed), o.ok ? "goal reached" : "FAILED",
                     o.item["time_s"].get<double>(), successes, completed);
      }
      outcomes[static_cast<size_t>(r)] = std::move(o);
      finished[static_cast<size_t>(r)] = true;
    }
  };
  std::vector<std::thread> jobs;
  for (int j = 0; j < std::min(a.jobs, a.runs); ++j) jobs.emplace_back(worker, j);
  for (auto& t : jobs) t.join();

  std::vector<RunOutcome> done_runs;
  nlohmann::json runs = nlohmann::json::array();
  for (int r = 0; r < a.runs; ++r) {
    if (!finished[static_cast<size_t>(r)]) continue;
    runs.push_back(outcomes[static_cast<size_t>(r)].item);
    done_runs.push_back(outcomes[static_cast<size_t>(r)]);
  }
  const double total_s = std::chrono::duration<double>(Clock::now() - t0).count();
  std::vector<double> motion, commands, events;
  for (const auto& o : done_runs) {
    if (!o.ok) continue;
    if (o.item["motion_s"].is_number()) motion.push_back(o.item["motion_s"].get<double>());
    commands.push_back(o.item["commands_sent"].get<double>());
    events.push_back(o.item["visual_events"].get<double>());
  }
  auto quantiles = [](const std::vector<double>& v) {
    auto q = [&](double p) { return v.empty() ? nlohmann::json() : nlohmann::json(Quantile(v, p)); };
    return nlohmann::json{{"min", q(0)}, {"p05", q(0.05)}, {"median", q(0.5)}, {"p95", q(0.95)}, {"max", q(1)}};
  };
  nlohmann::json summary = {{"scene", scene.name},
                            {"steps", strategy.steps.size()},
                            {"plan_s", plan_s},
                            {"total_s", total_s},
                            {"runs", runs},
                            {"successes", successes},
                            {"success_rate", runs.empty() ? 0.0 : successes / static_cast<double>(runs.size())},
                            {"motion_s", quantiles(motion)},
                            {"commands_sent", quantiles(commands)},
                            {"visual_events", quantiles(events)},
                            {"jobs", a.jobs},
                            {"speed", a.speed / a.slow},
                            {"slow_machine", a.slow},
                            {"camera", su.rendered ? "rendered" : "events"},
                            {"transport", a.can ? "can" : "lcm"},
                            {"netns", a.netns},
                            {"lockstep", a.lockstep},
                            {"interrupted", g_signal != 0}};
  WriteTextOutput(summary.dump(2) + "\n", (dir / "summary.json").string());
  if (a.runs > 1) WriteTextOutput(MonteCarloSvg(su, done_runs), (dir / "montecarlo.svg").string());
  for (const auto& item : runs) {
    if (a.runs > 1 && item["success"].get<bool>()) continue;  // Monte Carlo: the failures one by one, then the figures
    std::printf(
        "run seed %llu: %s (%s), %d/%zu steps, %d visual events, %d commands, %d faults, %.1f s, final error "
        "%s m\n",
        static_cast<unsigned long long>(item["seed"].get<std::uint64_t>()),
        item["success"].get<bool>() ? "goal reached" : "FAILED", item["reason"].get<std::string>().c_str(),
        item["steps_completed"].get<int>(), strategy.steps.size(), item["visual_events"].get<int>(),
        item["commands_sent"].get<int>(), item["faults_published"].get<int>(), item["time_s"].get<double>(),
        item["goal_error_m"].is_null() ? "?" : fmt::format("{:.3f}", item["goal_error_m"].get<double>()).c_str());
  }
  if (a.runs > 1 && !motion.empty()) {
    std::printf(
        "visco demo: time in motion median %.2f s (5-95 %%: %.2f-%.2f s), commands median %.0f, visual events "
        "median %.0f; figure: %s\n",
        Quantile(motion, 0.5), Quantile(motion, 0.05), Quantile(motion, 0.95), Quantile(commands, 0.5),
        Quantile(events, 0.5), (dir / "montecarlo.svg").c_str());
  }
  std::printf("visco demo: %d of %zu run(s) reached the goal recognisably; %.1f s in all; outputs in %s\n", successes,
              runs.size(), total_s, dir.c_str());
  if (g_signal != 0) return 130;
  return successes == static_cast<int>(runs.size()) && static_cast<int>(runs.size()) == a.runs ? 0 : 1;
}

}  // namespace

void RegisterDemoCommand(CLI::App& app) {
  auto args = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "demo",
      "The main job: plans the embedded default scene (or --scene FILE) with `visco plan`, then executes the "
      "strategy in closed loop as separate processes over LCM (the simulated robot and its driver, the rendered "
      "camera, the vision pipeline, the controller, lcm-logger), and writes plan.svg, run.svg, run.lcmlog and "
      "summary.json into DIR. Exit 0 only when the goal is recognisably reached (the controller recognised it and "
      "the simulated robot is in the goal).");
  cmd->add_option("--out", args->out, "output directory (default: a fresh ./visco-demo-N)");
  cmd->add_option("--scene", args->scene, "scene file instead of the embedded default (docs/formats.md)");
  cmd->add_option("--seed", args->seed, "seed of the adversary and the camera noise")->capture_default_str();
  cmd->add_flag("--can", args->can, "the controller talks to the driver over SocketCAN vcan0 instead of LCM");
  cmd->add_option("--runs", args->runs, "Monte Carlo: runs from seeded random starts in the start region")
      ->capture_default_str();
  cmd->add_option("--speed", args->speed,
                  "commanded speed of the strategy's motions, m/s (the controller's limit is 1)")
      ->capture_default_str();
  cmd->add_option("--jobs", args->jobs, "Monte Carlo: runs at the same time (each on its own LCM port), 1-8")
      ->capture_default_str();
  cmd->add_flag("--keep-logs", args->keep_logs,
                "Monte Carlo: keep every run's LCM logs (default: only the failed runs' logs)");
  cmd->add_option("--timeout", args->timeout_s, "give up a run after this many seconds")->capture_default_str();
  cmd->add_option("--slow-machine", args->slow,
                  "the machine is this many times slower than a 2-core PC (e.g. 10 in the HIL VM's emulated CPU): "
                  "the processes' time limits (vision age, hold, start-up, status, heartbeat, watchdog, --timeout) "
                  "are multiplied by it, the commanded speed and the camera rate divided by it, no supersampling")
      ->capture_default_str();
  cmd->add_flag("--lockstep", args->lockstep,
                "run the closed loop as one process on a simulated clock (`visco sim --lockstep`: the same driver, "
                "simulated robot, rendered camera, vision pipeline and controller, one thread, a private in-process "
                "bus) instead of five processes on the wall clock: the same --seed gives a bit-identical run.lcmlog, "
                "which `visco replay --check` replays (docs/replay.md)");
  cmd->add_flag("--netns", args->netns,
                "run every process on a host of its own: a network namespace each, joined by veth to a bridge, LCM "
                "multicast with ttl=1 between them, as on several machines (needs root; summary.json records where "
                "each process ran)");
  cmd->callback([args] {
    const int status = Run(*args);
    if (status == 130) throw JobFailed("interrupted");
    if (status != 0) throw JobFailed("the goal was not reached in every run (see summary.json)");
  });
}

}  // namespace visco::app

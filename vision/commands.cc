#include "vision/commands.h"

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <exception>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>

#include "common/error.h"
#include "common/event_log.h"
#include "lcmtypes/channels.h"
#include "visco/log_annotation_t.hpp"
#include "vision/camera.h"
#include "vision/camera_info.h"
#include "vision/detect_json.h"
#include "vision/image.h"
#include "vision/multi_tag_pose.h"
#include "vision/overlay.h"
#include "vision/pipeline.h"
#include "vision/pipeline_config.h"
#include "vision/tag_detector.h"
#include "vision/v4l2_camera.h"

namespace visco::vision {
namespace {

std::atomic<bool> g_interrupted{false};
extern "C" void OnSignal(int) { g_interrupted = true; }

V4l2Options NoCamera() {
  V4l2Options o;
  o.device.clear();
  return o;
}

// The first calibration on VISCO_CAMERA_INFO within `timeout_s`. @throws InputError if none comes or it is bad.
CameraCalibration WaitForCalibration(lcm::LCM& bus, double timeout_s) {
  struct Catch {
    std::optional<visco::camera_info_t> message;
    void Handle(const lcm::ReceiveBuffer*, const std::string&, const visco::camera_info_t* m) {
      if (!message) message = *m;
    }
  } first;
  lcm::Subscription* subscription = bus.subscribe(channels::kCameraInfo, &Catch::Handle, &first);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (!first.message && std::chrono::steady_clock::now() < deadline) bus.handleTimeout(100);
  bus.unsubscribe(subscription);
  if (!first.message) {
    throw InputError("command line", "--camera/--extrinsics",
                     "not given, and no calibration came on " + std::string(channels::kCameraInfo) + " within " +
                         std::to_string(timeout_s) + " s (is the camera process running? give the files instead)");
  }
  return DecodeCameraInfo(*first.message, channels::kCameraInfo);
}

struct TrackArgs {
  double calibration_timeout_s = 5;
  PipelineConfig pipeline;
  std::string images, video;
  V4l2Options v4l2 = NoCamera();  // device empty: no V4L2 camera
  bool fps_given = false;
  bool lcm_input = false;
  std::string lcm_url;
  bool publish = true;
  double fps = 30;
  std::int64_t max_frames = 0;
  std::string out;
  std::string log;
  std::string overlay;
};

const char* StateName(std::int8_t s) {
  switch (s) {
    case 1:
      return "negative";
    case 2:
      return "on_line";
    case 3:
      return "positive";
    default:
      return "unknown";
  }
}

void RunTrack(const TrackArgs& a) {
  const int inputs =
      (a.images.empty() ? 0 : 1) + (a.video.empty() ? 0 : 1) + (a.lcm_input ? 1 : 0) + (a.v4l2.device.empty() ? 0 : 1);
  if (inputs != 1) throw InputError("command line", "--images/--video/--lcm/--v4l2", "give exactly one frame source");
  if (!a.lcm_input) {
    // Only a stream on the bus has a calibration beside it.
    if (a.pipeline.camera.empty()) throw InputError("command line", "--camera", "required without --lcm");
    if (a.pipeline.extrinsics.empty()) throw InputError("command line", "--extrinsics", "required without --lcm");
  }
  // The event log records the bus from before the first frame (it is opened first).
  std::unique_ptr<EventLogTap> log = OpenEventLog(a.log, a.lcm_url);
  std::unique_ptr<lcm::LCM> bus;
  if (a.publish || a.lcm_input) {
    bus = std::make_unique<lcm::LCM>(a.lcm_url);
    if (!bus->good()) throw InputError("command line", "--lcm-url", "cannot open LCM bus '" + a.lcm_url + "'");
  }
  // Without calibration files, the camera process's calibration from VISCO_CAMERA_INFO (files given still win).
  std::optional<CameraCalibration> bus_calibration;
  if (a.lcm_input && (a.pipeline.camera.empty() || a.pipeline.extrinsics.empty())) {
    bus_calibration = WaitForCalibration(*bus, a.calibration_timeout_s);
  }
  std::vector<std::string> mismatches, from_bus;
  const LoadedPipeline loaded =
      ResolvePipelineConfig(a.pipeline, "", bus_calibration, channels::kCameraInfo, mismatches, from_bus);
  for (const std::string& m : mismatches) std::fprintf(stderr, "track: mismatch: %s\n", m.c_str());
  if (!from_bus.empty()) {
    std::fprintf(stderr, "track: calibration from %s (%s)\n", channels::kCameraInfo, loaded.calibration.source.c_str());
  }
  const CameraModel& camera = loaded.camera;
  const Eigen::Isometry3d& wMc = loaded.wMc;
  const ObjectModels& models = loaded.models;
  const PipelineOptions& po = loaded.options;
  // The overlay's path is checked (and a video opened, when the calibration gives the frame size) before any frame.
  std::unique_ptr<OverlayWriter> overlay;
  if (!a.overlay.empty()) {
    overlay = std::make_unique<OverlayWriter>(a.overlay, a.fps);
    if (camera.width > 0 && camera.height > 0) overlay->Open(camera.width, camera.height);
  }
  std::unique_ptr<FrameSource> source;
  const std::int64_t start = NowUtime();
  if (!a.images.empty()) source = MakeFolderSource(a.images, a.fps, start);
  if (!a.video.empty()) source = MakeVideoSource(a.video, start);
  if (a.lcm_input) source = MakeLcmSource(*bus, channels::kCameraImage);
  if (!a.v4l2.device.empty()) {
    V4l2Options v = a.v4l2;
    // The calibration's image size is asked of the camera (a camera that cannot give it is an error).
    v.width = camera.width;
    v.height = camera.height;
    if (!a.fps_given) v.fps = 0;
    source = MakeV4l2Source(v, po.camera_name);
  }

  std::FILE* out = stdout;
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(nullptr, &std::fclose);
  if (!a.out.empty()) {
    file.reset(std::fopen(a.out.c_str(), "w"));
    if (!file) throw InputError(a.out, "", "cannot write output file");
    out = file.get();
  }
  VisionPipeline pipeline(camera, wMc, models, po);
  std::int64_t frames = 0, bad = 0, lost = 0, crossings = 0, full = 0;
  double latency_sum = 0;
  std::atomic<bool> done{false};
  PipelineThread thread(
      std::move(source), pipeline, a.publish ? bus.get() : nullptr, nullptr, [&](const PipelineOutput& o) {
        for (const auto& f : o.faults) {
          nlohmann::json j;
          j["fault"] = {{"utime", f.utime},
                        {"code", f.code},
                        {"severity", f.severity},
                        {"cleared", f.cleared != 0},
                        {"message", f.message}};
          std::fprintf(out, "%s\n", j.dump().c_str());
        }
        if (!o.processed) {
          ++bad;
          return;
        }
        ++frames;
        full += o.full_detection ? 1 : 0;
        lost += o.robot.valid ? 0 : 1;
        latency_sum += o.events.latency_s;
        nlohmann::json j;
        j["seq"] = o.robot.frame_seq;
        j["utime"] = o.robot.utime;
        j["full_detection"] = o.full_detection;
        j["tags"] = nlohmann::json::array();
        for (const auto& t : o.detections.detections) j["tags"].push_back(t.id);
        j["robot"] = {{"valid", o.robot.valid},
                      {"position", {o.robot.position[0], o.robot.position[1]}},
                      {"stddev", o.robot.position_stddev},
                      {"heading_deg", o.robot.heading * 180 / M_PI}};
        j["objects"] = nlohmann::json::array();
        for (const auto& p : o.poses.poses) {
          j["objects"].push_back({{"id", p.object_id},
                                  {"position", {p.position[0], p.position[1], p.position[2]}},
                                  {"contact_refined", p.contact_refined},
                                  {"pose_decision", PoseDecisionName(static_cast<PoseDecision>(p.pose_decision))},
                                  {"ambiguous", p.ambiguous},
                                  {"tags_used", p.tags_used},
                                  {"rms_error_px", p.rms_error_px}});
        }
        j["events"] = nlohmann::json::array();
        for (const auto& e : o.events.events) {
          crossings += e.crossed ? 1 : 0;
          j["events"].push_back({{"cvc_ray", e.cvc_ray},
                                 {"signed_distance_px", e.signed_distance_px},
                                 {"stddev_px", e.distance_stddev_px},
                                 {"state", StateName(e.state)},
                                 {"crossed", e.crossed}});
        }
        if (po.tracker.mode == TagTrackingMode::kModelBased) {
          // Whether the robot's pose in this line is the model-based tracker's, and why not.
          j["model_tracker"] = {{"ran", o.model.ran},
                                {"used", o.model.used},
                                {"from_tags", o.model.from_tags},
                                {"edge_features", o.model.edge_features},
                                {"rms_px", o.model.rms_px},
                                {"failure", o.model.failure}};
        }
        j["latency_ms"] = o.events.latency_s * 1e3;
        std::fprintf(out, "%s\n", j.dump().c_str());
        std::fflush(out);
        if (a.max_frames > 0 && frames >= a.max_frames) done = true;
      });
  // One picture per pull (frame or bad frame), drawn and written on the pipeline thread; a write error ends the run.
  std::unique_ptr<TrackOverlay> drawer;
  std::exception_ptr overlay_error;  // read after the thread has stopped
  if (overlay) {
    drawer = std::make_unique<TrackOverlay>(camera, wMc, models);
    thread.SetFrameCallback([&](const Frame& frame, const PipelineOutput& o) {
      if (overlay_error) return;
      try {
        overlay->Write(drawer->Draw(frame, o, pipeline.features().last()));
      } catch (...) {
        overlay_error = std::current_exception();
        done = true;
      }
    });
  }
  // The configuration beside the output, at start and every second, so that a log of the bus cut anywhere holds
  // it and `visco replay` needs no other file (docs/replay.md).
  visco::log_annotation_t config{};
  config.source = "track";
  config.kind = kVisionConfigKind;
  config.text = VisionConfigToJson(loaded);
  auto publish_config = [&] {
    if (!a.publish) return;
    config.utime = NowUtime();
    bus->publish(kVisionConfigChannel, &config);
    // The calibration vision runs with, when it came from files: no camera process published it.
    if (loaded.calibration_from_files) {
      const visco::camera_info_t info = EncodeCameraInfo(loaded.calibration, config.utime);
      bus->publish(channels::kCameraInfo, &info);
    }
  };
  g_interrupted = false;
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  publish_config();
  auto next_config = std::chrono::steady_clock::now() + std::chrono::seconds(1);
  thread.Start();
  while (!g_interrupted && !done && !thread.finished()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if (std::chrono::steady_clock::now() >= next_config) {
      publish_config();
      next_config += std::chrono::seconds(1);
    }
  }
  thread.Stop();
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  if (overlay) overlay->Close();
  if (overlay_error) std::rethrow_exception(overlay_error);
  nlohmann::json s;
  s["summary"] = {{"frames", frames},          {"bad_frames", bad},
                  {"robot_lost_frames", lost}, {"crossings", crossings},
                  {"full_detections", full},   {"mean_latency_ms", frames > 0 ? latency_sum / frames * 1e3 : 0.0}};
  if (overlay) s["summary"]["overlay_frames"] = overlay->frames();
  std::fprintf(out, "%s\n", s.dump().c_str());
  if (log) std::fprintf(stderr, "track: %s\n", log->Close().c_str());
  if (frames == 0) throw JobFailed("no frame could be processed (" + std::to_string(bad) + " bad frames)");
}

struct DetectArgs {
  std::string image;
  std::string camera;
  std::string camera_name;
  double tag_size = 0;
  std::string family = "tag36h11";
  std::string out;
  std::string overlay;
  DetectorOptions detector;
  PoseOptions pose;
};

void WriteOutput(const std::string& text, const std::string& out) {
  if (out.empty()) {
    std::fwrite(text.data(), 1, text.size(), stdout);
    std::fputc('\n', stdout);
    return;
  }
  std::ofstream f(out);
  if (!f) throw InputError(out, "", "cannot write output file");
  f << text << "\n";
}

void RunDetect(const DetectArgs& a) {
  if (!(a.tag_size > 0)) throw InputError("command line", "--tag-size", "must be a positive length in metres");
  if (!a.overlay.empty()) CheckOverlayImagePath(a.overlay);
  const CameraModel camera = LoadCamera(a.camera, a.camera_name);
  const GrayImage image = ReadGrayImage(a.image);
  if (camera.width > 0 && camera.height > 0 && (camera.width != image.width || camera.height != image.height)) {
    throw InputError(a.image, "",
                     "image is " + std::to_string(image.width) + "x" + std::to_string(image.height) +
                         " but calibration " + a.camera + " is for " + std::to_string(camera.width) + "x" +
                         std::to_string(camera.height));
  }
  DetectorOptions d = a.detector;
  d.family = a.family;
  const DetectResult result = DetectTags(image.view(), camera, a.tag_size, d, a.pose);
  WriteOutput(DetectResultToJson(result), a.out);
  if (!a.overlay.empty()) WriteOverlayImage(DrawDetectOverlay(image.view(), camera, a.tag_size, result), a.overlay);
}

}  // namespace

void RegisterCommands(CLI::App& app) {
  auto args = std::make_shared<DetectArgs>();
  CLI::App* detect = app.add_subcommand(
      "detect",
      "Detect AprilTags in one image and estimate their poses. Prints JSON: {\"image\": {\"width\", \"height\"}, "
      "\"detections\": [{\"id\", \"family\", \"corners\" (pixels, AprilTag order: corner 0 bottom-left of the printed "
      "tag, then counter-clockwise), \"pose\": {\"t\" (m), \"R\"} (tag in the camera frame, ViSP convention: x right, "
      "y up as printed, z out of the tag face), \"decision_margin\", \"hamming\", \"reprojection_error_px\", "
      "\"ambiguous\"}], \"rejected\"}.");
  detect->add_option("IMAGE", args->image, "image file (PGM, PNG, JPEG, ...)")->required();
  detect->add_option("--camera", args->camera, "calibration: ViSP XML (.xml) or OpenCV YAML (.yaml/.yml)")->required();
  detect->add_option("--camera-name", args->camera_name, "camera to use in a multi-camera ViSP XML file");
  detect->add_option("--tag-size", args->tag_size, "tag size in metres: the black border's outer edge")->required();
  detect->add_option("--family", args->family, "tag family")->capture_default_str();
  detect->add_option("--out", args->out, "write the JSON to this file instead of stdout");
  detect->add_option("--overlay", args->overlay,
                     "also draw the detections on the image into this picture (.png; .jpg, .bmp, .ppm, .tif also): "
                     "each tag's border in green with a cross on corner 0 (orange: no pose), its id in red, its pose "
                     "as a frame (x red, y green, z blue); docs/vision.md, \"Overlays\"");
  detect->add_option("--decimate", args->detector.quad_decimate, "quad decimation (1: full resolution)")
      ->capture_default_str();
  detect->add_option("--min-margin", args->detector.min_decision_margin, "reject decodes below this decision margin")
      ->capture_default_str();
  detect->add_option("--max-hamming", args->detector.max_hamming, "reject decodes with more corrected bits")
      ->capture_default_str();
  detect
      ->add_option("--max-reprojection-error", args->pose.max_rms_error_px,
                   "reject poses whose RMS reprojection error (pixels) exceeds this")
      ->capture_default_str();
  detect->callback([args] { RunDetect(*args); });

  auto targs = std::make_shared<TrackArgs>();
  CLI::App* track = app.add_subcommand(
      "track",
      "Run the vision pipeline over a stream: an image folder, a video file, the LCM camera channel "
      "(VISCO_CAMERA_IMAGE, image_t) or a V4L2 camera. Detects and tracks the tags of the object models, estimates "
      "object poses, the "
      "robot position and the visual events, publishes them on LCM (VISCO_TAG_DETECTIONS, VISCO_OBJECT_POSES, "
      "VISCO_ROBOT_ESTIMATE, VISCO_VISUAL_EVENTS, faults on VISCO_FAULT) and prints one JSON line per frame (robot, "
      "objects with "
      "their pose decision, tags used and RMS error, events), faults as {\"fault\": ...} lines, and a final "
      "{\"summary\": ...} line.");
  AddPipelineConfigOptions(*track, targs->pipeline, ConfigDefaults::kBus);
  track
      ->add_option("--calibration-timeout", targs->calibration_timeout_s,
                   "with --lcm and no --camera or --extrinsics: seconds to wait for the camera's calibration on "
                   "VISCO_CAMERA_INFO (camera_info_t, with its pose for the extrinsics)")
      ->capture_default_str();
  track->add_option("--images", targs->images, "folder of image files, processed in name order");
  track->add_option("--video", targs->video, "video file (OpenCV)");
  track->add_flag("--lcm", targs->lcm_input, "read image_t frames from VISCO_CAMERA_IMAGE until interrupted");
  track->add_option("--v4l2", targs->v4l2.device,
                    "read a V4L2 camera (e.g. /dev/video0) in this process, at the calibration's image size: as "
                    "`visco capture` does (docs/camera.md)");
  track->add_option("--input", targs->v4l2.input, "with --v4l2: the device's input to select");
  track->add_option("--pixel-format", targs->v4l2.pixel_format, "with --v4l2: GREY, YUYV or MJPG");
  track->add_option("--exposure", targs->v4l2.exposure, "with --v4l2: manual exposure (the device's unit)");
  track->add_option("--gain", targs->v4l2.gain, "with --v4l2: manual gain (the device's unit)");
  track->add_option("--timeout-ms", targs->v4l2.timeout_ms, "with --v4l2: no frame for this long is a fault")
      ->capture_default_str();
  track->add_option("--lcm-url", targs->lcm_url,
                    "LCM provider URL (default: LCM's default). With --lcm over UDP multicast, add recv_buf_size "
                    "(e.g. udpm://239.255.76.67:7667?ttl=0&recv_buf_size=2097152): a 640x480 frame is larger than "
                    "the kernel's default receive buffer and frames are dropped without it");
  track->add_flag("!--no-publish", targs->publish, "do not publish on LCM (print only)");
  track
      ->add_option("--fps", targs->fps,
                   "frame rate of an image folder (timestamps); with --v4l2, the rate asked of "
                   "the camera (default: its current)")
      ->capture_default_str()
      ->each([targs](const std::string&) { targs->fps_given = true; });
  track->add_option("--max-frames", targs->max_frames, "stop after this many processed frames (0: no limit)");
  track->add_option("--out", targs->out, "write the JSON lines to this file instead of stdout");
  track->add_option("--log", targs->log,
                    "write an LCM event log (lcm-logger format) of the bus: every channel it publishes and receives, "
                    "images included (needs a udpm:// bus; docs/replay.md)");
  track->add_option("--overlay", targs->overlay,
                    "draw what vision saw on every frame into a video (.avi or .mkv: Motion JPEG; .mp4: MPEG-4) or a "
                    "folder of PNG pictures (a path without extension, created if missing: 000000.png, ...), one "
                    "picture per input frame (bad frames: black with the fault): tags and ids, searched windows, the "
                    "objects' prisms, CM vertices, VC lines, signed distances, events as they fire, faults; the video "
                    "runs at --fps; docs/vision.md, \"Overlays\"");
  track->callback([targs] {
    TrackArgs a = *targs;
    if (a.fps_given) a.v4l2.fps = a.fps;
    RunTrack(a);
  });
  RegisterCaptureCommand(app);
}

}  // namespace visco::vision

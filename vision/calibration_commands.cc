#include "vision/calibration_commands.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>

#include "common/error.h"
#include "common/robot_frame.h"
#include "lcmtypes/channels.h"
#include "vision/camera.h"
#include "vision/pipeline.h"
#include "vision/table_extrinsics.h"
#include "vision/tag_detector.h"

namespace visco::vision {
namespace {

struct ExtrinsicsArgs {
  std::string camera, camera_name;
  std::string images, video;
  bool lcm_input = false;
  std::string lcm_url;
  std::string family = "tag36h11";
  int tag_id = 0;
  double tag_size = 0;
  std::vector<double> tag_t{0, 0, 0};
  std::vector<double> tag_rpy_deg{0, 0, 0};
  double tag_position_stddev = 0;
  double tag_rotation_stddev_deg = 0;
  int frames = 30;
  double timeout_s = 10;
  double max_rms_px = 2.0;
  float quad_sigma = 0;
  std::string out;
};

nlohmann::ordered_json Triple(const Eigen::Vector3d& v, double scale = 1) {
  return {v.x() * scale, v.y() * scale, v.z() * scale};
}

void RunExtrinsics(const ExtrinsicsArgs& a) {
  const int inputs = (a.images.empty() ? 0 : 1) + (a.video.empty() ? 0 : 1) + (a.lcm_input ? 1 : 0);
  if (inputs != 1) throw InputError("command line", "--images/--video/--lcm", "give exactly one frame source");
  if (!(a.tag_size > 0)) throw InputError("command line", "--tag-size", "must be a positive length in metres");
  if (a.frames < 1) throw InputError("command line", "--frames", "must be at least 1");
  if (!(a.tag_position_stddev >= 0) || !(a.tag_rotation_stddev_deg >= 0)) {
    throw InputError("command line", "--tag-position-stddev/--tag-rotation-stddev-deg", "must be >= 0");
  }
  CheckFamilyName(a.family);
  const CameraModel camera = LoadCamera(a.camera, a.camera_name);
  TableTag tag;
  tag.family = a.family;
  tag.id = a.tag_id;
  tag.size = a.tag_size;
  tag.wMt.linear() =
      RotationFromRpy(a.tag_rpy_deg[0] * M_PI / 180, a.tag_rpy_deg[1] * M_PI / 180, a.tag_rpy_deg[2] * M_PI / 180);
  tag.wMt.translation() = Eigen::Vector3d(a.tag_t[0], a.tag_t[1], a.tag_t[2]);
  tag.position_stddev_m = a.tag_position_stddev;
  tag.rotation_stddev_rad = a.tag_rotation_stddev_deg * M_PI / 180;

  std::unique_ptr<lcm::LCM> bus;
  std::unique_ptr<FrameSource> source;
  const std::int64_t start = NowUtime();
  if (!a.images.empty()) source = MakeFolderSource(a.images, 30, start);
  if (!a.video.empty()) source = MakeVideoSource(a.video, start);
  if (a.lcm_input) {
    bus = std::make_unique<lcm::LCM>(a.lcm_url);
    if (!bus->good()) throw InputError("command line", "--lcm-url", "cannot open LCM bus '" + a.lcm_url + "'");
    source = MakeLcmSource(*bus, channels::kCameraImage);
  }

  DetectorOptions detector_options;
  detector_options.family = a.family;
  detector_options.quad_sigma = a.quad_sigma;
  TagDetector detector(detector_options);
  PoseOptions pose_options;
  pose_options.max_rms_error_px = a.max_rms_px;

  std::vector<TableTagView> views;
  std::optional<Eigen::Isometry3d> prior;  // the first frame whose corners chose the planar solution themselves
  int seen = 0, bad = 0, without_tag = 0;
  auto last_frame = std::chrono::steady_clock::now();
  Frame frame;
  std::string error;
  while (static_cast<int>(views.size()) < a.frames) {
    const SourceStatus status = source->Next(frame, error, 100);
    if (status == SourceStatus::kEnd) break;
    if (status == SourceStatus::kNoFrameYet) {
      const double idle = std::chrono::duration<double>(std::chrono::steady_clock::now() - last_frame).count();
      if (idle > a.timeout_s) {
        throw JobFailed("no frame on " + std::string(channels::kCameraImage) + " for " + std::to_string(a.timeout_s) +
                        " s (" + std::to_string(views.size()) + " of " + std::to_string(a.frames) + " frames used)");
      }
      continue;
    }
    last_frame = std::chrono::steady_clock::now();
    ++seen;
    if (status == SourceStatus::kBadFrame) {
      ++bad;
      std::fprintf(stderr, "extrinsics: bad frame %lld: %s\n", static_cast<long long>(frame.seq), error.c_str());
      continue;
    }
    if (camera.width > 0 && (frame.image.width != camera.width || frame.image.height != camera.height)) {
      throw InputError(frame.origin, "",
                       "frame is " + std::to_string(frame.image.width) + "x" + std::to_string(frame.image.height) +
                           " but calibration " + a.camera + " is for " + std::to_string(camera.width) + "x" +
                           std::to_string(camera.height));
    }
    const auto view = ObserveTableTag(detector, frame.image.view(), camera, tag, pose_options, prior);
    if (!view) {
      ++without_tag;
      continue;
    }
    if (!prior && !view->pose.ambiguous) prior = view->pose.cMo;
    views.push_back(*view);
  }
  if (views.empty()) {
    throw JobFailed("tag " + a.family + " id " + std::to_string(a.tag_id) + " was found (with a pose) in none of the " +
                    std::to_string(seen) + " frames");
  }
  const TableExtrinsics e = CombineTableTagViews(views, tag);
  SaveExtrinsicsWithStddev(e.wMc, e.covariance, camera.name, a.out);

  nlohmann::ordered_json s;
  s["extrinsics"] = a.out;
  s["frames"] = {{"used", e.frames}, {"without_tag", without_tag}, {"bad", bad}, {"ambiguous", e.ambiguous_frames}};
  const Eigen::Matrix3d r = e.wMc.linear();
  s["wMc"] = {{"t", Triple(e.wMc.translation())},
              {"R", {{r(0, 0), r(0, 1), r(0, 2)}, {r(1, 0), r(1, 1), r(1, 2)}, {r(2, 0), r(2, 1), r(2, 2)}}}};
  auto sd = [](const PoseCovariance6& c) {
    const Eigen::Matrix<double, 6, 1> d = c.diagonal().cwiseMax(0.0).cwiseSqrt();
    return nlohmann::ordered_json{{"position_m", Triple(d.tail<3>())},
                                  {"rotation_deg", Triple(d.head<3>(), 180 / M_PI)}};
  };
  s["stddev"] = sd(e.covariance);
  s["stddev_parts"] = {
      {"spread_per_frame", sd(e.spread)}, {"reprojection", sd(e.reprojection)}, {"tag_placement", sd(e.placement)}};
  s["reprojection_rms_px"] = {{"mean", e.mean_rms_px}, {"max", e.max_rms_px}};
  s["corner_sigma_px"] = e.corner_sigma_px;
  std::printf("%s\n", s.dump(2).c_str());
  if (e.frames < a.frames) {
    std::fprintf(stderr, "extrinsics: %d of the %d frames asked for showed the tag\n", e.frames, a.frames);
  }
  if (e.ambiguous_frames == e.frames) {
    std::fprintf(stderr,
                 "extrinsics: warning: in every frame the tag's two planar poses fit the corners alike; the pose may "
                 "be the mirror one (a larger tag, or the camera nearer, tells them apart)\n");
  }
}

struct RobotFrameArgs {
  std::string points;
  bool with_scale = false;
  std::string out;
};

void RunRobotFrame(const RobotFrameArgs& a) {
  const std::vector<FramePoint> points = LoadFramePoints(a.points);
  const RobotFrame f = FitRobotFrame(points, a.with_scale, a.points);
  if (!a.out.empty()) SaveRobotFrame(f, a.out);
  nlohmann::ordered_json s;
  s["robot_frame"] = {{"theta_deg", f.theta * 180 / M_PI}, {"scale", f.scale}, {"t", {f.t.x(), f.t.y()}}};
  s["stddev"] = {{"theta_deg", f.theta_stddev * 180 / M_PI}, {"t", {f.t_stddev.x(), f.t_stddev.y()}}};
  if (f.with_scale) s["stddev"]["scale"] = f.scale_stddev;
  s["points"] = static_cast<int>(points.size());
  s["dof"] = f.dof;
  s["rms_residual_m"] = f.rms_residual_m;
  double worst = 0;
  s["residuals"] = nlohmann::ordered_json::array();
  for (const auto& e : f.residuals) {
    s["residuals"].push_back({e.x(), e.y()});
    worst = std::max(worst, e.norm());
  }
  s["max_residual_m"] = worst;
  if (!a.out.empty()) s["out"] = a.out;
  std::printf("%s\n", s.dump(2).c_str());
  if (f.dof == 0) {
    std::fprintf(stderr, "robot-frame: warning: %zu points fit exactly; give more to check the fit\n", points.size());
  }
}

}  // namespace

void RegisterCalibrationCommands(CLI::App& app) {
  auto e = std::make_shared<ExtrinsicsArgs>();
  CLI::App* cmd = app.add_subcommand(
      "extrinsics",
      "Find the camera's pose in the world from an AprilTag lying on the table at a known pose, over N frames (an "
      "image folder, a video file or the LCM camera channel): the mean of the frames' poses, its uncertainty from "
      "their spread and from the reprojection error. Writes the extrinsics file `visco track` reads (--extrinsics, "
      "with wMc.stddev) and prints a JSON summary (docs/camera.md).");
  cmd->add_option("--camera", e->camera, "calibration: ViSP XML, OpenCV YAML or ROS camera_info YAML")->required();
  cmd->add_option("--camera-name", e->camera_name, "camera in a multi-camera ViSP XML file");
  cmd->add_option("--images", e->images, "folder of image files, in name order");
  cmd->add_option("--video", e->video, "video file (OpenCV)");
  cmd->add_flag("--lcm", e->lcm_input, "read image_t frames from VISCO_CAMERA_IMAGE (a live camera)");
  cmd->add_option("--lcm-url", e->lcm_url, "LCM provider URL (default: LCM's default; see `visco track --help`)");
  cmd->add_option("--tag-size", e->tag_size, "tag size in metres: the black border's outer edge")->required();
  cmd->add_option("--tag-id", e->tag_id, "id of the tag on the table")->capture_default_str();
  cmd->add_option("--family", e->family, "tag family")->capture_default_str();
  cmd->add_option("--tag-t", e->tag_t, "the tag centre in the world, metres (x y z; z = 0 on the table)")
      ->expected(3)
      ->capture_default_str();
  cmd->add_option("--tag-rpy-deg", e->tag_rpy_deg,
                  "the tag's orientation in the world, degrees (roll pitch yaw, R = Rz Ry Rx); 0 0 0: face up, its "
                  "printed x along the world's x")
      ->expected(3)
      ->capture_default_str();
  cmd->add_option("--tag-position-stddev", e->tag_position_stddev,
                  "uncertainty of the tag's placement, metres (1 sigma per axis), added to the result")
      ->capture_default_str();
  cmd->add_option("--tag-rotation-stddev-deg", e->tag_rotation_stddev_deg,
                  "uncertainty of the tag's orientation, degrees (1 sigma per axis), added to the result")
      ->capture_default_str();
  cmd->add_option("--frames", e->frames, "frames showing the tag to use (fewer if the folder or video ends first)")
      ->capture_default_str();
  cmd->add_option("--timeout", e->timeout_s, "with --lcm: give up after this many seconds without a frame")
      ->capture_default_str();
  cmd->add_option("--max-reprojection-error", e->max_rms_px, "leave out frames whose tag pose fits worse (RMS px)")
      ->capture_default_str();
  cmd->add_option("--quad-sigma", e->quad_sigma, "AprilTag segmentation blur (0.8 for noisy images)")
      ->capture_default_str();
  cmd->add_option("--out", e->out, "the extrinsics file to write (JSON, docs/formats.md)")->required();
  cmd->callback([e] { RunExtrinsics(*e); });

  auto f = std::make_shared<RobotFrameArgs>();
  CLI::App* fit = app.add_subcommand(
      "robot-frame",
      "Fit the robot's command frame to the world: from positions the robot was commanded to and where vision "
      "observed it, a 2-D rigid transform (or with --scale a similarity), least squares; prints it with the "
      "residuals per point and writes the robot frame file (docs/formats.md). Refused when the points do not "
      "determine it.");
  fit->add_option("POINTS", f->points,
                  "JSON: {\"points\": [{\"commanded\": [x, y], \"observed\": [x, y]}, ...]} (metres; commanded in the "
                  "robot's frame, observed in the world)")
      ->required();
  fit->add_flag("--scale", f->with_scale, "also fit a scale (world metres per commanded metre)");
  fit->add_option("--out", f->out, "write the robot frame file");
  fit->callback([f] { RunRobotFrame(*f); });
}

}  // namespace visco::vision

#include "replay/replayer.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>
#include <set>
#include <thread>
#include <utility>

#include "common/error.h"
#include "control/cycle_message.h"
#include "control/executor.h"
#include "control/fault_message.h"
#include "control/lcm_bridge.h"
#include "control/run.h"
#include "lcmtypes/channels.h"
#include "replay/safe_decode.h"
#include "visco/camera_info_t.hpp"
#include "visco/controller_cycle_t.hpp"
#include "visco/fault_t.hpp"
#include "visco/image_t.hpp"
#include "visco/log_annotation_t.hpp"
#include "visco/object_poses_t.hpp"
#include "visco/robot_estimate_t.hpp"
#include "visco/tag_detections_t.hpp"
#include "visco/velocity_command_t.hpp"
#include "visco/visual_events_t.hpp"
#include "vision/camera_info.h"
#include "vision/pipeline.h"

namespace visco::replay {
namespace {

// Seconds from `from` to `to` (microseconds); damaged timestamps can be anything, so no integer subtraction.
double SecondsBetween(std::int64_t from, std::int64_t to) {
  return (static_cast<double>(to) - static_cast<double>(from)) * 1e-6;
}

const std::set<std::string>& KnownChannels() {
  static const std::set<std::string> known = {channels::kCameraImage,     channels::kTagDetections,
                                              channels::kObjectPoses,     channels::kRobotEstimate,
                                              channels::kVisualEvents,    channels::kStrategy,
                                              channels::kCommand,         channels::kStatus,
                                              channels::kTelemetry,       channels::kFault,
                                              channels::kEstop,           channels::kHeartbeatController,
                                              channels::kHeartbeatDriver, channels::kHeartbeatVision,
                                              control::kCycleChannel,     control::kAnnotationChannel,
                                              channels::kSimTruth,        vision::kVisionConfigChannel,
                                              channels::kCameraInfo,      channels::kSimFrame};
  return known;
}

// An unknown channel that is visco's by its name (VISCO_...) or one of visco's with up to 3 characters changed: a
// damaged name rather than another program's channel on the bus.
bool LooksLikeDamagedName(const std::string& channel) {
  if (channel.rfind("VISCO_", 0) == 0) return true;
  for (const std::string& known : KnownChannels()) {
    if (known.size() != channel.size()) continue;
    int changed = 0;
    for (std::size_t i = 0; i < known.size(); ++i) changed += known[i] != channel[i] ? 1 : 0;
    if (changed <= 3) return true;
  }
  return false;
}

bool Known(const std::string& channel, const std::string& prefix) {
  if (KnownChannels().count(channel) > 0) return true;
  if (channel == "LCM_SELF_TEST") return true;  // LCM's own start-up check of a udpm:// bus (not replayed)
  return !prefix.empty() && channel.rfind(prefix, 0) == 0 && KnownChannels().count(channel.substr(prefix.size())) > 0;
}

template <class M>
bool DecodeAs(const LogEvent& e, M& m) {
  return SafeDecode(e.data, m);
}

template <class M>
std::vector<std::uint8_t> Encode(const M& m) {
  std::vector<std::uint8_t> buffer(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(buffer.data(), 0, static_cast<int>(buffer.size()));
  return buffer;
}

// The frame (image_t.utime) a logged vision output belongs to, if it is one.
// An image's capture time from its first fields (the fingerprint, then image_t.utime, big-endian), without decoding
// its pixels. False for an event too short or of another type.
bool ImageUtime(const LogEvent& e, std::int64_t& utime) {
  if (e.data.size() < 16) return false;
  std::uint64_t hash = 0, value = 0;
  for (int k = 0; k < 8; ++k) {
    hash = hash << 8 | e.data[static_cast<std::size_t>(k)];
    value = value << 8 | e.data[static_cast<std::size_t>(8 + k)];
  }
  if (hash != static_cast<std::uint64_t>(image_t::getHash())) return false;
  utime = static_cast<std::int64_t>(value);
  return true;
}

bool VisionOutputFrame(const LogEvent& e, std::int64_t& frame_utime) {
  const std::string_view c = e.channel;
  if (c == channels::kTagDetections) {
    tag_detections_t m;
    if (!DecodeAs(e, m)) return false;
    frame_utime = m.frame_utime;
    return true;
  }
  if (c == channels::kObjectPoses) {
    object_poses_t m;
    if (!DecodeAs(e, m)) return false;
    frame_utime = m.frame_utime;
    return true;
  }
  if (c == channels::kRobotEstimate) {
    robot_estimate_t m;
    if (!DecodeAs(e, m)) return false;
    frame_utime = m.utime;
    return true;
  }
  if (c == channels::kVisualEvents) {
    visual_events_t m;
    if (!DecodeAs(e, m)) return false;
    frame_utime = m.frame_utime;
    return true;
  }
  if (c == channels::kFault) {
    fault_t m;
    if (!DecodeAs(e, m) || m.source != "vision") return false;
    frame_utime = m.utime;
    return true;
  }
  return false;
}

// Field-by-field differences of the controller's values, numbers bit for bit.
class ControlDiffer {
 public:
  std::optional<FieldDifference> result;
  void Field(const std::string& name, double a, double b) {
    if (result || std::memcmp(&a, &b, sizeof a) == 0) return;
    char x[64], y[64];
    std::snprintf(x, sizeof x, "%.17g", a);
    std::snprintf(y, sizeof y, "%.17g", b);
    result = FieldDifference{name, x, y};
  }
  void Field(const std::string& name, std::int64_t a, std::int64_t b) {
    if (result || a == b) return;
    result = FieldDifference{name, std::to_string(a), std::to_string(b)};
  }
  void Field(const std::string& name, const std::string& a, const std::string& b) {
    if (result || a == b) return;
    result = FieldDifference{name, "\"" + a + "\"", "\"" + b + "\""};
  }
};

void CompareFrames(ControlDiffer& d, const control::VisualFrame& a, const control::VisualFrame& b) {
  d.Field("input.frame.capture_ns", a.capture_ns, b.capture_ns);
  d.Field("input.frame.count", std::int64_t{a.count}, std::int64_t{b.count});
  for (int i = 0; i < a.count && i < b.count; ++i) {
    const std::string p = "input.frame.items[" + std::to_string(i) + "].";
    const control::VisualObservation& x = a.items[i];
    const control::VisualObservation& y = b.items[i];
    d.Field(p + "ray", std::int64_t{x.ray}, std::int64_t{y.ray});
    d.Field(p + "state", std::int64_t{x.state}, std::int64_t{y.state});
    d.Field(p + "crossed", std::int64_t{x.crossed}, std::int64_t{y.crossed});
    d.Field(p + "signed_distance_px", x.signed_distance_px, y.signed_distance_px);
    d.Field(p + "stddev_px", x.stddev_px, y.stddev_px);
  }
}

void CompareEstimates(ControlDiffer& d, const control::PositionEstimate& a, const control::PositionEstimate& b) {
  d.Field("input.estimate.capture_ns", a.capture_ns, b.capture_ns);
  d.Field("input.estimate.valid", std::int64_t{a.valid}, std::int64_t{b.valid});
  d.Field("input.estimate.position[0]", a.position.x, b.position.x);
  d.Field("input.estimate.position[1]", a.position.y, b.position.y);
  d.Field("input.estimate.stddev", a.stddev, b.stddev);
}

// Adds a remark to the summary (the first few only).
void AddNote(ReplaySummary& s, std::string text) {
  if (s.notes.size() < 20) s.notes.push_back(std::move(text));
}

// Where the replay's output goes: the bus (unless --no-publish) and the --out log, under the replay's prefix (none
// when armed).
class Outputs {
 public:
  /// @throws InputError if the bus cannot be opened.
  explicit Outputs(const ReplayOptions& o) : prefix_(o.arm ? "" : o.prefix), out_path_(o.out_path) {
    if (o.publish) {
      bus_ = std::make_unique<lcm::LCM>(o.lcm_url);
      if (!bus_->good()) throw InputError("command line", "--lcm-url", "cannot open LCM bus '" + o.lcm_url + "'");
    }
    if (!o.out_path.empty()) {
      WriterOptions wo;
      wo.max_queue_bytes = std::size_t{1} << 30;
      out_ = std::make_unique<EventLogWriter>(o.out_path, wo);
    }
  }
  void Emit(const std::string& channel, std::int64_t timestamp, const std::vector<std::uint8_t>& bytes) {
    const std::string name = prefix_ + channel;
    if (bus_) bus_->publish(name, bytes.data(), static_cast<unsigned int>(bytes.size()));
    if (out_) out_->Write(name, timestamp, bytes);
  }
  /// Closes the --out log: what it could not write, in words ("" when everything went in).
  std::string Close() {
    if (!out_) return "";
    const WriterStats ws = out_->Close();
    if (ws.events_dropped == 0 && ws.error.empty()) return "";
    return out_path_ + ": " + std::to_string(ws.events_dropped) + " event(s) dropped " + ws.error;
  }

 private:
  std::string prefix_;
  std::string out_path_;
  std::unique_ptr<lcm::LCM> bus_;
  std::unique_ptr<EventLogWriter> out_;
};

// An image folder or a video file instead of a log: the frames go through vision as `visco track` would take them,
// on the frames' own timestamps (from `start_utime`, so that two replays give the same bytes). Nothing to compare.
ReplaySummary ReplaySource(const ReplayOptions& o, const vision::LoadedPipeline& loaded) {
  ReplaySummary s;
  s.publishing = o.publish;
  s.checked = o.check;
  const auto wall_start = std::chrono::steady_clock::now();
  std::unique_ptr<vision::FrameSource> source = !o.images_dir.empty()
                                                    ? vision::MakeFolderSource(o.images_dir, o.fps, o.start_utime)
                                                    : vision::MakeVideoSource(o.video_path, o.start_utime);
  Outputs outputs(o);
  std::int64_t now = 0;
  vision::PipelineOptions options = loaded.options;
  options.clock = [&now] { return now; };
  vision::VisionPipeline pipeline(loaded.camera, loaded.wMc, loaded.models, options);
  vision::Frame frame;
  std::string error;
  bool first = true;
  std::int64_t first_utime = 0;
  auto pace_start = std::chrono::steady_clock::now();
  for (;;) {
    error.clear();
    const vision::SourceStatus status = source->Next(frame, error, 0);
    if (status == vision::SourceStatus::kEnd) break;
    if (status == vision::SourceStatus::kNoFrameYet) continue;
    if (first) {
      first = false;
      first_utime = frame.utime;
      s.log_start_utime = frame.utime;
    }
    s.log_end_utime = frame.utime;
    const double t = SecondsBetween(first_utime, frame.utime);
    if (t > o.to_s) break;
    ++s.images;
    if (!o.fast) {
      std::this_thread::sleep_until(pace_start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                     std::chrono::duration<double>(t / o.speed)));
    }
    now = frame.utime;
    vision::PipelineOutput result;
    if (status == vision::SourceStatus::kBadFrame) {
      result.faults.push_back(pipeline.BadFrame(frame, error));
    } else {
      result = pipeline.Process(frame, frame.utime);
    }
    if (result.processed) {
      ++s.frames;
    } else {
      ++s.bad_frames;
    }
    if (t < o.from_s) {
      ++s.warmup_frames;
      continue;
    }
    vision::ForEachMessage(result, [&](const char* channel, const auto& message) {
      outputs.Emit(channel, frame.utime, Encode(message));
      ++s.produced;
    });
  }
  if (std::string dropped = outputs.Close(); !dropped.empty()) AddNote(s, std::move(dropped));
  if (s.images > 1 && s.log_end_utime > s.log_start_utime) {
    s.log_frame_rate_hz = static_cast<double>(s.images - 1) / SecondsBetween(s.log_start_utime, s.log_end_utime);
  }
  s.control_note = "no controller records in an image folder or video";
  s.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  return s;
}

// The options a replay cannot run with; the channel filter compiled. @throws InputError.
std::regex CheckOptions(const ReplayOptions& o) {
  const int sources = (o.log_path.empty() ? 0 : 1) + (o.images_dir.empty() ? 0 : 1) + (o.video_path.empty() ? 0 : 1);
  if (sources != 1) throw InputError("command line", "LOG/--images/--video", "give exactly one of them");
  if (o.seek && o.check) {
    throw InputError("command line", "--seek",
                     "vision would start fresh at --from, not in the live run's state: --check needs the frames "
                     "before it (leave --seek out)");
  }
  if (o.step && o.log_path.empty()) {
    throw InputError("command line", "--step", "steps through a log's images: give a LOG, not --images/--video");
  }
  if (o.check && o.log_path.empty()) {
    throw InputError("command line", "--check", "compares with what a log holds: give a LOG, not --images/--video");
  }
  if (!o.can_interface.empty() && !o.arm) {
    throw InputError("command line", "--can",
                     "replay never commands hardware unless armed: give --arm to use a CAN interface");
  }
  if (!o.can_interface.empty()) {
    throw InputError("command line", "--can",
                     "replay feeds the logged images through vision and publishes its outputs on LCM; it has no "
                     "robot commands to send on CAN");
  }
  if (!o.fast && !(o.speed > 0)) throw InputError("command line", "--speed", "must be positive");
  if (!(o.from_s >= 0) || !(o.to_s >= o.from_s)) {
    throw InputError("command line", "--from/--to", "need 0 <= FROM <= TO (seconds after the log's first event)");
  }
  try {
    return std::regex(o.channels);
  } catch (const std::regex_error& e) {
    throw InputError("command line", "--channels", std::string("not a regular expression: ") + e.what());
  }
}

// The log, read whole, and where in it the live processes' outputs are.
struct LogIndex {
  // The mapped log: `events` point into it (their channels and payloads), so it lives as long as they do.
  std::unique_ptr<EventLogReader> reader;
  std::vector<LogEvent> events;
  // What the live vision process published, per channel and frame (image_t.utime), in log order; the replay takes
  // each once it has compared it.
  std::map<std::pair<std::string, std::int64_t>, std::deque<std::size_t>> vision_outputs;
  std::set<std::int64_t> vision_frames;  // the frames the live vision process published anything for
  std::int64_t last_vision_frame = 0;
  std::int64_t images = 0;
  std::vector<std::size_t> cycles;        // the controller's period records
  std::int64_t annotation = -1;           // the run's configuration (-1: none)
  std::string vision_config;              // the live vision's configuration (the first one in the log), "" if none
  std::vector<std::size_t> camera_infos;  // the calibrations on VISCO_CAMERA_INFO
  // The controller's faults by utime (the period's), overrun warnings aside; taken once compared.
  std::map<std::int64_t, std::deque<std::size_t>> controller_faults;
};

// Reads and indexes the log; fills the summary's log report, times, frame rate and unknown channels.
// @throws InputError for a log without any usable event, or without vision output to --check against.
LogIndex ReadLog(const ReplayOptions& o, ReplaySummary& s) {
  LogIndex index;
  index.reader = std::make_unique<EventLogReader>(o.log_path);
  LogEvent event;
  while (index.reader->Next(event)) index.events.push_back(event);
  s.log = index.reader->report();
  if (index.events.empty()) throw InputError(o.log_path, "", "no usable event: " + s.log.Describe());
  s.log_start_utime = index.events.front().timestamp;
  s.log_end_utime = index.events.back().timestamp;

  std::int64_t first_image = 0, last_image = 0;
  std::map<std::int64_t, std::int64_t> image_log_utime;  // image_t.utime -> log time, of every image in the log
  std::map<std::int64_t, std::int64_t> first_output;     // frame utime -> log time of vision's first output for it
  for (std::size_t i = 0; i < index.events.size(); ++i) {
    const LogEvent& e = index.events[i];
    const std::string channel(e.channel);
    if (i > 0 && SecondsBetween(index.events[i - 1].timestamp, e.timestamp) < -1.0) ++s.timestamps_backwards;
    if (!Known(channel, o.prefix)) ++s.unknown_channels[channel];
    if (channel == channels::kCameraImage) {
      if (index.images++ == 0) first_image = e.timestamp;
      last_image = e.timestamp;
      std::int64_t utime = 0;
      if (ImageUtime(e, utime)) image_log_utime.emplace(utime, e.timestamp);
    }
    if (channel == control::kCycleChannel) index.cycles.push_back(i);
    if (channel == channels::kCameraInfo) index.camera_infos.push_back(i);
    if (channel == vision::kVisionConfigChannel && index.vision_config.empty()) {
      log_annotation_t a;
      if (DecodeAs(e, a) && a.kind == vision::kVisionConfigKind) index.vision_config = a.text;
    }
    if (channel == control::kAnnotationChannel) {
      log_annotation_t a;
      if (DecodeAs(e, a) && a.kind == "controller_config") index.annotation = static_cast<std::int64_t>(i);
    }
    if (channel == channels::kFault) {
      fault_t f;
      if (DecodeAs(e, f) && f.source == control::kControllerFaultSource &&
          f.code != static_cast<std::int32_t>(control::FaultCode::kOverrun)) {
        index.controller_faults[f.utime].push_back(i);
      }
    }
    std::int64_t frame_utime = 0;
    if (VisionOutputFrame(e, frame_utime)) {
      index.vision_outputs[{channel, frame_utime}].push_back(i);
      index.vision_frames.insert(frame_utime);
      first_output.emplace(frame_utime, e.timestamp);
    }
  }
  for (const auto& [frame_utime, output_log_utime] : first_output) {
    if (image_log_utime.count(frame_utime) > 0) continue;
    ReplaySummary::MissingImage m{frame_utime, output_log_utime, -1};
    // The last image the log holds from before the missing one (in capture time).
    auto before = image_log_utime.lower_bound(frame_utime);
    if (before != image_log_utime.begin()) {
      m.replay_to_s = SecondsBetween(s.log_start_utime, std::prev(before)->second) + 1e-3;
    }
    s.images_missing.push_back(m);
  }
  if (index.images > 1 && last_image > first_image) {
    s.log_frame_rate_hz = static_cast<double>(index.images - 1) / SecondsBetween(first_image, last_image);
  }
  index.last_vision_frame = index.vision_frames.empty() ? 0 : *index.vision_frames.rbegin();
  if (o.check && index.vision_frames.empty()) {
    throw InputError(o.log_path, "",
                     "holds no vision output (VISCO_ROBOT_ESTIMATE, VISCO_VISUAL_EVENTS, ...) to check against: record "
                     "the live run with --log on a process of its bus");
  }
  return index;
}

// Vision's configuration: files and options given on the command line win; the rest is the live run's, from the
// log (VISCO_VISION_CONFIG). The calibration vision ran with: the one its configuration names, else the log's first.
// Fills the summary's config_from_log and config_mismatches. @throws InputError.
vision::LoadedPipeline ResolveVisionConfig(const ReplayOptions& o, const LogIndex& log, ReplaySummary& s) {
  std::optional<vision::CameraCalibration> calibration;
  const std::string calibration_source = vision::VisionConfigCalibrationSource(log.vision_config);
  for (std::size_t i : log.camera_infos) {
    camera_info_t m;
    if (!DecodeAs(log.events[i], m)) continue;
    if (calibration && m.source != calibration_source) continue;
    try {
      calibration = vision::DecodeCameraInfo(m, o.log_path + ": event " + std::to_string(log.events[i].number));
    } catch (const InputError& e) {
      AddNote(s, std::string("unusable calibration: ") + e.what());
      continue;
    }
    if (m.source == calibration_source) break;
  }
  return vision::ResolvePipelineConfig(o.pipeline, log.vision_config, calibration, o.log_path, s.config_mismatches,
                                       s.config_from_log);
}

// Pacing by the gaps between consecutive events, each at most 1 s (a damaged timestamp must not stall the replay);
// the results do not depend on it (the pipeline's clock is the log's).
class Pacer {
 public:
  Pacer(bool fast, double speed) : fast_(fast), speed_(speed) {}
  void Wait(std::int64_t timestamp) {
    if (fast_) return;
    if (!started_) {
      started_ = true;
      next_wall_ = std::chrono::steady_clock::now();
    } else {
      const double gap = std::clamp(SecondsBetween(previous_timestamp_, timestamp), 0.0, 1.0) / speed_;
      next_wall_ += std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(gap));
      std::this_thread::sleep_until(next_wall_);
    }
    previous_timestamp_ = timestamp;
  }

 private:
  bool fast_;
  double speed_;
  bool started_ = false;
  std::int64_t previous_timestamp_ = 0;
  std::chrono::steady_clock::time_point next_wall_;
};

// --step: a prompt before each image, answered by a line of the step input.
class StepPrompt {
 public:
  explicit StepPrompt(const ReplayOptions& o) : on_(o.step), progress_(o.progress), input_(o.step_input) {}
  /// True to process the image, false to stop the replay here.
  bool Ask(const image_t& image, double t) {
    if (!on_) return true;
    if (skip_ > 0) {
      --skip_;
      return true;
    }
    std::fprintf(stderr, "%sreplay: image seq %lld at %.3f s (log time): Enter = next, N = N on, c = go on, q = stop: ",
                 progress_ ? "\n" : "", static_cast<long long>(image.seq), t);
    std::fflush(stderr);
    char line[64];
    if (std::fgets(line, sizeof(line), input_) == nullptr) {
      on_ = false;  // the input ended: go on without stopping
      return true;
    }
    if (line[0] == 'q') return false;
    if (line[0] == 'c') on_ = false;
    const long n = std::strtol(line, nullptr, 10);
    if (n > 1) skip_ = n - 1;
    return true;
  }

 private:
  bool on_;
  bool progress_;
  std::FILE* input_;
  std::int64_t skip_ = 0;
};

// What the replayed vision produced, for the controller.
struct ReplayedVision {
  std::map<std::int64_t, visual_events_t> events;      // by frame seq
  std::map<std::int64_t, robot_estimate_t> estimates;  // by frame seq
  bool differs = false;                                // --check stopped at a difference
};

constexpr const char* kVisionChannels[] = {channels::kTagDetections, channels::kObjectPoses, channels::kRobotEstimate,
                                           channels::kVisualEvents, channels::kFault};

// Compares what vision produced for a frame with what the live process published for it (--check): the first
// difference goes into the summary. Returns true when the log ends inside this frame's outputs.
bool CompareVisionOutput(const char* channel, const std::vector<std::uint8_t>& produced, std::int64_t log_utime,
                         const image_t& image, LogIndex& log, ReplaySummary& s) {
  Difference d{channel, log_utime, image.seq, image.utime, -1, {}};
  auto found = log.vision_outputs.find({channel, image.utime});
  if (found == log.vision_outputs.end() || found->second.empty()) {
    if (image.utime == log.last_vision_frame) return true;  // the process was stopped or killed while publishing
    d.field = {"(message)", "absent", "produced"};
    s.differences.push_back(d);
    return false;
  }
  const LogEvent& live = log.events[found->second.front()];
  found->second.pop_front();
  ++s.compared;
  if (auto diff = CompareMessages(channel, live.data, produced)) {
    d.field = *diff;
    s.differences.push_back(d);
  }
  return false;
}

// The logged images through vision again, on the log's clock; the other logged channels the filter selects are
// republished unchanged. With --check, each output is compared with the live one.
ReplayedVision ReplayVision(const ReplayOptions& o, const std::regex& channel_filter,
                            const vision::LoadedPipeline& loaded, LogIndex& log, Outputs& outputs, ReplaySummary& s) {
  ReplayedVision replayed;
  std::int64_t log_now = 0;
  vision::PipelineOptions options = loaded.options;
  options.clock = [&log_now] { return log_now; };
  vision::VisionPipeline pipeline(loaded.camera, loaded.wMc, loaded.models, options);
  Pacer pacer(o.fast, o.speed);
  StepPrompt step(o);
  bool cut_off = false;
  std::int64_t images_seen = 0;
  // --seek: the first event at or after --from, found in the event table (one scan of the mapped file's headers)
  // without decoding anything; a plain scan, since a damaged log's timestamps need not be sorted.
  std::size_t first_event = 0;
  if (o.seek) {
    while (first_event < log.events.size() &&
           SecondsBetween(s.log_start_utime, log.events[first_event].timestamp) < o.from_s) {
      ++first_event;
    }
    s.seeked_events = static_cast<std::int64_t>(first_event);
  }
  for (std::size_t event_index = first_event; event_index < log.events.size(); ++event_index) {
    const LogEvent& e = log.events[event_index];
    const double t = SecondsBetween(s.log_start_utime, e.timestamp);
    if (t > o.to_s) break;
    const std::string channel(e.channel);
    if (!std::regex_match(channel, channel_filter)) continue;
    if (channel != channels::kCameraImage) {
      if (t < o.from_s || !Known(channel, o.prefix) || channel == "LCM_SELF_TEST") continue;
      pacer.Wait(e.timestamp);
      outputs.Emit(channel, e.timestamp, std::vector<std::uint8_t>(e.data.begin(), e.data.end()));
      ++s.republished;
      continue;
    }
    ++s.images;
    ++images_seen;
    if (o.progress && images_seen % 10 == 0) {
      std::fprintf(stderr, "\rreplay: %lld/%lld images (%.0f%%), %zu difference(s)",
                   static_cast<long long>(images_seen), static_cast<long long>(log.images),
                   100.0 * static_cast<double>(images_seen) / static_cast<double>(log.images), s.differences.size());
    }
    image_t message;
    if (!DecodeAs(e, message)) {
      ++s.undecodable;
      AddNote(s, "event " + std::to_string(e.number) + " at byte " + std::to_string(e.offset) + " on " + channel +
                     " does not decode as visco.image_t: skipped (a live subscriber drops it too)");
      continue;
    }
    if (!log.vision_frames.empty() && log.vision_frames.count(message.utime) == 0) {
      ++s.skipped_frames;  // the live pipeline never saw it (its queue dropped it, or it was killed first)
      continue;
    }
    if (t >= o.from_s && !step.Ask(message, t)) {
      s.stopped_at_step = true;
      break;
    }
    pacer.Wait(e.timestamp);
    log_now = e.timestamp;
    vision::Frame frame;
    std::string error;
    vision::PipelineOutput result;
    if (!vision::DecodeImageMessage(message, frame, error)) {
      result.faults.push_back(pipeline.BadFrame(frame, error));
    } else {
      result = pipeline.Process(frame, e.timestamp);
    }
    if (result.processed) {
      ++s.frames;
      replayed.events[result.events.frame_seq] = result.events;
      replayed.estimates[result.robot.frame_seq] = result.robot;
    } else {
      ++s.bad_frames;
    }
    if (t < o.from_s) {
      ++s.warmup_frames;
      for (const char* c : kVisionChannels) log.vision_outputs.erase({c, message.utime});
      continue;
    }
    vision::ForEachMessage(result, [&](const char* produced_channel, const auto& produced) {
      const std::vector<std::uint8_t> bytes = Encode(produced);
      outputs.Emit(produced_channel, e.timestamp, bytes);
      ++s.produced;
      if (!o.check || !s.differences.empty()) return;
      if (CompareVisionOutput(produced_channel, bytes, e.timestamp, message, log, s)) cut_off = true;
    });
    if (cut_off) {
      AddNote(s, "the log ends inside the outputs of frame seq " + std::to_string(message.seq) +
                     " (the live process stopped): compared up to there");
      break;
    }
    if (o.check && s.differences.empty()) {
      // Whatever the live process published for this frame and the replay did not.
      for (const char* c : kVisionChannels) {
        auto found = log.vision_outputs.find({c, message.utime});
        if (found != log.vision_outputs.end() && !found->second.empty()) {
          s.differences.push_back({c, e.timestamp, message.seq, message.utime, -1, {"(message)", "present", "absent"}});
          break;
        }
      }
    }
    if (o.check && !s.differences.empty()) {
      replayed.differs = true;
      break;
    }
  }
  if (o.progress) std::fprintf(stderr, "\n");
  if (o.check && !replayed.differs) {
    // Vision outputs in the replayed window whose image is not in the log (lost by the logger, or cut off).
    for (const auto& [key, indices] : log.vision_outputs) {
      for (std::size_t i : indices) {
        const double t = SecondsBetween(s.log_start_utime, log.events[i].timestamp);
        if (t < o.from_s || t > o.to_s) continue;
        if (s.unmatched_logged++ == 0) {
          s.differences.push_back({key.first,
                                   log.events[i].timestamp,
                                   -1,
                                   key.second,
                                   -1,
                                   {"(message)", "present", "no image of this frame in the log"}});
        }
      }
    }
  }
  return replayed;
}

// The executor that replays the run: the run's task (the files the log names, or the options' overrides) and its
// configuration, started at the recorded time. @throws InputError for a configuration that is not JSON, a strategy
// that came over LCM without --strategy, or files that do not load.
struct ReplayedExecutor {
  control::Task task;
  std::unique_ptr<control::Executor> executor;
};
ReplayedExecutor MakeExecutor(const ReplayOptions& o, const LogEvent& annotation) {
  log_annotation_t a;
  DecodeAs(annotation, a);
  nlohmann::json config;
  try {
    config = nlohmann::json::parse(a.text);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(o.log_path, "controller_config", std::string("not JSON: ") + e.what());
  }
  control::RunOptions run;
  // The files the log names: a relative name is relative to the log's folder (docs/replay.md), so that a replay
  // works from any directory; those given on the command line are the user's, relative to the working directory.
  auto named = [&](const char* key) {
    const std::filesystem::path path = config.value(key, std::string());
    if (path.empty() || path.is_absolute()) return path.string();
    return (std::filesystem::path(o.log_path).parent_path() / path).lexically_normal().string();
  };
  run.strategy_path = !o.strategy_path.empty() ? o.strategy_path : named("strategy");
  run.scene_path = !o.scene_path.empty() ? o.scene_path : named("scene");
  run.rays_path = !o.rays_path.empty() ? o.rays_path : named("rays");
  if (run.strategy_path.empty()) {
    throw InputError(o.log_path, "controller_config",
                     "the run's strategy came over LCM: give the strategy file with --strategy (or --no-control)");
  }
  ReplayedExecutor r;
  r.task = control::LoadTask(run);
  const control::ExecutorConfig executor_config =
      control::ExecutorConfigFromJson(config.value("executor", nlohmann::json()).dump(), o.log_path);
  r.executor = std::make_unique<control::Executor>(r.task, executor_config);
  r.executor->Start(config.value("start_ns", std::int64_t{0}));
  return r;
}

// Compares a fault the replayed executor raised with the controller's logged fault of the same period (--check).
void CompareFault(const control::FaultEvent& f, LogIndex& log, ReplaySummary& s, ControlDiffer& d) {
  auto logged_fault = log.controller_faults.find(f.utime);
  if (logged_fault == log.controller_faults.end() || logged_fault->second.empty()) {
    d.result = FieldDifference{"fault (message)", "absent", "produced: " + std::string(f.message)};
    return;
  }
  fault_t live_message;
  DecodeAs(log.events[logged_fault->second.front()], live_message);
  logged_fault->second.pop_front();
  ++s.control_faults_compared;
  const control::FaultEvent live = control::FromFaultMessage(live_message);
  d.Field("fault.code", static_cast<std::int64_t>(live.code), static_cast<std::int64_t>(f.code));
  d.Field("fault.severity", std::int64_t{live.severity}, std::int64_t{f.severity});
  d.Field("fault.robot_stopped", std::int64_t{live.robot_stopped}, std::int64_t{f.robot_stopped});
  d.Field("fault.cleared", std::int64_t{live.cleared}, std::int64_t{f.cleared});
  d.Field("fault.message", live_message.message, std::string(f.message));  // as logged, even past FaultEvent's size
}

// Compares the replayed period's command, mode, step and hold with the record (--check).
void CompareCommand(const control::CycleRecord& record, const control::ExecutorOutput& output, ControlDiffer& d) {
  d.Field("command.velocity[0]", record.command.velocity.x, output.command.velocity.x);
  d.Field("command.velocity[1]", record.command.velocity.y, output.command.velocity.y);
  d.Field("command.estop", std::int64_t{record.command.estop}, std::int64_t{output.command.estop});
  d.Field("command.reset", std::int64_t{record.command.reset}, std::int64_t{output.command.reset});
  d.Field("command.quick_stop", std::int64_t{record.command.quick_stop}, std::int64_t{output.command.quick_stop});
  d.Field("mode", static_cast<std::int64_t>(record.mode), static_cast<std::int64_t>(output.mode));
  d.Field("step_index", std::int64_t{record.step_index}, std::int64_t{output.step_index});
  d.Field("holding", std::int64_t{record.holding}, std::int64_t{output.holding});
}

// The controller, period by period on its recorded inputs, with the replayed vision in place of the recorded one.
void ReplayController(const ReplayOptions& o, LogIndex& log, const ReplayedVision& vision, Outputs& outputs,
                      ReplaySummary& s) {
  if (!o.control) {
    s.control_note = "not replayed (--no-control)";
    return;
  }
  if (log.cycles.empty()) {
    s.control_note = "the log holds no controller records (they are written by visco run --log)";
    return;
  }
  if (log.annotation < 0) {
    s.control_note = "the log holds controller records but not the run's configuration (the run did not end normally)";
    s.control_incomplete = true;
    return;
  }
  if (vision.differs) {
    s.control_note = "not replayed: vision already differs";
    return;
  }
  if (s.stopped_at_step) {
    s.control_note = "not replayed: the replay was stopped at a --step prompt";
    return;
  }
  const ReplayedExecutor replayed = MakeExecutor(o, log.events[static_cast<std::size_t>(log.annotation)]);
  control::Executor& executor = *replayed.executor;
  control::ExecutorOutput output;
  std::int64_t previous_cycle = -1, last_utime = 0;
  for (std::size_t index : log.cycles) {
    const LogEvent& e = log.events[index];
    controller_cycle_t m;
    if (!DecodeAs(e, m)) {
      ++s.undecodable;
      s.control_incomplete = true;
      AddNote(s, "event " + std::to_string(e.number) + " on " + control::kCycleChannel +
                     " does not decode as visco.controller_cycle_t: skipped");
      continue;
    }
    const double t = SecondsBetween(s.log_start_utime, m.utime);
    if (t > o.to_s) break;
    if (m.cycle != previous_cycle + 1) {
      s.control_note = "period records missing before cycle " + std::to_string(m.cycle) +
                       " (dropped by the run's recorder or the log): the controller is compared up to there";
      s.control_incomplete = true;
      break;
    }
    previous_cycle = m.cycle;
    last_utime = m.utime;
    const control::CycleRecord record = control::FromCycleMessage(m);
    const control::ExecutorInput& recorded = record.input;
    control::ExecutorInput in = recorded;
    ControlDiffer d;
    if (in.have_frame) {
      auto found = vision.events.find(in.frame.frame_seq);
      if (found != vision.events.end()) {
        in.frame =
            control::ToVisualFrame(found->second, replayed.task, recorded.frame.capture_ns, found->second.frame_utime);
        CompareFrames(d, recorded.frame, in.frame);
        ++s.control_frames_from_vision;
      } else {
        ++s.control_frames_recorded;
      }
    }
    if (in.have_estimate) {
      auto found = vision.estimates.find(in.estimate.frame_seq);
      if (found != vision.estimates.end()) {
        in.estimate = control::ToPositionEstimate(found->second, recorded.estimate.capture_ns, found->second.utime);
        CompareEstimates(d, recorded.estimate, in.estimate);
      }
    }
    executor.Update(in, output);
    ++s.control_cycles;
    velocity_command_t command{};
    command.utime = in.now_utime;
    command.seq = output.command.seq;
    command.velocity[0] = output.command.velocity.x;
    command.velocity[1] = output.command.velocity.y;
    command.estop = output.command.estop;
    command.reset = output.command.reset;
    command.quick_stop = output.command.quick_stop;
    outputs.Emit(channels::kCommand, in.now_utime, Encode(command));
    ++s.produced;
    for (int i = 0; i < output.num_faults; ++i) {
      const control::FaultEvent& f = output.faults[i];
      outputs.Emit(channels::kFault, in.now_utime, Encode(control::ToFaultMessage(f)));
      ++s.produced;
      if (o.check && t >= o.from_s && !d.result) CompareFault(f, log, s, d);
    }
    if (!o.check || t < o.from_s) continue;
    ++s.control_compared;
    CompareCommand(record, output, d);
    if (d.result) {
      s.differences.push_back(
          {control::kCycleChannel, m.utime, in.have_frame ? in.frame.frame_seq : -1, 0, m.cycle, *d.result});
      break;
    }
  }
  if (o.check && s.differences.empty()) {
    for (const auto& [utime, indices] : log.controller_faults) {
      if (indices.empty()) continue;
      const double t = SecondsBetween(s.log_start_utime, utime);
      if (t < o.from_s || t > o.to_s || utime > last_utime) continue;
      fault_t live;
      DecodeAs(log.events[indices.front()], live);
      s.differences.push_back(
          {channels::kFault, utime, -1, 0, -1, {"fault (message)", "present: " + live.message, "absent"}});
      break;
    }
  }
}

}  // namespace

ReplaySummary RunReplay(const ReplayOptions& o) {
  const std::regex channel_filter = CheckOptions(o);
  if (o.log_path.empty()) {
    std::vector<std::string> mismatches, from_log;
    const std::string source = o.images_dir.empty() ? o.video_path : o.images_dir;
    return ReplaySource(o, vision::ResolvePipelineConfig(o.pipeline, "", std::nullopt, source, mismatches, from_log));
  }

  const auto wall_start = std::chrono::steady_clock::now();
  ReplaySummary s;
  s.publishing = o.publish;
  s.checked = o.check;
  LogIndex log = ReadLog(o, s);
  const vision::LoadedPipeline loaded = ResolveVisionConfig(o, log, s);
  Outputs outputs(o);
  const ReplayedVision vision = ReplayVision(o, channel_filter, loaded, log, outputs, s);
  ReplayController(o, log, vision, outputs, s);
  if (std::string dropped = outputs.Close(); !dropped.empty()) AddNote(s, std::move(dropped));
  s.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  if (s.frames == 0 && s.bad_frames == 0 && s.republished == 0 && s.skipped_frames == 0) {
    throw InputError(o.log_path, "",
                     "nothing usable to replay: " + std::to_string(s.images) + " image event(s), " +
                         std::to_string(s.undecodable) + " undecodable; " + s.log.Describe());
  }
  return s;
}

CheckVerdict JudgeCheck(const ReplaySummary& s) {
  if (!s.identical()) return CheckVerdict::kDifferent;
  return IncompleteLogReason(s).empty() ? CheckVerdict::kIdentical : CheckVerdict::kIncomplete;
}

std::string IncompleteLogReason(const ReplaySummary& s) {
  std::vector<std::string> parts;
  if (s.log.skipped_ranges > 0) {
    parts.push_back(std::to_string(s.log.skipped_bytes) + " byte(s) skipped in " +
                    std::to_string(s.log.skipped_ranges) + " range(s)" +
                    (s.log.truncated_tail ? " (the file ends in a cut-off event)" : ""));
  }
  if (s.log.number_gaps > 0) {
    parts.push_back(std::to_string(s.log.missing_numbers) + " event(s) missing by their numbers");
  }
  if (s.timestamps_backwards > 0) {
    parts.push_back(std::to_string(s.timestamps_backwards) + " timestamp(s) more than 1 s before the previous event's");
  }
  if (s.undecodable > 0) parts.push_back(std::to_string(s.undecodable) + " message(s) that do not decode");
  std::int64_t unknown = 0;
  for (const auto& [channel, count] : s.unknown_channels) unknown += LooksLikeDamagedName(channel) ? count : 0;
  if (unknown > 0) {
    parts.push_back(std::to_string(unknown) + " event(s) on unknown channels named like visco's (damaged names)");
  }
  if (s.control_incomplete) parts.push_back("the controller's records are incomplete: " + s.control_note);
  std::string out;
  for (const std::string& p : parts) out += (out.empty() ? "" : "; ") + p;
  return out;
}

std::string ReplaySummary::ToJson() const {
  nlohmann::json j;
  // Claimed only when shown: null without --check; false when --check compared nothing, found a difference or the
  // log is not whole (JudgeCheck: a damaged log is never called identical).
  j["checked"] = checked;
  j["identical"] = checked ? nlohmann::json(JudgeCheck(*this) == CheckVerdict::kIdentical) : nlohmann::json(nullptr);
  j["incomplete_log"] = IncompleteLogReason(*this);
  j["stopped_at_step"] = stopped_at_step;
  j["seeked_events"] = seeked_events;
  j["images"] = images;
  j["frames"] = frames;
  j["bad_frames"] = bad_frames;
  j["undecodable"] = undecodable;
  j["skipped_frames"] = skipped_frames;
  j["warmup_frames"] = warmup_frames;
  j["produced"] = produced;
  j["published"] = publishing ? produced : 0;
  j["republished"] = publishing ? republished : 0;
  j["compared"] = compared;
  j["unmatched_logged"] = unmatched_logged;
  nlohmann::json missing = nlohmann::json::array();
  for (const MissingImage& m : images_missing) {
    missing.push_back({{"frame_utime", m.frame_utime},
                       {"output_log_utime", m.output_log_utime},
                       {"replay_to_s", m.replay_to_s >= 0 ? nlohmann::json(m.replay_to_s) : nlohmann::json(nullptr)}});
  }
  j["images_missing"] = missing;
  j["differences"] = differences.size();
  if (!differences.empty()) {
    const Difference& d = differences.front();
    j["first_difference"] = {{"channel", d.channel},         {"cycle", d.cycle},
                             {"log_utime", d.log_utime},     {"frame_seq", d.frame_seq},
                             {"frame_utime", d.frame_utime}, {"field", d.field.field},
                             {"logged", d.field.logged},     {"replayed", d.field.replayed}};
  }
  nlohmann::json skipped = nlohmann::json::array();
  for (const SkippedRange& r : log.skipped)
    skipped.push_back({{"offset", r.offset}, {"bytes", r.bytes}, {"reason", r.reason}});
  j["log"] = {{"bytes", log.file_bytes},
              {"events", log.events},
              {"skipped_bytes", log.skipped_bytes},
              {"skipped_ranges", log.skipped_ranges},
              {"skipped", skipped},
              {"truncated_tail", log.truncated_tail},
              {"number_gaps", log.number_gaps},
              {"missing_events", log.missing_numbers},
              {"duration_s", SecondsBetween(log_start_utime, log_end_utime)},
              {"frame_rate_hz", log_frame_rate_hz}};
  j["control"] = {{"cycles", control_cycles},
                  {"compared", control_compared},
                  {"frames_from_vision", control_frames_from_vision},
                  {"frames_recorded", control_frames_recorded},
                  {"faults_compared", control_faults_compared},
                  {"note", control_note}};
  j["config"] = {{"from_log", config_from_log}, {"mismatches", config_mismatches}};
  j["unknown_channels"] = unknown_channels;
  j["notes"] = notes;
  j["wall_s"] = wall_s;
  j["frames_per_s"] = wall_s > 0 ? static_cast<double>(frames + bad_frames) / wall_s : 0.0;
  return j.dump();
}

}  // namespace visco::replay

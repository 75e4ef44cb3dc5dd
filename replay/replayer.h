#pragma once
// `visco replay`: the logged camera images go through the vision pipeline again, on the log's clock, and what it
// produces is published (on prefixed channels unless armed), written to a log, and, with `check`, compared field by
// field with what the live process published into the same log.
//
// When the log holds the controller's per-period records (`visco run --log`: VISCO_CONTROLLER_CYCLE and the run's
// configuration), the executor runs again too: period by period on the recorded inputs, with the visual events and
// the robot estimate of each period taken from the replayed vision output of the same frame (converted by the
// bridge's own ToVisualFrame / ToPositionEstimate), and its commands, mode and faults compared with the log.
//
// The seam between live and log: the live `visco track --lcm` decodes each image_t with vision::DecodeImageMessage,
// hands the frame to vision::VisionPipeline::Process and publishes vision::ForEachMessage's messages; the replay does
// exactly that with the logged bytes, and gives the pipeline the log's receive time of the image as its clock
// (PipelineOptions::clock), so that nothing it computes depends on the wall clock or on the replay's speed.

#include <cstdint>
#include <cstdio>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "replay/event_log.h"
#include "replay/message_diff.h"
#include "vision/pipeline_config.h"

namespace visco::replay {

struct ReplayOptions {
  std::string log_path;
  std::string images_dir;        // instead of a log: an image folder (name order, timestamps start_utime + i / fps)
  std::string video_path;        // ... or a video file (OpenCV; the container's timestamps)
  double fps = 30;               // of an image folder
  std::int64_t start_utime = 0;  // microseconds since the epoch of a folder's or video's first frame (deterministic)
  vision::PipelineConfig pipeline;
  bool fast = false;   // as fast as possible (default: at the log's pace times `speed`)
  double speed = 1.0;  // pace, multiple of the log's
  double from_s = 0;   // seconds after the log's first event: publish and compare from here (frames before it
                       // still go through vision, so that its tracking state is the live one)
  double to_s = std::numeric_limits<double>::infinity();  // ... up to here
  std::string channels = "VISCO_CAMERA_IMAGE";            // regex of the logged channels to replay; non-image ones are
                                                          // republished unchanged
  bool check = false;
  std::string out_path;  // write what the replay produces to this log
  bool publish = true;   // publish on LCM
  std::string lcm_url;   // "" = LCM's default
  std::string prefix = "REPLAY_";
  bool arm = false;                                  // publish on the live channel names
  std::string can_interface;                         // refused without `arm`
  bool progress = false;                             // a progress line on stderr
  bool control = true;                               // replay the controller when the log holds its records
  std::string strategy_path, scene_path, rays_path;  // override the run's files (default: those the log names)
  // Step through the images of [from, to]: before each one, a prompt on stderr and a line from `step_input`: empty
  // for the next image, a number N for N images on, "c" to go on without stopping, "q" to stop there. The end of
  // the input goes on without stopping.
  bool step = false;
  std::FILE* step_input = stdin;
  // Start at --from directly: the images before it are not run through vision (vision starts fresh there, so its
  // tracking state is not the live run's: not with --check).
  bool seek = false;
};

struct Difference {
  std::string channel;
  std::int64_t log_utime = 0;    // receive time of the frame's image in the log
  std::int64_t frame_seq = -1;   // image_t.seq
  std::int64_t frame_utime = 0;  // image_t.utime (capture)
  std::int64_t cycle = -1;       // controller period (control differences)
  FieldDifference field;
};

struct ReplaySummary {
  ReadReport log;
  bool stopped_at_step = false;    // "q" at a --step prompt
  std::int64_t seeked_events = 0;  // events before --from that --seek skipped
  std::int64_t log_start_utime = 0, log_end_utime = 0;
  double log_frame_rate_hz = 0;  // images per second of log time
  std::int64_t images = 0;       // image events replayed
  std::int64_t frames = 0;       // frames vision processed
  std::int64_t bad_frames = 0;   // frames vision rejected (reported as faults, as live)
  std::int64_t undecodable = 0;  // events that do not decode as their channel's type
  // Frames the live pipeline never processed (the log holds vision output, none for them): skipped, so that vision's
  // state follows the live run.
  std::int64_t skipped_frames = 0;
  std::int64_t warmup_frames = 0;     // frames before --from (processed, not published)
  std::int64_t produced = 0;          // messages produced (published, written with --out, or neither)
  bool publishing = false;            // produced messages went out on LCM (not --no-publish)
  bool checked = false;               // --check: compared with the log
  std::int64_t republished = 0;       // logged non-image messages passed on unchanged
  std::int64_t compared = 0;          // messages compared with the log
  std::int64_t unmatched_logged = 0;  // logged vision outputs no replayed frame produced
  // Frames the live vision published outputs for whose image is not in the log (lost by the logger, e.g. a UDP
  // datagram under load): their image_t.utime and the log time of their first output. Vision's state carries from
  // frame to frame, so a replay differs after the first of them.
  struct MissingImage {
    std::int64_t frame_utime = 0;
    std::int64_t output_log_utime = 0;
    double replay_to_s = -1;  // --to up to the last image before it (seconds after the log's first event); -1: none
  };
  std::vector<MissingImage> images_missing;
  std::vector<Difference> differences;          // --check stops at the first
  std::int64_t control_cycles = 0;              // controller periods replayed
  std::int64_t control_compared = 0;            // periods whose command, mode and faults were compared
  std::int64_t control_frames_from_vision = 0;  // periods whose visual input came from the replayed vision
  std::int64_t control_frames_recorded = 0;     // ... from the record (their frame was not replayed)
  std::int64_t control_faults_compared = 0;
  std::string control_note;  // why the controller was not replayed, if it was not
  // The controller's records are incomplete: missing or undecodable period records, or records without the run's
  // configuration (written at the end: a log cut off). Its comparison covers only part of the run.
  bool control_incomplete = false;
  // Events whose receive time is more than a second before the previous event's (a damaged timestamp: logs written
  // by visco's or LCM's logger go back by a few milliseconds at most, when two threads of one process publish).
  std::int64_t timestamps_backwards = 0;
  std::map<std::string, std::int64_t> unknown_channels;  // channel -> events
  std::vector<std::string> config_from_log;    // what of vision's configuration came from the log (VISCO_VISION_CONFIG)
  std::vector<std::string> config_mismatches;  // files or options given that differ from the log's
  std::vector<std::string> notes;              // undecodable events and other remarks (the first few)
  double wall_s = 0;
  /// Messages and controller periods compared with the log.
  std::int64_t compared_total() const { return compared + control_compared; }
  /// Shown identical: --check ran, compared something and found no difference.
  bool identical() const { return checked && differences.empty() && unmatched_logged == 0 && compared_total() > 0; }
  std::string ToJson() const;
};

/// Runs the replay. @throws InputError for bad options or a log with nothing usable (exit 2).
ReplaySummary RunReplay(const ReplayOptions& options);

/// What `visco replay --check` concludes from a summary (docs/replay.md, "Exit statuses").
enum class CheckVerdict {
  kIdentical,   ///< exit 0: everything compared is identical, and the log is whole
  kDifferent,   ///< exit 1: a difference
  kIncomplete,  ///< exit 3: what could be compared is identical, but part of the log is damaged or missing
};
CheckVerdict JudgeCheck(const ReplaySummary& summary);
/// What is damaged or missing in the log, for users ("" when nothing is): skipped bytes, a cut-off tail, missing
/// event numbers, timestamps going back, undecodable messages, unknown VISCO_ channels (a damaged name), incomplete
/// controller records.
std::string IncompleteLogReason(const ReplaySummary& summary);

}  // namespace visco::replay

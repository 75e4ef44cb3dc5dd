#include "replay/commands.h"

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <memory>

#include "common/error.h"
#include "replay/replayer.h"

namespace visco::replay {
namespace {

// Thrown to end the loops when the user stops at a --step prompt (the summary of that replay is printed).
struct Interrupted {};

void RunOnce(const ReplayOptions& o, int loop, int loops) {
  if (loops > 1) std::fprintf(stderr, "replay: loop %d of %d\n", loop, loops);
  const ReplaySummary s = RunReplay(o);
  if (!s.log.clean()) std::fprintf(stderr, "replay: %s: %s\n", o.log_path.c_str(), s.log.Describe().c_str());
  for (const auto& [channel, count] : s.unknown_channels) {
    std::fprintf(stderr, "replay: unknown channel %s (%lld event(s)): not replayed\n", channel.c_str(),
                 static_cast<long long>(count));
  }
  for (const std::string& note : s.notes) std::fprintf(stderr, "replay: %s\n", note.c_str());
  for (const std::string& m : s.config_mismatches) std::fprintf(stderr, "replay: mismatch: %s\n", m.c_str());
  std::printf("%s\n", s.ToJson().c_str());
  std::fflush(stdout);
  if (!s.control_note.empty()) std::fprintf(stderr, "replay: controller: %s\n", s.control_note.c_str());
  if (s.control_cycles > 0) {
    std::fprintf(stderr, "replay: controller: %lld period(s) through the executor (%lld with the replayed vision)\n",
                 static_cast<long long>(s.control_cycles), static_cast<long long>(s.control_frames_from_vision));
  }
  std::fprintf(stderr, "replay: %lld frame(s) through vision (%lld rejected as live), %lld message(s) produced%s",
               static_cast<long long>(s.frames), static_cast<long long>(s.bad_frames),
               static_cast<long long>(s.produced), o.publish ? "" : " (not published: --no-publish)");
  const CheckVerdict verdict = JudgeCheck(s);
  if (o.check) {
    std::fprintf(stderr, ", %lld compared (%lld vision message(s), %lld controller period(s)), %s\n",
                 static_cast<long long>(s.compared_total()), static_cast<long long>(s.compared),
                 static_cast<long long>(s.control_compared),
                 verdict == CheckVerdict::kIdentical    ? "identical"
                 : verdict == CheckVerdict::kIncomplete ? "identical as far as compared, but the LOG IS INCOMPLETE"
                                                        : (s.differences.empty() ? "nothing compared" : "DIFFERENT"));
  } else {
    std::fprintf(stderr, "\n");
  }
  // An image live vision processed that the log lacks, before the difference: the likely cause, said with it.
  auto missing_image_before = [&](std::int64_t log_utime) {
    for (const ReplaySummary::MissingImage& m : s.images_missing) {
      if (m.output_log_utime > log_utime) break;
      std::string text = "; the log lacks the image of a frame live vision processed before it (capture utime " +
                         std::to_string(m.frame_utime) + ", lost by the logger): vision's state carries from frame " +
                         "to frame, so the replay differs after it";
      if (m.replay_to_s >= 0) {
        char to[64];
        std::snprintf(to, sizeof to, "%.6f", m.replay_to_s);
        text += std::string("; --to ") + to + " compares up to the last image before it";
      }
      return text;
    }
    return std::string();
  };
  if (o.check && s.differences.empty() && !s.identical()) {
    throw JobFailed("replay --check: " +
                    std::string(s.compared_total() == 0
                                    ? "nothing was compared (no vision output or controller period of the log was "
                                      "replayed): nothing is shown identical"
                                    : "logged vision outputs that no replayed frame produced"));
  }
  if (o.check && !s.identical()) {
    const Difference& d = s.differences.front();
    const std::string where =
        d.cycle >= 0 ? "controller cycle " + std::to_string(d.cycle) + ", frame seq " + std::to_string(d.frame_seq)
                     : "frame seq " + std::to_string(d.frame_seq) + ", capture utime " + std::to_string(d.frame_utime);
    throw JobFailed("replay --check: first difference on " + d.channel + " at log time " + std::to_string(d.log_utime) +
                    " (" + where + "), field " + d.field.field + ": log " + d.field.logged + ", replay " +
                    d.field.replayed + missing_image_before(d.log_utime));
  }
  if (o.check && verdict == CheckVerdict::kIncomplete) {
    throw Incomplete("replay --check: " + o.log_path + " is incomplete (" + IncompleteLogReason(s) + "): the " +
                     std::to_string(s.compared_total()) +
                     " message(s) and period(s) compared are identical, what is damaged or missing was not checked");
  }
  if (s.stopped_at_step) throw Interrupted();
}

void Run(const ReplayOptions& options, int loops) {
  ReplayOptions o = options;
  o.progress = o.progress && ::isatty(STDERR_FILENO) == 1;
  if (loops < 1) throw InputError("command line", "--loop", "must be at least 1");
  if (loops > 1 && o.check) {
    throw InputError("command line", "--loop", "repeats a replay for watching it; --check compares once");
  }
  try {
    // Every loop is a replay of its own (a fresh pipeline and controller): each gives the same output.
    for (int loop = 1; loop <= loops; ++loop) RunOnce(o, loop, loops);
  } catch (const Interrupted&) {
    std::fprintf(stderr, "replay: stopped at a --step prompt\n");
  }
}

}  // namespace

void RegisterCommands(CLI::App& app) {
  auto o = std::make_shared<ReplayOptions>();
  CLI::App* cmd = app.add_subcommand(
      "replay",
      "Replay an LCM event log (lcm-logger format, e.g. written by --log of run, sim, track or driver): the logged "
      "camera images (VISCO_CAMERA_IMAGE) go through the vision pipeline again, on the log's clock, with the "
      "options `visco track` had; what it produces is published on prefixed channels (REPLAY_VISCO_...) unless "
      "--arm, and written to --out. --check compares it field by field with what the live process logged and exits "
      "1 at the first difference (channel, time, field), 0 when identical. A damaged log (truncated, flipped bits, "
      "wrong sync words, unknown channels, undecodable messages) is reported; exit 2 when nothing usable remains. "
      "Prints a JSON summary. See docs/replay.md.");
  cmd->add_option("LOG", o->log_path, "the event log (or --images / --video)");
  cmd->add_option("--images", o->images_dir, "instead of a log: a folder of image files, in name order");
  cmd->add_option("--video", o->video_path, "instead of a log: a video file (OpenCV)");
  cmd->add_option("--fps", o->fps, "frame rate of an image folder (timestamps)")->capture_default_str();
  cmd->add_option("--start-utime", o->start_utime,
                  "capture time of a folder's or video's first frame, microseconds since the epoch")
      ->capture_default_str();
  vision::AddPipelineConfigOptions(*cmd, o->pipeline, vision::ConfigDefaults::kLog);
  cmd->add_flag("--fast", o->fast, "as fast as possible instead of at the log's pace");
  cmd->add_option("--speed", o->speed, "pace as a multiple of the log's")->capture_default_str();
  cmd->add_option("--from", o->from_s,
                  "publish and compare from T seconds after the log's first event (earlier frames still go through "
                  "vision, so that its tracking state is the live one)");
  cmd->add_option("--to", o->to_s, "stop T seconds after the log's first event");
  cmd->add_option("--channels", o->channels,
                  "regular expression of the logged channels to replay: images go through vision, other visco "
                  "channels are republished unchanged")
      ->capture_default_str();
  cmd->add_flag("--check", o->check, "compare with the log; exit 1 at the first difference");
  cmd->add_option("--out", o->out_path, "write what the replay produces to this event log");
  cmd->add_flag("!--no-publish", o->publish, "do not publish on LCM");
  cmd->add_option("--lcm-url", o->lcm_url, "LCM provider URL for publishing (LCM's default when empty)");
  cmd->add_option("--prefix", o->prefix, "channel prefix of what the replay publishes")->capture_default_str();
  cmd->add_flag("--arm", o->arm, "publish on the live channel names (a live controller may act on them)");
  cmd->add_option("--can", o->can_interface, "a CAN interface: refused unless --arm");
  cmd->add_flag("!--no-progress", o->progress, "no progress line on a terminal");
  cmd->add_flag("!--no-control", o->control, "do not replay the controller (its records from visco run --log)");
  cmd->add_option("--strategy", o->strategy_path, "controller: the strategy file (default: the one the log names)");
  cmd->add_option("--scene", o->scene_path, "controller: the scene file (default: the one the log names)");
  cmd->add_option("--rays", o->rays_path, "controller: the rays file (default: the one the log names)");
  cmd->add_flag("--seek", o->seek,
                "start at --from directly (found in the log's event table, nothing decoded): the images before it do "
                "not go through vision, so vision starts fresh there (not with --check)");
  cmd->add_flag("--step", o->step,
                "step through the log's images in [--from, --to]: a prompt before each (Enter: next, N: N on, c: go "
                "on, q: stop)");
  auto loops = std::make_shared<int>(1);
  cmd->add_option("--loop", *loops, "replay [--from, --to] this many times (each replay from a fresh pipeline)")
      ->capture_default_str();
  o->progress = true;
  cmd->callback([o, loops] { Run(*o, *loops); });
}

}  // namespace visco::replay

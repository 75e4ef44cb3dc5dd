// `visco replay --check` on damaged copies of the checked-in log, with no file but the log (the calibration,
// extrinsics, object models and options come from its VISCO_VISION_CONFIG): the copy with its images stored raw
// (GRAY8, the same pixels) is identical; a copy damaged in seeded random ways (pixels in the middle of an image;
// truncation anywhere; a garbled event header) is never called identical, and never crashes.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>
#include <vector>

#include "common/error.h"
#include "lcmtypes/channels.h"
#include "replay/event_log.h"
#include "replay/replayer.h"
#include "visco/image_t.hpp"

namespace visco::replay {
namespace {

#if defined(__SANITIZE_ADDRESS__)
constexpr int kDefaultCases = 3;  // per kind; each replay is ~10x slower under ASan
#else
constexpr int kDefaultCases = 8;
#endif

int Cases() {
  const char* env = std::getenv("VISCO_FUZZ_ITERATIONS");  // to run longer by hand
  return env != nullptr ? std::max(1, std::atoi(env)) : kDefaultCases;
}

struct Event {
  std::int64_t timestamp;
  std::string channel;
  std::vector<std::uint8_t> data;
};

std::vector<std::uint8_t> Encode(const std::vector<Event>& events, std::vector<std::size_t>* offsets) {
  std::vector<std::uint8_t> out;
  auto be = [&out](std::uint64_t v, int bytes) {
    for (int k = bytes - 1; k >= 0; --k) out.push_back(static_cast<std::uint8_t>(v >> (8 * k)));
  };
  for (std::size_t i = 0; i < events.size(); ++i) {
    if (offsets != nullptr) offsets->push_back(out.size());
    be(0xEDA1DA01u, 4);
    be(i, 8);
    be(static_cast<std::uint64_t>(events[i].timestamp), 8);
    be(events[i].channel.size(), 4);
    be(events[i].data.size(), 4);
    out.insert(out.end(), events[i].channel.begin(), events[i].channel.end());
    out.insert(out.end(), events[i].data.begin(), events[i].data.end());
  }
  return out;
}

// The fixture with every PNG image stored raw: the same pixels, so vision's output (pixel digest included) is the
// same; a raw image is what a demo logs, and damage inside it decodes without complaint.
std::vector<Event> RawFixture() {
  std::ifstream in("tests/replay/data/slot_run.lcmlog", std::ios::binary);
  EXPECT_TRUE(in.good()) << "run from the repository top";
  const std::vector<std::uint8_t> bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  EventLogReader reader(bytes);
  std::vector<Event> events;
  LogEvent e;
  while (reader.Next(e)) {
    Event out{e.timestamp, std::string(e.channel), std::vector<std::uint8_t>(e.data.begin(), e.data.end())};
    if (out.channel == channels::kCameraImage) {
      image_t image;
      EXPECT_GE(image.decode(out.data.data(), 0, static_cast<int>(out.data.size())), 0);
      if (image.pixel_format == image_t::PIXEL_FORMAT_PNG) {
        const cv::Mat m = cv::imdecode(image.data, cv::IMREAD_GRAYSCALE);
        EXPECT_FALSE(m.empty());
        image.pixel_format = image_t::PIXEL_FORMAT_GRAY8;
        image.row_stride = m.cols;
        image.data.assign(m.data, m.data + m.total());
        image.size = static_cast<std::int32_t>(image.data.size());
        out.data.resize(static_cast<std::size_t>(image.getEncodedSize()));
        image.encode(out.data.data(), 0, static_cast<int>(out.data.size()));
      }
    }
    events.push_back(std::move(out));
  }
  EXPECT_TRUE(reader.report().clean());
  return events;
}

struct Outcome {
  CheckVerdict verdict = CheckVerdict::kIdentical;
  bool reported = false;  // an exception (exit 1 or 2) or something in the log's report
  std::string what;
};

Outcome Check(const std::vector<std::uint8_t>& bytes, const std::string& path) {
  {
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  }
  ReplayOptions o;
  o.log_path = path;  // and no other vision file: vision's configuration is the log's
  // The copy is not beside the fixture, whose controller record names its run's files relative to the fixture's
  // folder: they are given, as a user replaying a copy elsewhere would.
  o.strategy_path = "tests/control/data/slot_e2e_plan.json";
  o.scene_path = "tests/control/data/slot_e2e_scene.json";
  o.rays_path = "tests/replay/data/slot_e2e_rays.json";
  o.fast = true;
  o.publish = false;
  o.check = true;
  Outcome r;
  try {
    const ReplaySummary s = RunReplay(o);
    r.verdict = JudgeCheck(s);
    r.reported = !IncompleteLogReason(s).empty();
    r.what = s.ToJson().substr(0, 300);
  } catch (const InputError& e) {
    r.verdict = CheckVerdict::kDifferent;  // exit 2
    r.what = e.what();
  } catch (const JobFailed& e) {
    r.verdict = CheckVerdict::kDifferent;  // exit 1
    r.what = e.what();
  }
  return r;
}

TEST(ReplayCheck, DamagedLogIsNeverIdentical) {
  const std::vector<Event> events = RawFixture();
  ASSERT_GT(events.size(), 1000u);
  std::vector<std::size_t> offsets;
  const std::vector<std::uint8_t> raw = Encode(events, &offsets);
  const std::string path =
      (std::filesystem::temp_directory_path() / ("visco_check_damage_" + std::to_string(::getpid()) + ".lcmlog"))
          .string();
  // Undamaged, raw: identical, with no file but the log.
  const Outcome whole = Check(raw, path);
  EXPECT_EQ(whole.verdict, CheckVerdict::kIdentical) << whole.what;

  std::vector<std::size_t> images;
  for (std::size_t i = 0; i < events.size(); ++i) {
    if (events[i].channel == channels::kCameraImage) images.push_back(i);
  }
  const int cases = Cases();
  int pixel_cases = 0, truncations = 0, headers = 0, small_timestamp_changes = 0;
  for (int c = 0; c < cases; ++c) {
    std::mt19937 rng(20261207u + static_cast<std::uint32_t>(c));
    {
      // 64 bytes changed in the middle of an image's pixels (the image_t's last bytes are its pixels): an image
      // whose damage changes no tag, pose or event is still told apart by its pixel digest.
      std::vector<std::uint8_t> bytes = raw;
      const std::size_t i = images[rng() % images.size()];
      const std::size_t end = offsets[i] + kHeaderBytes + events[i].channel.size() + events[i].data.size();
      const std::size_t start = end - 640 * 480 / 2 + (rng() % 1000) * 64;
      for (std::size_t k = start; k < start + 64; ++k) bytes[k] ^= static_cast<std::uint8_t>(1 + rng() % 255);
      const Outcome r = Check(bytes, path);
      EXPECT_NE(r.verdict, CheckVerdict::kIdentical) << "pixels of event " << i << ": " << r.what;
      ++pixel_cases;
    }
    {
      // Truncated anywhere after the first second of the log.
      std::vector<std::uint8_t> bytes = raw;
      bytes.resize(raw.size() / 10 + rng() % (raw.size() - raw.size() / 10));
      const Outcome r = Check(bytes, path);
      EXPECT_NE(r.verdict, CheckVerdict::kIdentical) << "truncated at " << bytes.size() << ": " << r.what;
      ++truncations;
    }
    {
      // 1-3 bytes of one event's header or channel name garbled.
      std::vector<std::uint8_t> bytes = raw;
      const std::size_t i = rng() % events.size();
      const std::size_t span = kHeaderBytes + events[i].channel.size();
      bool only_timestamp = true;
      std::int64_t timestamp_change = 0;
      const int n = 1 + static_cast<int>(rng() % 3);
      for (int k = 0; k < n; ++k) {
        const std::size_t at = rng() % span;
        const auto flip = static_cast<std::uint8_t>(1 + rng() % 255);
        bytes[offsets[i] + at] ^= flip;
        only_timestamp = only_timestamp && at >= 12 && at < 20;
      }
      for (int k = 0; k < 8; ++k) {
        timestamp_change = (timestamp_change << 8) | bytes[offsets[i] + 12 + static_cast<std::size_t>(k)];
      }
      timestamp_change -= events[i].timestamp;
      const Outcome r = Check(bytes, path);
      if (only_timestamp && std::abs(timestamp_change) < 1000000) {
        // A receive time moved by less than a second: the format has no checksum to see it, and nothing a replay
        // compares depends on it (vision's clock sets only the publication stamps the comparison leaves out).
        EXPECT_EQ(r.verdict, CheckVerdict::kIdentical) << r.what;
        ++small_timestamp_changes;
      } else {
        EXPECT_NE(r.verdict, CheckVerdict::kIdentical) << "header of event " << i << ": " << r.what;
      }
      ++headers;
    }
  }
  std::filesystem::remove(path);
  std::printf(
      "damaged copies, none called identical: %d with pixels changed, %d truncated, %d with a garbled header "
      "(%d of them only a receive time moved by < 1 s: undetectable, outputs identical)\n",
      pixel_cases, truncations, headers, small_timestamp_changes);
}

}  // namespace
}  // namespace visco::replay

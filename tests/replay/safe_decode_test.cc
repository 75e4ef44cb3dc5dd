// SafeDecode: every message type the replay decodes round-trips; damaged array counts (negative, huge) and truncated
// messages are refused without an exception or a huge allocation.

#include "replay/safe_decode.h"

#include <gtest/gtest.h>

#include <vector>

#include "tests/lcmtypes/fill_messages.h"

namespace visco::replay {
namespace {

template <class M>
std::vector<std::uint8_t> Encoded() {
  M m;
  testing::Fill(m);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

// Round trip, truncation at every 7th length, and a negative or huge value written over every 4-byte window (so
// over every count field, whichever offset it has).
template <class M>
void ExpectSafe() {
  const std::vector<std::uint8_t> good = Encoded<M>();
  M decoded;
  EXPECT_TRUE(SafeDecode(good, decoded)) << M::getTypeName();
  std::vector<std::uint8_t> again(static_cast<std::size_t>(decoded.getEncodedSize()));
  decoded.encode(again.data(), 0, static_cast<int>(again.size()));
  EXPECT_EQ(again, good) << M::getTypeName();
  // Truncated: refused.
  for (std::size_t n = 0; n < good.size(); n += 7) {
    M m;
    EXPECT_FALSE(SafeDecode(std::span<const std::uint8_t>(good.data(), n), m)) << M::getTypeName() << " cut at " << n;
  }
  // Every 4-byte window set to a negative or a huge count: never an exception (SafeDecode would pass it on) and no
  // multi-gigabyte allocation (the test would run out of memory or time).
  for (std::size_t at = 8; at + 4 <= good.size(); ++at) {
    for (std::uint32_t value : {0xFFFFFFFFu, 0x7FFFFFFFu, 0x40000000u}) {
      std::vector<std::uint8_t> bad = good;
      for (int k = 0; k < 4; ++k)
        bad[at + static_cast<std::size_t>(k)] = static_cast<std::uint8_t>(value >> (24 - 8 * k));
      M m;
      SafeDecode(bad, m);
    }
  }
}

TEST(SafeDecode, TheReplaysTypesRoundTripAndDamagedCountsAreRefused) {
  ExpectSafe<image_t>();
  ExpectSafe<camera_info_t>();
  ExpectSafe<tag_detections_t>();
  ExpectSafe<object_poses_t>();
  ExpectSafe<visual_events_t>();
  ExpectSafe<controller_cycle_t>();
  ExpectSafe<robot_estimate_t>();
  ExpectSafe<fault_t>();
  ExpectSafe<log_annotation_t>();
}

}  // namespace
}  // namespace visco::replay

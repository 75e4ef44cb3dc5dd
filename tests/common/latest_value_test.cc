#include "common/latest_value.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

namespace visco {
namespace {

struct Sample {
  std::uint64_t sequence;
  std::uint64_t check;  // sequence * 7 + 3: a torn read would break it
  double padding[14];
};

TEST(LatestValue, EmptyUntilPublished) {
  LatestValue<Sample> value;
  Sample out{};
  EXPECT_FALSE(value.TryTake(out));
  value.Publish(Sample{1, 10, {}});
  ASSERT_TRUE(value.TryTake(out));
  EXPECT_EQ(out.sequence, 1u);
  EXPECT_FALSE(value.TryTake(out)) << "a value is handed over once";
  EXPECT_EQ(out.sequence, 1u) << "TryTake leaves the output untouched when nothing is new";
}

TEST(LatestValue, ConsumerSeesNewest) {
  LatestValue<Sample> value;
  for (std::uint64_t i = 1; i <= 5; ++i) value.Publish(Sample{i, i * 7 + 3, {}});
  Sample out{};
  ASSERT_TRUE(value.TryTake(out));
  EXPECT_EQ(out.sequence, 5u);
  EXPECT_EQ(value.published(), 5u);
}

// Producer and consumer race; every value read must be whole (never torn) and sequences must never go back.
TEST(LatestValue, ConcurrentHandOffIsWholeAndMonotonic) {
  LatestValue<Sample> value;
  constexpr std::uint64_t kCount = 200000;
  std::atomic<bool> done{false};
  std::thread producer([&] {
    for (std::uint64_t i = 1; i <= kCount; ++i) value.Publish(Sample{i, i * 7 + 3, {}});
    done = true;
  });
  std::uint64_t last = 0;
  std::uint64_t reads = 0;
  Sample out{};
  for (;;) {
    const bool finished = done.load();
    if (value.TryTake(out)) {
      ASSERT_EQ(out.check, out.sequence * 7 + 3) << "torn read";
      ASSERT_GT(out.sequence, last) << "went backwards";
      last = out.sequence;
      ++reads;
    } else if (finished) {
      break;
    }
  }
  producer.join();
  EXPECT_EQ(last, kCount) << "the final value must be delivered";
  EXPECT_GT(reads, 0u);
}

}  // namespace
}  // namespace visco

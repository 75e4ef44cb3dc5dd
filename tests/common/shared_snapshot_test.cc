#include "common/shared_snapshot.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>
#include <vector>

namespace visco {
namespace {

struct Sample {
  std::uint64_t sequence;
  std::uint64_t check;  // sequence * 7 + 3: a torn read would break it
  double padding[14];
  std::uint8_t odd_size[5];  // not a multiple of 8 bytes
};

Sample Make(std::uint64_t i) {
  Sample s{};
  s.sequence = i;
  s.check = i * 7 + 3;
  for (double& p : s.padding) p = static_cast<double>(i);
  for (std::uint8_t& b : s.odd_size) b = static_cast<std::uint8_t>(i);
  return s;
}

bool Whole(const Sample& s) {
  if (s.check != s.sequence * 7 + 3) return false;
  for (double p : s.padding) {
    if (p != static_cast<double>(s.sequence)) return false;
  }
  for (std::uint8_t b : s.odd_size) {
    if (b != static_cast<std::uint8_t>(s.sequence)) return false;
  }
  return true;
}

TEST(SharedSnapshot, HoldsTheInitialValueUntilPublished) {
  SharedSnapshot<Sample> value(Make(0));
  EXPECT_EQ(value.Read().sequence, 0u);
  EXPECT_TRUE(Whole(value.Read()));
  value.Publish(Make(4));
  EXPECT_EQ(value.Read().sequence, 4u);
  EXPECT_EQ(value.Read().sequence, 4u) << "reading leaves the value in place";
  EXPECT_EQ(value.published(), 2u);
}

TEST(SharedSnapshot, DefaultIsAValueInitialisedT) {
  SharedSnapshot<Sample> value;
  const Sample s = value.Read();
  EXPECT_EQ(s.sequence, 0u);
  EXPECT_EQ(s.check, 0u);
}

// One writer and three readers race; every value read must be whole (never torn) and, per reader, never older than
// the one it read before. Under ThreadSanitizer (tsan preset) this is also the proof that nothing races.
TEST(SharedSnapshot, ConcurrentReadsAreWholeAndMonotonic) {
  SharedSnapshot<Sample> value(Make(0));
  constexpr std::uint64_t kCount = 100000;
  std::atomic<bool> done{false};
  std::atomic<int> torn{0}, backwards{0};
  std::atomic<std::uint64_t> reads{0};
  std::vector<std::thread> readers;
  for (int r = 0; r < 3; ++r) {
    readers.emplace_back([&] {
      std::uint64_t last = 0;
      for (;;) {
        const bool finished = done.load();
        const Sample s = value.Read();
        if (!Whole(s)) ++torn;
        if (s.sequence < last) ++backwards;
        last = s.sequence;
        reads.fetch_add(1, std::memory_order_relaxed);
        if (finished) {
          if (s.sequence != kCount) ++backwards;  // the final value must be visible after the writer finished
          break;
        }
      }
    });
  }
  for (std::uint64_t i = 1; i <= kCount; ++i) value.Publish(Make(i));
  done = true;
  for (std::thread& t : readers) t.join();
  EXPECT_EQ(torn.load(), 0) << "torn read";
  EXPECT_EQ(backwards.load(), 0) << "went backwards, or missed the final value";
  EXPECT_GT(reads.load(), 0u);
}

}  // namespace
}  // namespace visco

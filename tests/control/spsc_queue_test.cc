// The SPSC queue: order, capacity, drops, and a two-thread run that checks every value arrives once, in order.

#include "control/spsc_queue.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <thread>

namespace visco::control {
namespace {

TEST(SpscQueue, FifoWithCapacityAndDrops) {
  SpscQueue<int, 4> q;
  EXPECT_EQ(q.capacity(), 3u);
  EXPECT_TRUE(q.TryPush(1));
  EXPECT_TRUE(q.TryPush(2));
  EXPECT_TRUE(q.TryPush(3));
  EXPECT_FALSE(q.TryPush(4));
  EXPECT_EQ(q.dropped(), 1u);
  int v = 0;
  EXPECT_TRUE(q.TryPop(v));
  EXPECT_EQ(v, 1);
  EXPECT_TRUE(q.TryPush(5));
  EXPECT_TRUE(q.TryPop(v));
  EXPECT_EQ(v, 2);
  EXPECT_TRUE(q.TryPop(v));
  EXPECT_EQ(v, 3);
  EXPECT_TRUE(q.TryPop(v));
  EXPECT_EQ(v, 5);
  EXPECT_FALSE(q.TryPop(v));
}

TEST(SpscQueue, TwoThreadsEveryValueOnceInOrder) {
  struct Item {
    std::uint64_t value;
    std::uint64_t check;
  };
  SpscQueue<Item, 64> q;
  constexpr std::uint64_t kCount = 200000;
  std::thread producer([&] {
    for (std::uint64_t i = 0; i < kCount; ++i) {
      while (!q.TryPush({i, ~i})) std::this_thread::yield();
    }
  });
  std::uint64_t expected = 0;
  Item item{};
  while (expected < kCount) {
    if (!q.TryPop(item)) {
      std::this_thread::yield();
      continue;
    }
    ASSERT_EQ(item.value, expected);
    ASSERT_EQ(item.check, ~expected);
    ++expected;
  }
  producer.join();
  EXPECT_GT(q.dropped(), 0u);  // the producer's retries after full were counted as drops
}

}  // namespace
}  // namespace visco::control

// The jitter histogram's bin edges match controller_telemetry_t: bin 0 = [0, 2) us, bin i = [2^i, 2^(i+1)) us.

#include "control/jitter_stats.h"

#include <gtest/gtest.h>

#include <cmath>

namespace visco::control {
namespace {

TEST(JitterStats, BinEdges) {
  EXPECT_EQ(JitterBin(-5), 0);
  EXPECT_EQ(JitterBin(0), 0);
  EXPECT_EQ(JitterBin(1999), 0);
  EXPECT_EQ(JitterBin(2000), 1);
  EXPECT_EQ(JitterBin(3999), 1);
  EXPECT_EQ(JitterBin(4000), 2);
  EXPECT_EQ(JitterBin(1'000'000), 9);  // 1 ms in [512, 1024) us
  EXPECT_EQ(JitterBin(32'767'000), 14);
  EXPECT_EQ(JitterBin(32'768'000), 15);
  EXPECT_EQ(JitterBin(10'000'000'000), 15);  // open-ended
  // Against the definition, for every microsecond up to 70 ms.
  for (std::int64_t us = 0; us < 70000; ++us) {
    int reference = 0;
    for (int i = 1; i < kJitterBins; ++i) {
      if (us >= (std::int64_t{1} << i)) reference = i;
    }
    ASSERT_EQ(JitterBin(us * 1000 + 999), reference) << us;
  }
}

TEST(JitterStats, Statistics) {
  JitterStats s;
  s.Record(1000);
  s.Record(5000);
  s.Record(3000);
  EXPECT_EQ(s.count, 3);
  EXPECT_EQ(s.min_ns, 1000);
  EXPECT_EQ(s.max_ns, 5000);
  EXPECT_DOUBLE_EQ(s.mean_ns(), 3000);
  EXPECT_EQ(s.histogram[0], 1);
  EXPECT_EQ(s.histogram[1], 1);
  EXPECT_EQ(s.histogram[2], 1);
  s.Reset();
  EXPECT_EQ(s.count, 0);
}

}  // namespace
}  // namespace visco::control

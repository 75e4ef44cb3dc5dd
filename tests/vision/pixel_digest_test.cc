// PixelDigest (the pixels' digest in tag_detections_t.pixel_digest) against a plain FNV-1a over the bytes it is
// documented to cover, strides with padding, and any one changed pixel changing it.

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "vision/image.h"

namespace visco::vision {
namespace {

// FNV-1a 64 of a byte string, the obvious way.
std::uint64_t Fnv1a(const std::vector<std::uint8_t>& bytes) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (std::uint8_t b : bytes) h = (h ^ b) * 0x100000001b3ull;
  return h;
}

TEST(PixelDigest, IsFnv1aOfSizeAndRowsAndSeesEveryPixel) {
  EXPECT_EQ(Fnv1a({}), 0xcbf29ce484222325ull);
  EXPECT_EQ(Fnv1a({'a'}), 0xaf63dc4c8601ec8cull);  // the published FNV-1a 64 test vector of "a"
  std::mt19937 rng(4042);
  const int width = 37, height = 11, stride = 40;
  std::vector<std::uint8_t> padded(static_cast<std::size_t>(stride) * height);
  for (auto& b : padded) b = static_cast<std::uint8_t>(rng());
  std::vector<std::uint8_t> bytes = {37, 0, 0, 0, 11, 0, 0, 0};
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) bytes.push_back(padded[static_cast<std::size_t>(v) * stride + u]);
  }
  const GrayImageView view{padded.data(), width, height, stride};
  const std::uint64_t digest = PixelDigest(view);
  EXPECT_EQ(digest, Fnv1a(bytes));
  // The padding is not part of it; every pixel is, by any change of its value.
  padded[static_cast<std::size_t>(stride) - 1] ^= 0xff;
  EXPECT_EQ(PixelDigest(view), digest);
  for (int i = 0; i < 200; ++i) {
    const std::size_t at = static_cast<std::size_t>(rng() % height) * stride + rng() % width;
    const auto flip = static_cast<std::uint8_t>(1 + rng() % 255);
    padded[at] ^= flip;
    EXPECT_NE(PixelDigest(view), digest);
    padded[at] ^= flip;
  }
  // The same bytes in another shape are another image.
  EXPECT_NE(PixelDigest({padded.data(), height, width, height}), PixelDigest({padded.data(), width, height, width}));
}

}  // namespace
}  // namespace visco::vision

// PackGrayPng (image_t's lossless PNG, `visco capture --png`, `visco sim --png`): what vision decodes from the
// message is the picture, pixel for pixel (same PixelDigest, which replay compares), for a rendered noisy frame and
// random bytes, with strides; the stream is PNG and, for a camera picture, smaller than the raw pixels.

#include "vision/image_png.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "common/error.h"
#include "tests/vision/sliding_robot_world.h"
#include "vision/pipeline.h"

namespace visco::vision {
namespace {

GrayImage Decoded(const visco::image_t& m) {
  Frame frame;
  std::string error;
  EXPECT_TRUE(DecodeImageMessage(m, frame, error)) << error;
  return frame.image;
}

TEST(ImagePng, RenderedFrameRoundTripsPixelForPixelAndIsSmaller) {
  const GrayImage picture = test_world::SlidingRobotWorld().Render(3);
  for (const int level : {0, 1, 6, 9}) {
    visco::image_t m{};
    m.seq = 7;
    PackGrayPng(picture.view(), level, m);
    EXPECT_EQ(m.pixel_format, visco::image_t::PIXEL_FORMAT_PNG);
    EXPECT_EQ(m.size, static_cast<std::int32_t>(m.data.size()));
    EXPECT_EQ(m.seq, 7);
    ASSERT_GE(m.data.size(), 8u);
    const std::vector<std::uint8_t> signature = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    EXPECT_TRUE(std::equal(signature.begin(), signature.end(), m.data.begin()));
    const GrayImage back = Decoded(m);
    EXPECT_TRUE(back.pixels == picture.pixels) << "level " << level;
    EXPECT_EQ(PixelDigest(back.view()), PixelDigest(picture.view()));
    if (level > 0) {
      EXPECT_LT(m.data.size(), picture.pixels.size()) << "level " << level;
    }
  }
}

TEST(ImagePng, RandomPixelsWithAStrideRoundTrip) {
  std::mt19937 rng(40);
  const int width = 97, height = 31, stride = 101;
  std::vector<std::uint8_t> padded(static_cast<std::size_t>(stride) * height);
  for (auto& b : padded) b = static_cast<std::uint8_t>(rng());
  visco::image_t m{};
  PackGrayPng({padded.data(), width, height, stride}, 3, m);
  EXPECT_EQ(m.width, width);
  EXPECT_EQ(m.height, height);
  EXPECT_EQ(m.row_stride, width);
  const GrayImage back = Decoded(m);
  ASSERT_EQ(back.width, width);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) ASSERT_EQ(back.at(u, v), padded[static_cast<std::size_t>(v) * stride + u]);
  }
}

TEST(ImagePng, LevelOutsideZlibsIsRefused) {
  const GrayImage picture(8, 8, 1);
  visco::image_t m{};
  EXPECT_THROW(PackGrayPng(picture.view(), 10, m), InputError);
  EXPECT_THROW(PackGrayPng(picture.view(), -1, m), InputError);
}

}  // namespace
}  // namespace visco::vision

#include "vision/image_png.h"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "common/error.h"

namespace visco::vision {

void PackGrayPng(const GrayImageView& image, int level, visco::image_t& message) {
  if (level < kPngLevelMin || level > kPngLevelMax) {
    throw InputError("command line", "--png-level", "must be 0..9 (zlib), not " + std::to_string(level));
  }
  const cv::Mat m(image.height, image.width, CV_8UC1, const_cast<std::uint8_t*>(image.data),
                  static_cast<std::size_t>(image.stride));
  bool ok = false;
  try {
    ok = cv::imencode(".png", m, message.data, {cv::IMWRITE_PNG_COMPRESSION, level});
  } catch (const cv::Exception& e) {
    throw JobFailed(std::string("PNG encoding failed: ") + e.what());
  }
  if (!ok) throw JobFailed("PNG encoding failed");
  message.width = image.width;
  message.height = image.height;
  message.row_stride = image.width;
  message.pixel_format = visco::image_t::PIXEL_FORMAT_PNG;
  message.size = static_cast<std::int32_t>(message.data.size());
}

}  // namespace visco::vision

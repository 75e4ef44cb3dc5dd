#include "vision/image.h"

#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/error.h"

namespace visco::vision {

GrayImage ReadGrayImage(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw InputError(path, "", "image file does not exist");
  cv::Mat m;
  try {
    m = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    throw InputError(path, "", std::string("cannot decode image: ") + e.err);
  }
  if (m.empty()) throw InputError(path, "", "cannot decode image (corrupt or unsupported format)");
  if (m.depth() != CV_8U) {
    cv::Mat tmp;
    m.convertTo(tmp, CV_8U, m.depth() == CV_16U ? 1.0 / 257 : 1.0);
    m = tmp;
  }
  if (m.channels() == 3) {
    cv::cvtColor(m, m, cv::COLOR_BGR2GRAY);
  } else if (m.channels() == 4) {
    cv::cvtColor(m, m, cv::COLOR_BGRA2GRAY);
  }
  GrayImage out(m.cols, m.rows);
  for (int v = 0; v < m.rows; ++v) std::copy_n(m.ptr<std::uint8_t>(v), m.cols, &out.pixels[std::size_t(v) * m.cols]);
  return out;
}

std::uint64_t PixelDigest(const GrayImageView& image) {
  std::uint64_t h = 14695981039346656037ull;
  auto add = [&h](std::uint8_t byte) {
    h ^= byte;
    h *= 1099511628211ull;
  };
  for (const int n : {image.width, image.height}) {
    const auto u = static_cast<std::uint32_t>(n);
    for (int k = 0; k < 4; ++k) add(static_cast<std::uint8_t>(u >> (8 * k)));
  }
  for (int v = 0; v < image.height; ++v) {
    const std::uint8_t* row = image.data + static_cast<std::size_t>(v) * static_cast<std::size_t>(image.stride);
    for (int u = 0; u < image.width; ++u) add(row[u]);
  }
  return h;
}

void WriteGrayImage(const GrayImageView& image, const std::string& path) {
  const cv::Mat m(image.height, image.width, CV_8UC1, const_cast<std::uint8_t*>(image.data),
                  static_cast<std::size_t>(image.stride));
  bool ok = false;
  try {
    ok = cv::imwrite(path, m);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok) throw JobFailed("cannot write image " + path);
}

}  // namespace visco::vision

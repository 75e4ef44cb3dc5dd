#pragma once
// Lossless compression of the frames a camera process publishes: image_t's PIXEL_FORMAT_PNG, which vision decodes
// as it decodes raw grey (vision/pipeline.h), pixel for pixel. It makes logs of the camera channel smaller at a
// CPU cost per frame (docs/camera.md, "Logging compressed images").

#include <cstdint>

#include "visco/image_t.hpp"
#include "vision/image.h"

namespace visco::vision {

/// The zlib levels PackGrayPng accepts: 0 (stored) to 9 (smallest, slowest).
inline constexpr int kPngLevelMin = 0, kPngLevelMax = 9;

/// Fills `message.data` with `image` as a grey PNG stream at zlib `level`, and sets pixel_format (PIXEL_FORMAT_PNG),
/// width, height, row_stride (= width, the decoded picture's) and size; utime, seq and camera are left as they are.
/// Not real-time safe: libpng allocates per call. @throws InputError for a level outside 0..9 and JobFailed if
/// the encoder fails.
void PackGrayPng(const GrayImageView& image, int level, visco::image_t& message);

}  // namespace visco::vision

#pragma once
// Small pieces both V4L2 ends share (the capture source, v4l2_camera.cc, and the output writer, v4l2_output.cc).
// Internal to vision: no V4L2 header here.

#include <cstdint>
#include <string>

namespace visco::vision::internal {

// ioctl, retried when a signal interrupts it.
int Xioctl(int fd, unsigned long request, void* arg);

// A pixel format's fourcc as text ("GREY", "YUYV"), trailing blanks dropped.
std::string FourccText(std::uint32_t fourcc);

}  // namespace visco::vision::internal

#pragma once
// What a closed-loop run's LCM log (lcm-logger's format) says happened: the trajectory as vision saw it, where visual
// events reported a crossing, where contact started, and how long the robot was commanded to move.

#include <Eigen/Core>
#include <cmath>
#include <filesystem>
#include <vector>

namespace visco::app::demo {

struct Trace {
  std::vector<Eigen::Vector2d> path;       // vision's robot estimates, a point every 1 cm
  std::vector<Eigen::Vector2d> crossings;  // where a visual event reported a crossing
  std::vector<Eigen::Vector2d> contacts;   // where contact started
  int events = 0;
  int messages = 0;
  double motion_s = NAN;  // first to last non-zero velocity command (the log's receive times)
};

/// The trace of the log at `log`; an empty trace when the log cannot be opened.
Trace ReadTrace(const std::filesystem::path& log);

}  // namespace visco::app::demo

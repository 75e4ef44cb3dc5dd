#include "app/demo/trace.h"

#include <cstdint>
#include <lcm/lcm-cpp.hpp>

#include "lcmtypes/channels.h"
#include "visco/robot_estimate_t.hpp"
#include "visco/robot_status_t.hpp"
#include "visco/velocity_command_t.hpp"
#include "visco/visual_events_t.hpp"

namespace visco::app::demo {
namespace {

namespace fs = std::filesystem;

// LCM's generated decoders store doubles through integer pointers; with a value-initialised message ({}) GCC at -O2
// may keep the zeros it knows of (measured: every position read back as 0). Decode into a default-initialised one:
// the decoder writes every field.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
template <typename Message>
bool Decode(const lcm::LogEvent& e, Message* out) {
  return out->decode(e.data, 0, e.datalen) >= 0;
}

}  // namespace

Trace ReadTrace(const fs::path& log) {
  Trace t;
  lcm::LogFile file(log.string(), "r");
  if (!file.good()) return t;
  bool in_contact = false;
  Eigen::Vector2d last(NAN, NAN);
  std::int64_t first_move = -1, last_move = -1;
  while (const lcm::LogEvent* e = file.readNextEvent()) {
    ++t.messages;
    if (e->channel == channels::kCommand) {
      velocity_command_t c;
      if (!Decode(*e, &c) || (c.velocity[0] == 0 && c.velocity[1] == 0)) continue;
      if (first_move < 0) first_move = e->timestamp;
      last_move = e->timestamp;
    } else if (e->channel == channels::kRobotEstimate) {
      // The trajectory as vision saw it (the driver's status carries odometry, zero in the simulation).
      robot_estimate_t s;
      if (!Decode(*e, &s) || !s.valid) continue;
      const Eigen::Vector2d p(s.position[0], s.position[1]);
      if (t.path.empty() || (p - t.path.back()).norm() > 0.01) t.path.push_back(p);
      last = p;
    } else if (e->channel == channels::kStatus) {
      robot_status_t s;
      if (!Decode(*e, &s)) continue;
      if (s.contact && !in_contact && std::isfinite(last.x())) t.contacts.push_back(last);
      in_contact = s.contact;
    } else if (e->channel == channels::kVisualEvents) {
      visual_events_t v;
      if (!Decode(*e, &v)) continue;
      for (const auto& ev : v.events) {
        if (ev.crossed && std::isfinite(last.x())) {
          ++t.events;
          t.crossings.push_back(last);
        }
      }
    }
  }
  if (first_move >= 0) t.motion_s = static_cast<double>(last_move - first_move) * 1e-6;
  return t;
}
#pragma GCC diagnostic pop

}  // namespace visco::app::demo

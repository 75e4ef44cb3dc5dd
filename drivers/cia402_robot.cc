#include "drivers/cia402_robot.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "common/error.h"
#include "drivers/robot_link.h"
#include "drivers/socketcan.h"

namespace visco::drivers {
namespace {

using Json = nlohmann::json;
using namespace cia402;

std::string Hex(std::uint32_t value, int digits) {
  char text[16];
  std::snprintf(text, sizeof(text), "0x%0*X", digits, value);
  return text;
}

std::string Object(std::uint16_t index, std::uint8_t sub) { return Hex(index, 4) + ":" + Hex(sub, 2).substr(2); }

}  // namespace

Cia402Config ParseCia402Config(const std::string& text, const std::string& source) {
  const Json j = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  auto fail = [&](const std::string& object, const std::string& what) { throw InputError(source, object, what); };
  if (j.is_discarded()) fail("", "not valid JSON");
  if (!j.is_object()) fail("", "must be a JSON object");
  const std::set<std::string> keys = {"format",
                                      "interface",
                                      "mode",
                                      "master_node",
                                      "sync_period_ms",
                                      "heartbeat_ms",
                                      "heartbeat_timeout_ms",
                                      "boot_timeout_ms",
                                      "sdo_timeout_ms",
                                      "state_timeout_ms",
                                      "quick_stop_option",
                                      "workspace",
                                      "axes"};
  for (const auto& item : j.items()) {
    if (keys.count(item.key()) == 0) {
      fail(item.key(),
           "unknown key (format, interface, mode, master_node, sync_period_ms, heartbeat_ms, "
           "heartbeat_timeout_ms, boot_timeout_ms, sdo_timeout_ms, state_timeout_ms, quick_stop_option, "
           "workspace, axes)");
    }
  }
  if (!j.contains("format") || j["format"] != "visco-cia402-1") fail("format", "must be \"visco-cia402-1\"");
  Cia402Config c;
  c.source = source;
  auto number = [&](const Json& o, const std::string& key, const std::string& object, double& out, double min,
                    double max) {
    if (!o.contains(key)) return false;
    if (!o[key].is_number() || !std::isfinite(o[key].get<double>())) fail(object, "must be a number");
    const double v = o[key].get<double>();
    if (!(v >= min && v <= max)) {
      std::ostringstream what;
      what << "must be in [" << min << ", " << max << "], not " << v;
      fail(object, what.str());
    }
    out = v;
    return true;
  };
  auto integer = [&](const Json& o, const std::string& key, const std::string& object, int& out, int min, int max) {
    double v = out;
    if (!number(o, key, object, v, min, max)) return false;
    if (v != std::floor(v)) fail(object, "must be an integer");
    out = static_cast<int>(v);
    return true;
  };
  if (!j.contains("interface") || !j["interface"].is_string() || j["interface"].get<std::string>().empty()) {
    fail("interface", "the drives' CAN interface, e.g. \"can1\" (missing or not a string)");
  }
  c.interface = j["interface"].get<std::string>();
  if (j.contains("mode")) {
    if (j["mode"] == "profile_velocity" || j["mode"] == 3) {
      c.mode = kModeProfileVelocity;
    } else if (j["mode"] == "cyclic_synchronous_velocity" || j["mode"] == 9) {
      c.mode = kModeCyclicSynchronousVelocity;
    } else {
      fail("mode", "must be \"profile_velocity\" (3) or \"cyclic_synchronous_velocity\" (9)");
    }
  }
  integer(j, "master_node", "master_node", c.master_node, 1, 127);
  number(j, "sync_period_ms", "sync_period_ms", c.sync_period_ms, 1, 1000);
  int ms = static_cast<int>(c.heartbeat_ms);
  integer(j, "heartbeat_ms", "heartbeat_ms", ms, 10, 10000);
  c.heartbeat_ms = ms;
  ms = static_cast<int>(c.heartbeat_timeout_ms);
  integer(j, "heartbeat_timeout_ms", "heartbeat_timeout_ms", ms, 20, 65535);
  c.heartbeat_timeout_ms = ms;
  if (c.heartbeat_timeout_ms < 2 * c.heartbeat_ms) {
    fail("heartbeat_timeout_ms", "must be at least twice heartbeat_ms (one lost heartbeat is no loss of the drive)");
  }
  number(j, "boot_timeout_ms", "boot_timeout_ms", c.boot_timeout_ms, 1, 600000);
  number(j, "sdo_timeout_ms", "sdo_timeout_ms", c.sdo_timeout_ms, 1, 60000);
  number(j, "state_timeout_ms", "state_timeout_ms", c.state_timeout_ms, 1, 60000);
  int option = c.quick_stop_option;
  integer(j, "quick_stop_option", "quick_stop_option", option, 0, 8);
  c.quick_stop_option = static_cast<std::uint16_t>(option);
  if (j.contains("workspace")) {
    const Json& w = j["workspace"];
    if (!w.is_array() || w.size() != 4) fail("workspace", "must be [xmin, ymin, xmax, ymax]");
    for (int i = 0; i < 4; ++i) {
      if (!w[i].is_number()) fail("workspace", "must be [xmin, ymin, xmax, ymax] (numbers)");
      c.workspace[i] = w[i].get<double>();
    }
    if (!(c.workspace[0] < c.workspace[2] && c.workspace[1] < c.workspace[3])) {
      fail("workspace", "min must be below max on both axes");
    }
    c.have_workspace = true;
  }
  if (!j.contains("axes") || !j["axes"].is_array() || j["axes"].size() != 2) {
    fail("axes", "must be two drives, [x axis, y axis], each {\"node\": N, \"counts_per_metre\": C, ...}");
  }
  std::set<int> nodes;
  for (int i = 0; i < 2; ++i) {
    const std::string object = "axes[" + std::to_string(i) + "]";
    const Json& a = j["axes"][i];
    if (!a.is_object()) fail(object, "must be an object");
    for (const auto& item : a.items()) {
      if (item.key() != "node" && item.key() != "counts_per_metre" && item.key() != "velocity_units_per_mps" &&
          item.key() != "acceleration" && item.key() != "quick_stop_deceleration") {
        fail(object + "." + item.key(),
             "unknown key (node, counts_per_metre, velocity_units_per_mps, acceleration, quick_stop_deceleration)");
      }
    }
    Cia402Axis& axis = c.axes[i];
    if (!integer(a, "node", object + ".node", axis.node, 1, 127)) fail(object + ".node", "missing (1..127)");
    if (!nodes.insert(axis.node).second) fail(object + ".node", "node " + std::to_string(axis.node) + " twice");
    if (axis.node == c.master_node) {
      fail(object + ".node", "node " + std::to_string(axis.node) + " is the master's own (master_node)");
    }
    const double big = 1e12;
    if (!number(a, "counts_per_metre", object + ".counts_per_metre", axis.counts_per_metre, -big, big) ||
        axis.counts_per_metre == 0.0) {
      fail(object + ".counts_per_metre", "missing or zero (position counts per metre; negative reverses the axis)");
    }
    axis.velocity_units_per_mps = axis.counts_per_metre;
    number(a, "velocity_units_per_mps", object + ".velocity_units_per_mps", axis.velocity_units_per_mps, -big, big);
    if (axis.velocity_units_per_mps == 0.0) fail(object + ".velocity_units_per_mps", "must not be zero");
    number(a, "acceleration", object + ".acceleration", axis.acceleration, 1e-6, 1e6);
    number(a, "quick_stop_deceleration", object + ".quick_stop_deceleration", axis.quick_stop_deceleration, 1e-6, 1e6);
  }
  return c;
}

Cia402Config LoadCia402Config(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "", "cannot open the CiA 402 configuration");
  std::stringstream text;
  text << in.rdbuf();
  return ParseCia402Config(text.str(), path);
}

Cia402Robot::Cia402Robot(const Cia402Config& config, const Cia402DriverContext& context)
    : config_(config), context_(context) {
  for (int i = 0; i < 2; ++i) drives_[i].node = config.axes[i].node;
  if (config.interface == context.driver_interface) {
    // One bus for the controller and the drives: the driver's own node is taken; the driver's heartbeat may be the
    // master's.
    for (int i = 0; i < 2; ++i) {
      if (config.axes[i].node == context.driver_node) {
        throw InputError(config.source, "axes[" + std::to_string(i) + "].node",
                         "node " + std::to_string(context.driver_node) + " is the driver's own on " + config.interface +
                             " (--node)");
      }
    }
    produce_heartbeat_ = config.master_node != context.driver_node;
  }
}

Cia402Robot::~Cia402Robot() { Deactivate(); }

void Cia402Robot::Refuse(int axis, const std::string& what) {
  throw JobFailed("CiA 402: node " + std::to_string(drives_[axis].node) + " on " + config_.interface + ": " + what);
}

void Cia402Robot::Write(const can::Frame& frame) {
  if (!socket_) return;
  const CanIo io = socket_->Write(frame);
  if (io == CanIo::kNetDown) {
    interface_down_ = true;
  } else if (io == CanIo::kOk) {
    interface_down_ = false;
  }
}

void Cia402Robot::Fault(bool bus, std::uint16_t code, const char* format, ...) {
  want_ = Want::kQuickStop;  // every axis stops, whichever failed
  command_[0] = command_[1] = 0.0;
  if (feedback_.fault) return;  // the first cause is the one reported
  feedback_.fault = true;
  feedback_.fault_bus = bus;
  feedback_.fault_code = code;
  va_list args;
  va_start(args, format);
  std::vsnprintf(feedback_.fault_message, sizeof(feedback_.fault_message), format, args);
  va_end(args);
}

void Cia402Robot::Dispatch(const can::Frame& frame, std::int64_t now_us) {
  if ((frame.id & can::kErrFlag) != 0) {
    if ((frame.id & can::kErrBusOff) != 0 && configured_) {
      Fault(true, can::kEmcyBusOff, "CAN bus-off on %s (the drives' bus): every axis quick-stopped",
            config_.interface.c_str());
    }
    return;
  }
  for (Drive& d : drives_) {
    const std::uint32_t n = static_cast<std::uint32_t>(d.node);
    if (frame.id == kHeartbeat + n && frame.dlc >= 1) {
      const std::uint8_t state = frame.data[0] & 0x7F;
      if (state == kStateBootUp) {
        d.booted = true;
        if (configured_ && want_ != Want::kDisabled) {
          Fault(true, 0x8130, "node %d rebooted (boot-up message): restart the driver to configure it again", d.node);
        }
      }
      d.nmt = state;
      d.last_heartbeat_us = now_us;
    } else if (std::uint16_t sw = 0; DecodeTpdo1(d.node, frame, sw, d.velocity)) {
      d.statusword = sw;
      d.state = StateOf(sw);
      d.have_tpdo1 = true;
    } else if (DecodeTpdo2(d.node, frame, d.position)) {
      d.have_tpdo2 = true;
    } else if (Emcy emcy; DecodeEmcy(d.node, frame, emcy)) {
      if (emcy.code == 0) continue;  // "error reset": a fault of the drive cleared
      d.emcy = emcy.code;
      if (configured_ && want_ != Want::kDisabled) {
        Fault(false, emcy.code, "node %d EMCY 0x%04X: %s (error register 0x%02X)", d.node, emcy.code,
              EmcyText(emcy.code), emcy.error_register);
      }
    } else if (SdoReply reply; sdo_pending_ && d.node == sdo_node_ && DecodeSdoReply(d.node, frame, reply)) {
      sdo_reply_ = reply;
      sdo_replied_ = true;
    }
  }
}

void Cia402Robot::Cycle(std::int64_t now_us) {
  for (int i = 0; i < 2; ++i) {
    Drive& d = drives_[i];
    d.controlword = ControlwordToward(d.state, want_, d.controlword);
    double target = 0.0;
    if (want_ == Want::kEnabled && d.state == DriveState::kOperationEnabled) {
      target = std::round(command_[i] * config_.axes[i].velocity_units_per_mps);
    }
    constexpr double kMax = std::numeric_limits<std::int32_t>::max();
    d.target = static_cast<std::int32_t>(std::fmax(-kMax, std::fmin(kMax, target)));
    Write(Rpdo1(d.node, d.controlword, d.target));
  }
  Write(Sync());
  if (produce_heartbeat_ && now_us >= next_heartbeat_us_) {
    Write(Heartbeat(config_.master_node, kStateOperational));
    next_heartbeat_us_ = now_us + static_cast<std::int64_t>(config_.heartbeat_ms * 1000.0);
  }
}

void Cia402Robot::Watch(std::int64_t now_us) {
  if (interface_down_) {
    Fault(true, 0x8100, "CAN interface %s (the drives' bus) is down: the drives quick-stop on the lost heartbeat",
          config_.interface.c_str());
  }
  const auto timeout_us = static_cast<std::int64_t>(config_.heartbeat_timeout_ms * 1000.0);
  const auto state_timeout_us = static_cast<std::int64_t>(config_.state_timeout_ms * 1000.0);
  const bool resetting = reset_us_ >= 0 && now_us - reset_us_ < state_timeout_us;
  for (Drive& d : drives_) {
    if (now_us - d.last_heartbeat_us > timeout_us) {
      Fault(true, 0x8130, "node %d: heartbeat lost (none for %.0f ms, consumer time %.0f ms): every axis stopped",
            d.node, (now_us - d.last_heartbeat_us) / 1e3, config_.heartbeat_timeout_ms);
    } else if (d.nmt != kStateOperational) {
      Fault(true, 0x8130, "node %d is %s, not operational: every axis stopped", d.node, NmtStateName(d.nmt));
    }
    if ((d.state == DriveState::kFault || d.state == DriveState::kFaultReactionActive) && !resetting) {
      Fault(false, d.emcy != 0 ? d.emcy : 0x1000, "node %d in %s (statusword 0x%04X%s%s)", d.node, ToString(d.state),
            d.statusword, d.emcy != 0 ? ", last EMCY: " : "", d.emcy != 0 ? EmcyText(d.emcy) : "");
    }
    if (want_ == Want::kEnabled) {
      if (d.state == DriveState::kOperationEnabled) {
        d.enabled_seen = true;
      } else if (d.enabled_seen) {
        Fault(false, 0x1000, "node %d left OPERATION ENABLED by itself (now %s, statusword 0x%04X)", d.node,
              ToString(d.state), d.statusword);
      } else if (!resetting) {
        Fault(false, 0x1000, "node %d did not reach OPERATION ENABLED within %.0f ms of the reset (in %s)", d.node,
              config_.state_timeout_ms, ToString(d.state));
      }
    }
  }
}

void Cia402Robot::SetVelocity(const double velocity[2]) {
  for (int i = 0; i < 2; ++i) command_[i] = std::isfinite(velocity[i]) ? velocity[i] : 0.0;
}

void Cia402Robot::QuickStop() {
  command_[0] = command_[1] = 0.0;
  if (want_ != Want::kDisabled) want_ = Want::kQuickStop;
}

void Cia402Robot::Reset() {
  command_[0] = command_[1] = 0.0;
  if (!configured_) return;
  feedback_.fault = false;
  feedback_.fault_bus = false;
  feedback_.fault_code = 0;
  feedback_.fault_message[0] = '\0';
  want_ = Want::kEnabled;
  reset_us_ = MonotonicMicros();
  for (Drive& d : drives_) {
    d.enabled_seen = false;
    d.emcy = 0;
  }
}

void Cia402Robot::Step(double /*dt*/) {
  if (!socket_) return;
  const std::int64_t now = MonotonicMicros();
  ReceivedFrame received;
  for (int i = 0; i < 64; ++i) {  // bounded: two drives send a few frames per SYNC period
    const CanIo io = socket_->Read(received);
    if (io == CanIo::kNetDown) interface_down_ = true;
    if (io != CanIo::kOk) break;
    Dispatch(received.frame, now);
  }
  if (!configured_) return;
  if (now >= next_sync_us_) {
    Cycle(now);
    next_sync_us_ += static_cast<std::int64_t>(config_.sync_period_ms * 1000.0);
    if (next_sync_us_ <= now) next_sync_us_ = now + static_cast<std::int64_t>(config_.sync_period_ms * 1000.0);
  }
  if (want_ != Want::kDisabled) Watch(now);
  UpdateFeedback();
}

void Cia402Robot::UpdateFeedback() {
  for (int i = 0; i < 2; ++i) {
    feedback_.position[i] = drives_[i].position / config_.axes[i].counts_per_metre;
    feedback_.velocity[i] = drives_[i].velocity / config_.axes[i].velocity_units_per_mps;
  }
  if (config_.have_workspace) {
    const double* w = config_.workspace;
    feedback_.out_of_bounds = feedback_.position[0] < w[0] || feedback_.position[1] < w[1] ||
                              feedback_.position[0] > w[2] || feedback_.position[1] > w[3];
  }
}

// ---- configuration: outside the loop, waiting for the drives' answers ----

void Cia402Robot::Pump(std::int64_t until_us) {
  std::int64_t now = MonotonicMicros();
  if (until_us > now && socket_->WaitReadable(until_us - now)) {
    ReceivedFrame received;
    while (socket_->Read(received) == CanIo::kOk) Dispatch(received.frame, MonotonicMicros());
  }
}

template <typename Done>
void Cia402Robot::Await(double timeout_ms, Done done, bool cyclic) {
  const std::int64_t deadline = MonotonicMicros() + static_cast<std::int64_t>(timeout_ms * 1000.0);
  while (!done()) {
    const std::int64_t now = MonotonicMicros();
    if (now >= deadline) return;
    if (cyclic && now >= next_sync_us_) {
      Cycle(now);
      next_sync_us_ = now + static_cast<std::int64_t>(config_.sync_period_ms * 1000.0);
    }
    Pump(cyclic ? std::min(deadline, next_sync_us_) : deadline);
  }
}

bool Cia402Robot::Sdo(int axis, const can::Frame& request, SdoReply& reply, const char* what) {
  const std::uint16_t index = static_cast<std::uint16_t>(request.data[1] | request.data[2] << 8);
  const std::uint8_t sub = request.data[3];
  sdo_pending_ = true;
  sdo_replied_ = false;
  sdo_node_ = drives_[axis].node;
  Write(request);
  if (interface_down_) Refuse(axis, "the interface is down");
  Await(
      config_.sdo_timeout_ms, [&] { return sdo_replied_; }, configured_);
  sdo_pending_ = false;
  const std::string object = Object(index, sub) + " (" + what + ")";
  if (!sdo_replied_) {
    Refuse(axis,
           "no SDO answer for " + object + " within " + std::to_string(std::lround(config_.sdo_timeout_ms)) + " ms");
  }
  reply = sdo_reply_;
  if (reply.kind == SdoReplyKind::kAborted) {
    if (reply.value == 0x06020000 || reply.value == 0x06090011) return false;  // absent: the caller decides
    Refuse(axis, std::string("SDO ") + (request.data[0] == 0x40 ? "read" : "write") + " of " + object +
                     " aborted with code " + Hex(reply.value, 8) + ": " + SdoAbortText(reply.value));
  }
  if (reply.index != index || reply.sub != sub) {
    Refuse(axis, "SDO answer for " + Object(reply.index, reply.sub) + " to a request for " + object);
  }
  if (reply.kind == SdoReplyKind::kUnsupported) Refuse(axis, "SDO answer for " + object + " is not expedited");
  return true;
}

std::uint32_t Cia402Robot::SdoRead(int axis, std::uint16_t index, std::uint8_t sub, const char* what) {
  SdoReply reply;
  if (!Sdo(axis, SdoUpload(drives_[axis].node, index, sub), reply, what)) {
    Refuse(axis, "SDO read of " + Object(index, sub) + " (" + what + ") aborted with code " + Hex(reply.value, 8) +
                     ": " + SdoAbortText(reply.value));
  }
  if (reply.kind != SdoReplyKind::kUploaded) Refuse(axis, "a download answer to the read of " + Object(index, sub));
  return reply.value;
}

bool Cia402Robot::SdoReadOptional(int axis, std::uint16_t index, std::uint8_t sub, std::uint32_t& value,
                                  const char* what) {
  SdoReply reply;
  if (!Sdo(axis, SdoUpload(drives_[axis].node, index, sub), reply, what)) return false;
  value = reply.value;
  return reply.kind == SdoReplyKind::kUploaded;
}

void Cia402Robot::SdoWrite(int axis, std::uint16_t index, std::uint8_t sub, std::uint32_t value, int size,
                           const char* what) {
  SdoReply reply;
  if (!Sdo(axis, SdoDownload(drives_[axis].node, index, sub, value, size), reply, what)) {
    Refuse(axis, "SDO write of " + Object(index, sub) + " (" + what + ") = " + std::to_string(value) +
                     " aborted with code " + Hex(reply.value, 8) + ": " + SdoAbortText(reply.value));
  }
  if (reply.kind != SdoReplyKind::kDownloaded) Refuse(axis, "an upload answer to the write of " + Object(index, sub));
}

void Cia402Robot::Configure() {
  CanSocketOptions options;
  options.interface = config_.interface;
  options.error_mask = DefaultErrorMask();
  for (const Drive& d : drives_) {
    for (std::uint32_t base : {kEmcy, kTpdo1, kTpdo2, kSdoServerToClient, kHeartbeat}) {
      options.filters.push_back({base + static_cast<std::uint32_t>(d.node), 0x7FF});
    }
  }
  socket_ = std::make_unique<CanSocket>(options);

  // Boot-up: each drive's communication reset (never a broadcast: the bus may carry other devices), its boot-up
  // message awaited. A drive powered later boots up by itself within the time-out.
  for (Drive& d : drives_) {
    d.booted = false;
    Write(Nmt(kNmtResetCommunication, d.node));
  }
  Await(
      config_.boot_timeout_ms, [&] { return drives_[0].booted && drives_[1].booted; }, false);
  for (int i = 0; i < 2; ++i) {
    if (!drives_[i].booted) {
      Refuse(i, "no boot-up message (" + Hex(kHeartbeat + drives_[i].node, 3) + ") within " +
                    std::to_string(std::lround(config_.boot_timeout_ms)) +
                    " ms of its NMT reset communication: is it powered, on this bus, with this node id and bit rate?");
    }
  }

  for (int i = 0; i < 2; ++i) {
    const Cia402Axis& axis = config_.axes[i];
    const int node = axis.node;
    const std::uint32_t device = SdoRead(i, kDeviceType, 0, "device type");
    if ((device & 0xFFFF) != kDeviceProfile402) {
      Refuse(i, Object(kDeviceType, 0) + " (device type) = " + Hex(device, 8) + ": device profile " +
                    std::to_string(device & 0xFFFF) + ", not a CiA 402 drive (402)");
    }
    std::uint32_t modes = 0;
    if (SdoReadOptional(i, kSupportedDriveModes, 0, modes, "supported drive modes") &&
        (modes & (1U << (config_.mode - 1))) == 0) {
      Refuse(i, Object(kSupportedDriveModes, 0) + " (supported drive modes) = " + Hex(modes, 8) + ": no mode " +
                    std::to_string(config_.mode));
    }
    SdoWrite(i, kModesOfOperation, 0, static_cast<std::uint8_t>(config_.mode), 1, "modes of operation");
    SdoWrite(i, kQuickStopOptionCode, 0, config_.quick_stop_option, 2, "quick stop option code");
    SdoWrite(i, kProducerHeartbeatTime, 0, static_cast<std::uint32_t>(config_.heartbeat_ms), 2,
             "producer heartbeat time");
    const int master = produce_heartbeat_ ? config_.master_node : context_.driver_node;
    SdoWrite(i, kConsumerHeartbeatTime, 1,
             static_cast<std::uint32_t>(master) << 16 | static_cast<std::uint32_t>(config_.heartbeat_timeout_ms), 4,
             "consumer heartbeat time of the master");
    // PDO mapping (CiA 301 7.4.7.1): disable, clear, map, count, transmission type, enable.
    struct Pdo {
      std::uint16_t communication, mapping;
      std::uint32_t cob;
      std::uint8_t type;
      std::uint32_t entries[2];
      std::uint8_t count;
    };
    const std::uint8_t rpdo_type = config_.mode == kModeCyclicSynchronousVelocity ? 1 : 255;
    const Pdo pdos[] = {
        {kRpdo1Communication,
         kRpdo1Mapping,
         kRpdo1 + node,
         rpdo_type,
         {MappingEntry(kControlword, 0, 16), MappingEntry(kTargetVelocity, 0, 32)},
         2},
        {kTpdo1Communication,
         kTpdo1Mapping,
         kTpdo1 + node,
         1,
         {MappingEntry(kStatusword, 0, 16), MappingEntry(kVelocityActualValue, 0, 32)},
         2},
        {kTpdo1Communication + 1,
         kTpdo1Mapping + 1,
         kTpdo2 + node,
         1,
         {MappingEntry(kPositionActualValue, 0, 32), 0},
         1},
    };
    for (const Pdo& p : pdos) {
      SdoWrite(i, p.communication, 1, kPdoInvalid | p.cob, 4, "PDO COB-ID, disabled");
      SdoWrite(i, p.mapping, 0, 0, 1, "PDO mapping count, cleared");
      for (std::uint8_t k = 0; k < p.count; ++k) {
        SdoWrite(i, p.mapping, static_cast<std::uint8_t>(k + 1), p.entries[k], 4, "PDO mapping entry");
      }
      SdoWrite(i, p.mapping, 0, p.count, 1, "PDO mapping count");
      SdoWrite(i, p.communication, 2, p.type, 1, "PDO transmission type");
      SdoWrite(i, p.communication, 1, p.cob, 4, "PDO COB-ID, enabled");
    }
    // Limits: written where the configuration gives them, then read back and checked against the driver's.
    const double scale = std::abs(axis.velocity_units_per_mps);
    if (axis.acceleration > 0.0) {
      const auto units = static_cast<std::uint32_t>(std::lround(axis.acceleration * scale));
      SdoWrite(i, kProfileAcceleration, 0, units, 4, "profile acceleration");
      SdoWrite(i, kProfileDeceleration, 0, units, 4, "profile deceleration");
    }
    if (axis.quick_stop_deceleration > 0.0) {
      SdoWrite(i, kQuickStopDeceleration, 0,
               static_cast<std::uint32_t>(std::lround(axis.quick_stop_deceleration * scale)), 4,
               "quick stop deceleration");
    }
    const double max_velocity = SdoRead(i, kMaxProfileVelocity, 0, "max profile velocity") / scale;
    const double acceleration = SdoRead(i, kProfileAcceleration, 0, "profile acceleration") / scale;
    const double deceleration = SdoRead(i, kProfileDeceleration, 0, "profile deceleration") / scale;
    const double quick_stop = SdoRead(i, kQuickStopDeceleration, 0, "quick stop deceleration") / scale;
    const std::string object = "axes[" + std::to_string(i) + "]";
    auto refuse_limit = [&](const std::string& what) {
      throw InputError(config_.source, object, "node " + std::to_string(node) + ": " + what);
    };
    if (max_velocity < context_.max_speed) {
      std::ostringstream what;
      what << "the drive's max profile velocity " << Object(kMaxProfileVelocity, 0) << " = " << max_velocity
           << " m/s is below the driver's --max-speed " << context_.max_speed
           << " m/s: lower --max-speed or raise the drive's limit";
      refuse_limit(what.str());
    }
    if (!(acceleration > 0.0) || !(deceleration > 0.0) || !(quick_stop > 0.0)) {
      refuse_limit(
          "the drive's profile acceleration 0x6083, deceleration 0x6084 or quick stop deceleration 0x6085 is "
          "zero: it would not move or not stop (set \"acceleration\" and \"quick_stop_deceleration\")");
    }
    if (quick_stop < deceleration) {
      std::ostringstream what;
      what << "the drive's quick stop deceleration 0x6085 = " << quick_stop
           << " m/s^2 is below its profile deceleration 0x6084 = " << deceleration << " m/s^2: a quick stop would stop "
           << "slower than a normal one";
      refuse_limit(what.str());
    }
    spdlog::info(
        "CiA 402: node {} ({} axis) on {}: mode {}, max velocity {:.3g} m/s, acceleration {:.3g} / "
        "deceleration {:.3g} / quick stop {:.3g} m/s^2",
        node, i == 0 ? "x" : "y", config_.interface, static_cast<int>(config_.mode), max_velocity, acceleration,
        deceleration, quick_stop);
  }

  // NMT start of these nodes only; the cyclic exchange (SYNC, RPDOs with disable voltage, the master's heartbeat)
  // begins, and the drives' TPDOs and operational heartbeats are awaited: the states are readable.
  for (const Drive& d : drives_) Write(Nmt(kNmtStart, d.node));
  configured_ = true;
  want_ = Want::kDisabled;
  next_sync_us_ = next_heartbeat_us_ = MonotonicMicros();
  const double wait_ms = config_.state_timeout_ms + 2 * config_.heartbeat_ms;
  Await(
      wait_ms,
      [&] {
        for (const Drive& d : drives_) {
          if (d.nmt != kStateOperational || !d.have_tpdo1 || !d.have_tpdo2) return false;
        }
        return true;
      },
      true);
  for (int i = 0; i < 2; ++i) {
    const Drive& d = drives_[i];
    if (d.nmt != kStateOperational) {
      Refuse(i, std::string("not operational after its NMT start (heartbeat says ") + NmtStateName(d.nmt) + ")");
    }
    if (!d.have_tpdo1 || !d.have_tpdo2) Refuse(i, "no TPDO1/TPDO2 after its NMT start and SYNC");
  }
}

void Cia402Robot::Activate() {
  want_ = Want::kSwitchedOn;
  Await(
      config_.state_timeout_ms,
      [&] { return drives_[0].state == DriveState::kSwitchedOn && drives_[1].state == DriveState::kSwitchedOn; }, true);
  for (int i = 0; i < 2; ++i) {
    const Drive& d = drives_[i];
    if (d.state != DriveState::kSwitchedOn) {
      std::string emcy = d.emcy != 0 ? std::string(", last EMCY ") + Hex(d.emcy, 4) + ": " + EmcyText(d.emcy) : "";
      Refuse(i, "did not reach SWITCHED ON within " + std::to_string(std::lround(config_.state_timeout_ms)) +
                    " ms (in " + ToString(d.state) + ", statusword " + Hex(d.statusword, 4) + emcy + ")");
    }
  }
  UpdateFeedback();  // Read() before the loop's first Step gives the drives' positions, not zeros
  spdlog::info("CiA 402: nodes {} and {} on {} switched on; the driver's reset enables them", drives_[0].node,
               drives_[1].node, config_.interface);
}

void Cia402Robot::Deactivate() {
  if (!socket_) return;
  if (configured_) {
    want_ = Want::kDisabled;
    command_[0] = command_[1] = 0.0;
    const std::int64_t now = MonotonicMicros();
    Cycle(now);  // disable voltage
    Cycle(now);
  }
  for (const Drive& d : drives_) Write(Nmt(kNmtEnterPreOperational, d.node));
  configured_ = false;
  socket_.reset();
}

}  // namespace visco::drivers

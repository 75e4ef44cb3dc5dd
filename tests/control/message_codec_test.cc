// The codecs of the controller's LCM messages (control/cycle_message.h, control/fault_message.h), which `visco run`
// and lockstep runs write and `visco replay` reads: on seeded random values of every field, a value encoded, put
// through LCM's wire format and decoded is the value again -- both from the controller's side (record, fault) and from
// the message's (every field of the message, compared as encoded bytes).

#include <gtest/gtest.h>

#include <bit>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "control/cycle_message.h"
#include "control/fault_message.h"

namespace visco::control {
namespace {

constexpr int kSeeds = 200;

class Random {
 public:
  explicit Random(std::uint64_t seed) : engine_(seed) {}
  // Any 64-bit pattern, NaNs and infinities included: the codecs copy numbers, they never compute with them.
  double Double() { return std::bit_cast<double>(engine_()); }
  std::int64_t Int64() { return static_cast<std::int64_t>(engine_()); }
  std::int32_t Int32() { return static_cast<std::int32_t>(engine_()); }
  std::int8_t Int8() { return static_cast<std::int8_t>(engine_()); }
  bool Bool() { return (engine_() & 1) != 0; }
  int Below(int n) { return static_cast<int>(engine_() % static_cast<std::uint64_t>(n)); }
  // Text without NUL (the controller's fields are C strings), any other byte.
  std::string Text(int max_length) {
    std::string s(static_cast<std::size_t>(Below(max_length + 1)), ' ');
    for (char& c : s) c = static_cast<char>(1 + Below(255));
    return s;
  }
  Vec2 Vector() { return {Double(), Double()}; }

 private:
  std::mt19937_64 engine_;
};

template <class M>
std::vector<std::uint8_t> Bytes(const M& m) {
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  return bytes;
}

// Through LCM's wire format, as the log holds it.
template <class M>
M ThroughWire(const M& m) {
  const std::vector<std::uint8_t> bytes = Bytes(m);
  M out;
  EXPECT_EQ(out.decode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  return out;
}

std::uint64_t Bits(double v) { return std::bit_cast<std::uint64_t>(v); }

void ExpectSame(Vec2 a, Vec2 b, const char* what) {
  EXPECT_EQ(Bits(a.x), Bits(b.x)) << what << ".x";
  EXPECT_EQ(Bits(a.y), Bits(b.y)) << what << ".y";
}

CycleRecord RandomRecord(Random& r) {
  CycleRecord c;
  c.cycle = r.Int64();
  ExecutorInput& in = c.input;
  in.now_ns = r.Int64();
  in.now_utime = r.Int64();
  in.have_status = r.Bool();
  in.status.receive_ns = r.Int64();
  in.status.utime = r.Int64();
  in.status.seq = r.Int32();
  in.status.command_seq = r.Int32();
  in.status.position = r.Vector();
  in.status.velocity = r.Vector();
  in.status.contact = r.Bool();
  in.status.contact_force = r.Vector();
  in.status.state = r.Int32();
  in.status.fault_bits = r.Int32();
  in.heartbeat_ns = r.Int64();
  in.peer_lost = r.Bool();
  in.link_fault_code = r.Int32();
  CopyText(in.link_fault, r.Text(sizeof in.link_fault - 1).c_str());
  in.have_frame = r.Bool();
  in.frame.capture_ns = r.Int64();
  in.frame.frame_seq = r.Int64();
  in.frame.count = r.Below(kMaxVisualObservations + 1);
  for (int i = 0; i < in.frame.count; ++i) {
    in.frame.items[i] = {r.Int32(), r.Int8(), r.Bool(), r.Double(), r.Double()};
  }
  in.have_estimate = r.Bool();
  in.estimate.capture_ns = r.Int64();
  in.estimate.frame_seq = r.Int64();
  in.estimate.valid = r.Bool();
  in.estimate.position = r.Vector();
  in.estimate.stddev = r.Double();
  in.estop = r.Bool();
  c.command.utime = in.now_utime;  // the executor stamps its command with the period's time
  c.command.seq = 0;               // not recorded
  c.command.velocity = r.Vector();
  c.command.estop = r.Bool();
  c.command.reset = r.Bool();
  c.command.quick_stop = r.Bool();
  c.mode = static_cast<Mode>(r.Int8());
  c.step_index = r.Int32();
  c.holding = r.Bool();
  return c;
}

void ExpectSame(const CycleRecord& a, const CycleRecord& b) {
  EXPECT_EQ(a.cycle, b.cycle);
  const ExecutorInput& x = a.input;
  const ExecutorInput& y = b.input;
  EXPECT_EQ(x.now_ns, y.now_ns);
  EXPECT_EQ(x.now_utime, y.now_utime);
  EXPECT_EQ(x.have_status, y.have_status);
  EXPECT_EQ(x.status.receive_ns, y.status.receive_ns);
  EXPECT_EQ(x.status.utime, y.status.utime);
  EXPECT_EQ(x.status.seq, y.status.seq);
  EXPECT_EQ(x.status.command_seq, y.status.command_seq);
  ExpectSame(x.status.position, y.status.position, "status.position");
  ExpectSame(x.status.velocity, y.status.velocity, "status.velocity");
  EXPECT_EQ(x.status.contact, y.status.contact);
  ExpectSame(x.status.contact_force, y.status.contact_force, "status.contact_force");
  EXPECT_EQ(x.status.state, y.status.state);
  EXPECT_EQ(x.status.fault_bits, y.status.fault_bits);
  EXPECT_EQ(x.heartbeat_ns, y.heartbeat_ns);
  EXPECT_EQ(x.peer_lost, y.peer_lost);
  EXPECT_EQ(x.link_fault_code, y.link_fault_code);
  EXPECT_STREQ(x.link_fault, y.link_fault);
  EXPECT_EQ(x.have_frame, y.have_frame);
  EXPECT_EQ(x.frame.capture_ns, y.frame.capture_ns);
  EXPECT_EQ(x.frame.frame_seq, y.frame.frame_seq);
  ASSERT_EQ(x.frame.count, y.frame.count);
  for (int i = 0; i < x.frame.count; ++i) {
    EXPECT_EQ(x.frame.items[i].ray, y.frame.items[i].ray) << i;
    EXPECT_EQ(x.frame.items[i].state, y.frame.items[i].state) << i;
    EXPECT_EQ(x.frame.items[i].crossed, y.frame.items[i].crossed) << i;
    EXPECT_EQ(Bits(x.frame.items[i].signed_distance_px), Bits(y.frame.items[i].signed_distance_px)) << i;
    EXPECT_EQ(Bits(x.frame.items[i].stddev_px), Bits(y.frame.items[i].stddev_px)) << i;
  }
  EXPECT_EQ(x.have_estimate, y.have_estimate);
  EXPECT_EQ(x.estimate.capture_ns, y.estimate.capture_ns);
  EXPECT_EQ(x.estimate.frame_seq, y.estimate.frame_seq);
  EXPECT_EQ(x.estimate.valid, y.estimate.valid);
  ExpectSame(x.estimate.position, y.estimate.position, "estimate.position");
  EXPECT_EQ(Bits(x.estimate.stddev), Bits(y.estimate.stddev));
  EXPECT_EQ(x.estop, y.estop);
  EXPECT_EQ(a.command.utime, b.command.utime);
  EXPECT_EQ(a.command.seq, b.command.seq);
  ExpectSame(a.command.velocity, b.command.velocity, "command.velocity");
  EXPECT_EQ(a.command.estop, b.command.estop);
  EXPECT_EQ(a.command.reset, b.command.reset);
  EXPECT_EQ(a.command.quick_stop, b.command.quick_stop);
  EXPECT_EQ(a.mode, b.mode);
  EXPECT_EQ(a.step_index, b.step_index);
  EXPECT_EQ(a.holding, b.holding);
}

// Every field of the message, as a log may hold it (at most a frame's observations).
controller_cycle_t RandomCycleMessage(Random& r) {
  controller_cycle_t m{};
  m.utime = r.Int64();
  m.now_ns = r.Int64();
  m.cycle = r.Int64();
  m.have_status = r.Bool();
  m.status_receive_ns = r.Int64();
  m.status_utime = r.Int64();
  m.status_seq = r.Int32();
  m.status_command_seq = r.Int32();
  for (double& v : m.status_position) v = r.Double();
  for (double& v : m.status_velocity) v = r.Double();
  m.status_contact = r.Bool();
  for (double& v : m.status_contact_force) v = r.Double();
  m.status_state = r.Int32();
  m.status_fault_bits = r.Int32();
  m.heartbeat_ns = r.Int64();
  m.peer_lost = r.Bool();
  m.link_fault_code = r.Int32();
  m.link_fault = r.Text(127);
  m.have_frame = r.Bool();
  m.frame_capture_ns = r.Int64();
  m.frame_seq = r.Int64();
  m.num_observations = r.Below(kMaxVisualObservations + 1);
  for (int i = 0; i < m.num_observations; ++i) {
    m.ray.push_back(r.Int32());
    m.state.push_back(r.Int8());
    m.crossed.push_back(r.Bool());
    m.signed_distance_px.push_back(r.Double());
    m.stddev_px.push_back(r.Double());
  }
  m.have_estimate = r.Bool();
  m.estimate_capture_ns = r.Int64();
  m.estimate_frame_seq = r.Int64();
  m.estimate_valid = r.Bool();
  for (double& v : m.estimate_position) v = r.Double();
  m.estimate_stddev = r.Double();
  m.estop = r.Bool();
  for (double& v : m.command_velocity) v = r.Double();
  m.command_estop = r.Bool();
  m.command_reset = r.Bool();
  m.command_quick_stop = r.Bool();
  m.mode = r.Int8();
  m.step_index = r.Int32();
  m.holding = r.Bool();
  return m;
}

TEST(CycleMessage, RecordRoundTripsThroughTheLog) {
  for (int seed = 0; seed < kSeeds; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    Random r(seed);
    const CycleRecord record = RandomRecord(r);
    ExpectSame(FromCycleMessage(ThroughWire(ToCycleMessage(record))), record);
  }
}

TEST(CycleMessage, EveryFieldOfTheMessageRoundTrips) {
  for (int seed = 0; seed < kSeeds; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    Random r(1000 + seed);
    const controller_cycle_t message = RandomCycleMessage(r);
    EXPECT_EQ(Bytes(ToCycleMessage(FromCycleMessage(ThroughWire(message)))), Bytes(message));
  }
}

TEST(CycleMessage, MoreObservationsThanAFrameHoldsKeepsTheFirst) {
  Random r(7);
  controller_cycle_t message = RandomCycleMessage(r);
  message.num_observations = kMaxVisualObservations + 3;
  message.ray.assign(static_cast<std::size_t>(message.num_observations), 5);
  message.state.assign(message.ray.size(), 1);
  message.crossed.assign(message.ray.size(), true);
  message.signed_distance_px.assign(message.ray.size(), 2.5);
  message.stddev_px.assign(message.ray.size(), 0.5);
  const CycleRecord record = FromCycleMessage(ThroughWire(message));
  EXPECT_EQ(record.input.frame.count, kMaxVisualObservations);
  EXPECT_EQ(record.input.frame.items[kMaxVisualObservations - 1].ray, 5);
}

FaultEvent RandomFault(Random& r) {
  FaultEvent f;
  f.utime = r.Int64();
  f.code = static_cast<FaultCode>(r.Int32());
  f.severity = r.Int8();
  f.robot_stopped = r.Bool();
  f.cleared = r.Bool();
  CopyText(f.message, r.Text(sizeof f.message - 1).c_str());
  return f;
}

TEST(FaultMessage, FaultRoundTripsThroughTheBus) {
  for (int seed = 0; seed < kSeeds; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    Random r(2000 + seed);
    const FaultEvent fault = RandomFault(r);
    const fault_t message = ThroughWire(ToFaultMessage(fault));
    EXPECT_EQ(message.source, "controller");
    EXPECT_EQ(message.emcy_code, 0);
    EXPECT_EQ(message.fault_bits, 0);
    const FaultEvent back = FromFaultMessage(message);
    EXPECT_EQ(back.utime, fault.utime);
    EXPECT_EQ(back.code, fault.code);
    EXPECT_EQ(back.severity, fault.severity);
    EXPECT_EQ(back.robot_stopped, fault.robot_stopped);
    EXPECT_EQ(back.cleared, fault.cleared);
    EXPECT_STREQ(back.message, fault.message);
  }
}

TEST(FaultMessage, EveryFieldOfTheControllersMessageRoundTrips) {
  for (int seed = 0; seed < kSeeds; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    Random r(3000 + seed);
    fault_t message{};
    message.utime = r.Int64();
    message.source = "controller";
    message.code = r.Int32();
    message.severity = r.Int8();
    message.robot_stopped = r.Bool();
    message.cleared = r.Bool();
    message.message = r.Text(static_cast<int>(sizeof(FaultEvent::message)) - 1);
    // emcy_code and fault_bits are the driver's: 0 in the controller's faults.
    EXPECT_EQ(Bytes(ToFaultMessage(FromFaultMessage(ThroughWire(message)))), Bytes(message));
  }
}

}  // namespace
}  // namespace visco::control

#pragma once
// The simulated robot as the plant of simulated drives (`visco sim --plant HOST:PORT`): the robot's axes are moved by
// drives in other processes (a CiA 402 drive simulator on CAN, tests/drivers/hil/cia402_drive_sim.py), not by a
// driver in this process. Each drive sends its axis's actual velocity over UDP; the plant steps the simulated robot
// (docs/semantics.md's motion model: the velocity cone's adversary, contact and friction with the scene's
// C-obstacles, the bounds) with those velocities at a fixed rate and answers each drive with its axis's position and
// velocity, which the drive reports as its encoder (0x6064, 0x606C). The camera renders the robot where the plant
// put it. The wire format (little-endian, one datagram each way; docs/your_own_robot.md "The whole loop"):
//   drive -> plant  16 bytes: "VPL1", axis (u8: 0 = x, 1 = y), 3 bytes 0, velocity (f64, m/s)
//   plant -> drive  24 bytes: "VPL1", axis, 3 bytes 0, position (f64, m), velocity (f64, m/s)
// An axis whose drive has sent nothing for `axis_timeout_s` is commanded 0 (a dead drive's axis is braked).
// Not real-time code: a thread of `visco sim`.

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <mutex>
#include <string>

#include "drivers/simulated_robot.h"

namespace visco::sim {

struct PlantOptions {
  std::string address;          // HOST:PORT to listen on (UDP), e.g. 127.0.0.1:47000; port 0: any free port
  double period_s = 0.001;      // the physics step
  double axis_timeout_s = 0.1;  // a drive silent this long: its axis is commanded 0
  std::string trace_path;       // set: the robot's state every 10 ms, a text line "t x y vx vy contact" (t:
                                // CLOCK_MONOTONIC seconds, metres, m/s, 0/1), for tests that check when it stopped
};

struct PlantStats {
  std::uint64_t steps = 0;
  std::uint64_t datagrams = 0;    // valid velocity datagrams received
  std::uint64_t malformed = 0;    // datagrams of another size or magic, or an axis other than 0 and 1
  std::uint64_t axis_losses = 0;  // times an axis's drive fell silent for axis_timeout_s
  drivers::RobotTruth last;       // the last step's state
};

class UdpPlant {
 public:
  /// Opens and binds the socket. @throws InputError for a malformed address or period; JobFailed when the socket
  /// cannot be bound.
  UdpPlant(const PlantOptions& options, drivers::SimulatedRobot& robot);
  ~UdpPlant();
  UdpPlant(const UdpPlant&) = delete;
  UdpPlant& operator=(const UdpPlant&) = delete;

  /// Steps the robot until `stop` (the thread that calls it owns the robot meanwhile).
  void Run(const std::atomic<bool>& stop);
  /// Any thread.
  PlantStats Stats() const;
  /// The UDP port it listens on (the one given, or the one the system chose for port 0).
  int port() const { return port_; }

 private:
  PlantOptions options_;
  drivers::SimulatedRobot& robot_;
  int fd_ = -1;
  int port_ = 0;
  std::FILE* trace_ = nullptr;
  mutable std::mutex mutex_;
  PlantStats stats_;  // under mutex_
};

/// Parses HOST:PORT (an IPv4 address or "localhost"; port 0..65535). @throws InputError naming `option`.
void ParseUdpAddress(const std::string& address, const char* option, std::string& host, int& port);

}  // namespace visco::sim

#!/usr/bin/python3 -S
"""HIL test of the CiA 402 backend (`visco-rt driver --robot cia402`) against the independent drive simulator
(cia402_drive_sim.py), inside the VM of scripts/hil-vm: the controller's side on vcan0 is python_can_peer.Peer (the
visco protocol from drivers/README.md alone), the drives' bus is vcan1 (or vcan0 in the one-bus case). Each case
asserts what the robot -- the simulated drives -- did:
  A. (cyclic synchronous velocity, two buses, node 3 booting 1 s late) boot and SDO configuration, NMT start of the
     two nodes only, enable on the driver's reset, velocity tracking within the drive's limits, quick stop on the
     driver's watchdog stop and re-enable, a drive's fault (EMCY relayed, the other axis quick-stopped) and fault
     reset, a drive's heartbeat lost, the drives' interface taken down and up, a bus-off on it, the driver killed (the
     drives stop on its lost heartbeat);
  B. a drive that aborts an SDO: a clear error naming node, object and abort code, nothing enabled;
  C. a drive that never boots: a clear error, the other never started;
  D. a drive whose max profile velocity is below the driver's --max-speed: refused (exit 2), nothing started;
  E. (profile velocity, one bus shared with the controller, the drives consuming the driver's own heartbeat) enable,
     track, stop.
usage: cia402_hil_test.py VISCO_RT_BINARY
"""
import json
import os
import signal
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cia402_drive_sim as drives  # noqa: E402
from python_can_peer import FAILURES, Peer, check  # noqa: E402

VISCO = sys.argv[1] if len(sys.argv) > 1 else os.environ["VISCO_BIN"]
COUNTS = 100000  # counts per metre, and velocity units (counts/s) per m/s
DISABLED, READY, MOVING, STOPPED = 0, 1, 2, 3


def config(path, **overrides):
    c = {"format": "visco-cia402-1", "interface": "vcan1", "mode": "cyclic_synchronous_velocity",
         "sync_period_ms": 20, "heartbeat_ms": 100, "heartbeat_timeout_ms": 500, "boot_timeout_ms": 5000,
         "sdo_timeout_ms": 1000, "state_timeout_ms": 2000, "quick_stop_option": 6,
         "axes": [{"node": 2, "counts_per_metre": COUNTS, "acceleration": 2.0, "quick_stop_deceleration": 20.0},
                  {"node": 3, "counts_per_metre": COUNTS, "acceleration": 2.0, "quick_stop_deceleration": 20.0}]}
    c.update(overrides)
    with open(path, "w") as f:
        json.dump(c, f)
    return path


def start_driver(name, cfg, interface="vcan0"):
    log = open("/tmp/cia402_%s.log" % name, "w")
    # Pinned to CPU 1, the test and the simulated drives to CPU 0 (run_in_vm.sh): vcan's receive queues are per CPU, and
    # a sender that migrates between CPUs can have its frames delivered out of order, which a real bus cannot do.
    process = subprocess.Popen(["/usr/bin/taskset", "-c", "1", VISCO, "driver", "--can", interface, "--node", "1",
                                "--watchdog-ms", "300", "--heartbeat-ms", "100", "--status-period-ms", "20",
                                "--max-speed", "0.5", "--robot", "cia402", "--robot-config", cfg],
                               stdout=log, stderr=subprocess.STDOUT)
    process.log_path = log.name
    return process


def output(process):
    with open(process.log_path, errors="replace") as f:
        return f.read()


def states(sim, node):
    return [value for _, what, value in sim.drive(node).history if what == "state"]


def nmt_history(sim, node):
    return [value for _, what, value in sim.drive(node).history if what == "nmt"]


def wait_for(predicate, seconds):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.01)
    return predicate()


def both(sim, state, nodes=(2, 3)):
    return all(sim.snapshot(n)["state"] == state for n in nodes)


def mapping(sim, node, index):
    d = sim.drive(node)
    return [d.get(index, s) for s in range(1, d.get(index, 0) + 1)]


def stop(sim):
    # The simulator's own load beside the case's checks: a failure with a long wait or time step is the emulated CPU's.
    print("   drives: " + sim.load(), flush=True)
    sim.stop()


def enable(peer, sim, what):
    peer.command(0, 0, reset=True)
    # Zero commands meanwhile: a drive's fault reset and enable take several SYNC periods, longer than the driver's
    # watchdog may wait for the controller.
    ok = peer.wait(lambda: peer.status is not None and peer.status[3] == READY and both(sim, drives.ENABLED), 3.0,
                   (0, 0))
    check(ok, what + ": the driver's reset -> READY, both drives OPERATION ENABLED")
    return ok


def case_a():
    print("== A: cyclic synchronous velocity on vcan1, node 3 boots 1 s late", flush=True)
    sim = drives.Sim("vcan1", [2, 3], boot_delays={3: 1.0}).start()
    t0 = time.monotonic()
    driver = start_driver("a", config("/tmp/cia402_a.json"))
    peer = Peer(1)
    up = peer.wait(lambda: peer.session is not None and peer.status is not None, 60.0)
    check(up, "driver up (session and status on vcan0)")
    if not up:
        print(output(driver))
        driver.kill()
        stop(sim)
        return
    boot3 = [t for t, what, value in sim.drive(3).history if what == "nmt" and value == "boot-up"]
    check(boot3 and boot3[-1] - t0 >= 0.5, "node 3 booted late (%.2f s after the driver started)" %
          ((boot3[-1] - t0) if boot3 else -1))
    for n in (2, 3):
        d = sim.drive(n)
        check(d.nmt == drives.OPERATIONAL, "node %d started (NMT operational)" % n)
        check(d.get(0x6060) == 9 and d.get(0x605A) == 6 and d.get(0x1017) == 100 and
              d.get(0x1016, 1) == (127 << 16 | 500),
              "node %d configured by SDO: mode 9, quick stop option 6, heartbeat 100 ms, consumer 127/500 ms" % n)
        check(mapping(sim, n, 0x1600) == [0x60400010, 0x60FF0020] and d.get(0x1400, 2) == 1,
              "node %d RPDO1 = controlword + target velocity, synchronous" % n)
        check(mapping(sim, n, 0x1A00) == [0x60410010, 0x606C0020] and mapping(sim, n, 0x1A01) == [0x60640020]
              and d.get(0x1800, 2) == 1 and d.get(0x1801, 2) == 1 and not d.get(0x1801, 1) & 0x80000000,
              "node %d TPDO1 = statusword + velocity, TPDO2 = position, both on every SYNC" % n)
        check(d.get(0x6083) == 2 * COUNTS and d.get(0x6085) == 20 * COUNTS,
              "node %d acceleration and quick stop deceleration written" % n)
        check(d.state == drives.SWITCHED_ON, "node %d SWITCHED ON after activation (%s)" % (n, d.state))
    check(peer.status[3] == DISABLED, "the driver boots DISABLED")

    if not enable(peer, sim, "enable"):
        print(output(driver))
    # Velocity tracking: (0.3, -0.2) m/s, 2 m/s^2.
    peer.wait(lambda: False, 1.0, (0.3, -0.2))
    s2, s3 = sim.snapshot(2), sim.snapshot(3)
    check(abs(s2["velocity"] - 0.3 * COUNTS) < 1 and abs(s3["velocity"] + 0.2 * COUNTS) < 1,
          "the drives track (0.3, -0.2) m/s (%.0f, %.0f counts/s)" % (s2["velocity"], s3["velocity"]))
    p0 = sim.snapshot(2)["position"], time.monotonic()
    peer.wait(lambda: False, 0.5, (0.3, -0.2))
    p1 = sim.snapshot(2)["position"], time.monotonic()
    speed = (p1[0] - p0[0]) / COUNTS / (p1[1] - p0[1])
    check(abs(speed - 0.3) < 0.03, "node 2 advanced at %.3f m/s" % speed)
    check(peer.status[3] == MOVING and abs(peer.status[1] - 0.3) < 0.005 and abs(peer.status[2] + 0.2) < 0.005,
          "the driver's status reports the drives' velocity (%.4f, %.4f) m/s" % (peer.status[1], peer.status[2]))
    check(max(sim.snapshot(n)["max_speed"] for n in (2, 3)) <= sim.drive(2).get(0x607F),
          "never faster than the drive's max profile velocity")

    # Quick stop on the driver's stop: the controller goes silent, the watchdog (300 ms) stops the robot.
    last = time.monotonic()
    stopped = wait_for(lambda: both(sim, drives.QUICK_STOP) and sim.snapshot(2)["velocity"] == 0 and
                       sim.snapshot(3)["velocity"] == 0, 3.0)
    took = time.monotonic() - last
    check(stopped, "watchdog stop: both drives QUICK STOP ACTIVE and still (%.0f ms after the last command)" %
          (took * 1e3))
    check(took < 0.3 + 0.5, "within the watchdog period plus 500 ms")
    peer.drain(0.2)
    check(peer.status[3] == STOPPED, "the driver STOPPED")
    if not enable(peer, sim, "after the quick stop (transition 16)"):
        print(output(driver))
    peer.wait(lambda: False, 0.4, (0.2, 0.2))

    # A drive's fault: EMCY relayed, the other axis quick-stopped, fault reset by the driver's reset.
    peer.emcy.clear()
    sim.inject_fault(2, 0x2310)
    got = peer.wait(lambda: any(e[0] == 0x2310 and e[3] for e in peer.emcy), 2.0, (0.2, 0.2))
    check(got, "node 2's EMCY 0x2310 relayed by the driver (robot stopped)")
    check(wait_for(lambda: sim.snapshot(2)["state"] == drives.FAULT and
                   sim.snapshot(3)["state"] == drives.QUICK_STOP and sim.snapshot(3)["velocity"] == 0, 2.0),
          "node 2 in FAULT, node 3 quick-stopped and still")
    peer.drain(0.1)
    check(peer.status[3] == STOPPED, "the driver STOPPED on the drive's fault")
    if enable(peer, sim, "fault reset"):
        check(drives.SWITCH_ON_DISABLED in states(sim, 2)[-4:], "node 2 went through SWITCH ON DISABLED (reset)")
    peer.wait(lambda: False, 0.4, (0.2, 0.2))

    # A drive's heartbeat lost.
    peer.emcy.clear()
    sim.silence(3)
    lost = time.monotonic()
    got = peer.wait(lambda: any(e[0] == 0x8130 and e[3] for e in peer.emcy), 3.0, (0.2, 0.2))
    check(got, "node 3's lost heartbeat reported with EMCY 0x8130 (%.0f ms, consumer time 500 ms)" %
          ((time.monotonic() - lost) * 1e3))
    check(wait_for(lambda: sim.snapshot(2)["state"] == drives.QUICK_STOP and sim.snapshot(2)["velocity"] == 0, 2.0),
          "the other axis (node 2) quick-stopped")
    sim.silence(3, False)
    time.sleep(1.0)  # node 3 missed the master's heartbeat while it was silent: it faults by itself
    check(sim.snapshot(3)["state"] == drives.FAULT, "node 3 faulted on the master's heartbeat it missed")
    enable(peer, sim, "after the heartbeat loss")
    peer.wait(lambda: False, 0.4, (0.2, 0.2))

    # The drives' interface taken down (what vcan can do of a bus-off) and up again.
    peer.emcy.clear()
    subprocess.run(["ip", "link", "set", "vcan1", "down"], check=False)
    got = peer.wait(lambda: any(e[0] in (0x8100, 0x8130) and e[3] for e in peer.emcy), 3.0, (0.2, 0.2))
    check(got, "the drives' interface down: reported, robot stopped (EMCY %s)" %
          ", ".join("0x%04X" % e[0] for e in peer.emcy))
    peer.drain(0.1)
    check(peer.status[3] == STOPPED, "the driver STOPPED")
    check(wait_for(lambda: both(sim, drives.FAULT), 3.0),
          "the drives, deaf to the master's heartbeat, stopped themselves (FAULT)")
    subprocess.run(["ip", "link", "set", "vcan1", "up"], check=False)
    time.sleep(0.5)
    enable(peer, sim, "interface up again")
    peer.wait(lambda: False, 0.4, (0.2, 0.2))
    check(sim.snapshot(2)["velocity"] > 0.1 * COUNTS, "moving again")

    # A bus-off on the drives' interface, as a CAN controller reports it (an error frame; vcan has no controller to
    # go bus-off by itself).
    peer.emcy.clear()
    injector = drives.can.Bus(interface="socketcan", channel="vcan1")
    injector.send(drives.can.Message(arbitration_id=0x040, is_error_frame=True, is_extended_id=False, dlc=8,
                                     data=bytes(8)))  # CAN_ERR_BUSOFF
    busoff = time.monotonic()
    got = peer.wait(lambda: any(e[0] == 0x8100 and e[3] for e in peer.emcy), 2.0, (0.2, 0.2))
    check(got, "bus-off on the drives' interface reported with EMCY 0x8100 (%.0f ms)" %
          ((time.monotonic() - busoff) * 1e3))
    check(wait_for(lambda: both(sim, drives.QUICK_STOP) and sim.snapshot(2)["velocity"] == 0 and
                   sim.snapshot(3)["velocity"] == 0, 2.0), "bus-off: both drives quick-stopped and still")
    peer.drain(0.1)
    check(peer.status[3] == STOPPED, "bus-off: the driver STOPPED")
    injector.send(drives.can.Message(arbitration_id=0x100, is_error_frame=True, is_extended_id=False, dlc=8,
                                     data=bytes(8)))  # CAN_ERR_RESTARTED
    injector.shutdown()
    enable(peer, sim, "after the bus-off")
    peer.wait(lambda: False, 0.4, (0.2, 0.2))
    check(sim.snapshot(2)["velocity"] > 0.1 * COUNTS, "moving again after the bus-off")

    # The driver killed: the drives consume its heartbeat and stop.
    driver.send_signal(signal.SIGKILL)
    driver.wait()
    killed = time.monotonic()
    check(wait_for(lambda: both(sim, drives.FAULT) and sim.snapshot(2)["velocity"] == 0 and
                   sim.snapshot(3)["velocity"] == 0, 3.0),
          "driver killed: both drives FAULT and still after %.0f ms (consumer time 500 ms)" %
          ((time.monotonic() - killed) * 1e3))
    check(all(0x8130 in [v for _, w, v in sim.drive(n).history if w == "emcy"] for n in (2, 3)),
          "each drive sent EMCY 0x8130 (heartbeat of the master lost)")
    peer.bus.shutdown()
    stop(sim)


def refused(name, sim, cfg, expect_code, expect_words, interface="vcan0"):
    driver = start_driver(name, cfg, interface)
    try:
        code = driver.wait(timeout=60)
    except subprocess.TimeoutExpired:
        driver.kill()
        code = None
    text = output(driver)
    check(code == expect_code, "%s: exit status %s (expected %d)" % (name, code, expect_code))
    missing = [w for w in expect_words if w not in text]
    check(not missing, "%s: the error names %s" % (name, ", ".join(expect_words)))
    if missing:
        print(text[-1500:])
    for n in sim.drives:
        check(all(s not in (drives.READY, drives.SWITCHED_ON, drives.ENABLED) for s in states(sim, n)) and
              "operational" not in nmt_history(sim, n), "%s: node %d never started nor powered" % (name, n))
    stop(sim)


def case_b():
    print("== B: node 3 aborts the SDO write of its mode of operation", flush=True)
    sim = drives.Sim("vcan1", [2, 3], aborts={3: (0x6060, 0, 0x06090030)}).start()
    refused("b", sim, config("/tmp/cia402_b.json"), 1,
            ["node 3 on vcan1", "0x6060:00 (modes of operation)", "0x06090030", "invalid value for parameter"])


def case_c():
    print("== C: node 3 never boots", flush=True)
    sim = drives.Sim("vcan1", [2, 3], boot_delays={3: 1e9}).start()
    refused("c", sim, config("/tmp/cia402_c.json", boot_timeout_ms=1500), 1,
            ["node 3 on vcan1", "no boot-up message (0x703) within 1500 ms"])


def case_d():
    print("== D: node 2's max profile velocity is below the driver's --max-speed", flush=True)
    sim = drives.Sim("vcan1", [2, 3], max_velocities={2: 1000}).start()
    refused("d", sim, config("/tmp/cia402_d.json"), 2,
            ["axes[0]: node 2", "max profile velocity 0x607F:00 = 0.01 m/s", "--max-speed 0.5"])


def case_e():
    print("== E: profile velocity on one bus (vcan0) with the controller, the drives consuming the driver's heartbeat",
          flush=True)
    # The drives' speed uncertain by +-10 % (docs/semantics.md's motion model, as the simulated robot has it).
    sim = drives.Sim("vcan0", [2, 3], speed_uncertainty=0.1).start()
    driver = start_driver("e", config("/tmp/cia402_e.json", interface="vcan0", mode="profile_velocity",
                                      master_node=1, sync_period_ms=10))
    peer = Peer(1)
    up = peer.wait(lambda: peer.session is not None and peer.status is not None, 60.0)
    check(up, "one bus: driver up")
    for n in (2, 3):
        d = sim.drive(n)
        check(d.get(0x6060) == 3 and d.get(0x1400, 2) == 255 and d.get(0x1016, 1) == (1 << 16 | 500),
              "node %d: mode 3, RPDO1 asynchronous, consuming the driver's own heartbeat (node 1)" % n)
    if up and enable(peer, sim, "one bus"):
        peer.wait(lambda: False, 1.0, (-0.1, 0.25))
        samples = []
        peer.wait(lambda: samples.append((sim.snapshot(2)["velocity"], sim.snapshot(3)["velocity"])), 1.0,
                  (-0.1, 0.25))
        worst = max(max(abs(v2 / (-0.1 * COUNTS) - 1), abs(v3 / (0.25 * COUNTS) - 1)) for v2, v3 in samples)
        check(worst <= 0.1 + 1e-3, "one bus: the drives track (-0.1, 0.25) m/s within their 10 %% uncertainty "
              "(worst %.1f %% of %d samples)" % (worst * 100, len(samples)))
        check(worst > 0.005, "one bus: the uncertainty is there (the speed varies)")
        peer.command(0, 0, estop=True)

        # Quick-stopped; or, where the emulated CPU stalled this process longer than the drives' consumer time (seen
        # under a loaded host), faulted by their own heartbeat consumer first: either way stopped and still.
        def stopped(n):
            s = sim.snapshot(n)
            lost = any(what == "heartbeat lost" for _, what, _ in sim.drive(n).history)
            return s["velocity"] == 0 and (s["state"] == drives.QUICK_STOP or (lost and s["state"] == drives.FAULT))
        check(wait_for(lambda: stopped(2) and stopped(3), 2.0),
              "one bus: e-stop -> both drives quick-stopped and still (%s, %s)" %
              (sim.snapshot(2)["state"], sim.snapshot(3)["state"]))
    driver.send_signal(signal.SIGTERM)
    driver.wait()
    check(wait_for(lambda: all(sim.drive(n).nmt == drives.PRE_OPERATIONAL for n in (2, 3)), 2.0),
          "driver ended: drives back in pre-operational, voltage disabled (%s, %s)" %
          (sim.snapshot(2)["state"], sim.snapshot(3)["state"]))
    summary = [line for line in output(driver).splitlines() if line.startswith("{")]
    check(bool(summary) and json.loads(summary[-1])["estops"] == 1, "the driver's summary counts the e-stop")
    peer.bus.shutdown()
    stop(sim)


def main():
    started = time.monotonic()
    for case in (case_a, case_b, case_c, case_d, case_e):
        t = time.monotonic()
        case()
        print("   (%.1f s)" % (time.monotonic() - t), flush=True)
    print("cia402 HIL: %d failure(s) in %.1f s" % (len(FAILURES), time.monotonic() - started), flush=True)
    return 1 if FAILURES else 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/python3 -S
"""The whole loop's latency from a camera frame to the drives' target velocity, from the controller's log (`visco run
--log`: its period records, controller_cycle_t) and the candump of the drives' bus: for every frame the controller
used (the first period whose robot estimate comes from a new frame), the time from the frame's capture to the first
RPDO1 (controlword, target velocity) on the drives' bus after that period, i.e. the first drive target that can
carry the frame's effect. Both clocks are the machine's wall clock (the records' utime and capture time; candump's
receive timestamps). Prints quantiles; exit 1 when no frame could be matched.

usage: loop_latency.py CONTROLLER.lcmlog CANDUMP.log [--interface vcan1] [--nodes 2 3]
"""
import argparse
import bisect
import os
import re
import statistics
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "replay"))
import logtool  # noqa: E402  (lcm-logger's format, standard library only)

LINE = re.compile(r"^\((\d+\.\d+)\)\s+(\S+)\s+([0-9A-Fa-f]{3})#([0-9A-Fa-f]*)\s*$")


def cycle(payload):
    """The fields of controller_cycle_t up to the command (lcmtypes/controller_cycle_t.lcm)."""
    r = logtool.Message(payload)
    c = {}
    c["utime"], c["now_ns"], c["cycle"] = r.take("qqq")
    r.take("?qqii"), r.take("dd"), r.take("dd"), r.take("?"), r.take("dd"), r.take("iiq?i")
    r.string()
    r.take("?qq")
    n = r.take("i")
    r.take("%di%db%d?%dd%dd" % (n, n, n, n, n))  # the observations
    c["have_estimate"], c["estimate_capture_ns"], c["estimate_frame_seq"], _ = r.take("?qq?")
    r.take("ddd"), r.take("?")
    c["command"] = r.take("dd")
    return c


def frame_times(log, rpdo_times):
    """For each camera frame the controller used (the first period whose robot estimate comes from it): its capture
    time, the period's time and the first drive target after it (None while no drive ran: no RPDO1 within 0.5 s,
    before the drives are up or after they stopped), all in seconds of the wall clock."""
    last_seq = None
    for _, _, channel, payload in logtool.read(log):
        if channel != logtool.CYCLE:
            continue
        c = cycle(payload)
        if not c["have_estimate"] or c["estimate_frame_seq"] == last_seq:
            continue
        last_seq = c["estimate_frame_seq"]
        wall_minus_mono = c["utime"] * 1e-6 - c["now_ns"] * 1e-9
        used = c["utime"] * 1e-6
        i = bisect.bisect_right(rpdo_times, used)
        target = rpdo_times[i] if i < len(rpdo_times) and rpdo_times[i] - used < 0.5 else None
        yield c["estimate_capture_ns"] * 1e-9 + wall_minus_mono, used, target


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("log")
    parser.add_argument("candump")
    parser.add_argument("--interface", default="vcan1")
    parser.add_argument("--nodes", type=int, nargs="+", default=[2, 3])
    args = parser.parse_args()
    rpdo_ids = {0x200 + n for n in args.nodes}
    rpdo_times = []
    for line in open(args.candump, errors="replace"):
        m = LINE.match(line)
        if m and m.group(2) == args.interface and int(m.group(3), 16) in rpdo_ids:
            rpdo_times.append(float(m.group(1)))
    rpdo_times.sort()
    latencies, to_controller, to_drive, idle = [], [], [], 0
    for capture, used, target in frame_times(args.log, rpdo_times):
        if target is None:
            idle += 1
            continue
        latencies.append(target - capture)
        to_controller.append(used - capture)
        to_drive.append(target - used)
    if not latencies:
        print("loop latency: no frame of the log matched a drive target on %s" % args.interface)
        return 1

    def quantiles(values):
        q = statistics.quantiles(values, n=20, method="inclusive") if len(values) > 1 else [values[0]] * 19
        return "p50 %.0f ms, p95 %.0f ms, max %.0f ms" % (statistics.median(values) * 1e3, q[18] * 1e3,
                                                          max(values) * 1e3)

    print("loop latency: camera frame (its capture time) -> first drive target (RPDO1 on %s) after the controller "
          "used it, %d frames (%d more while no drive ran): min %.0f ms, %s; of which capture -> the controller's "
          "period using it %s, that period -> the drive's target %s" %
          (args.interface, len(latencies), idle, min(latencies) * 1e3, quantiles(latencies), quantiles(to_controller),
           quantiles(to_drive)))
    return 0


if __name__ == "__main__":
    sys.exit(main())

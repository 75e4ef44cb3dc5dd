#!/usr/bin/python3 -S
"""Decodes a candump log (`candump -L`) of CiA 402 drives and their master -- NMT, SYNC, heartbeats, expedited SDO,
EMCY and the PDOs the visco CiA 402 backend maps (RPDO1 0x200+n: controlword u16, target velocity i32; TPDO1 0x180+n:
statusword u16, velocity actual i32; TPDO2 0x280+n: position actual i32) -- from CiA 301 / CiA 402 alone, checks the
traffic, and prints the figures: frames per second by kind and the bus load against 1 Mbit/s on each interface.

Checks (each failure is printed and makes the exit status 1):
  * every frame is known: a drive node's (--nodes), the visco driver's (--visco-node), the master's heartbeat
    (--master-node) or NMT/SYNC, with its length;
  * NMT commands are addressed to drive nodes, never broadcast (node 0);
  * every RPDO1 controlword is a CiA 402 command (disable voltage, quick stop, shutdown, switch on, enable
    operation, fault reset) and a target velocity other than 0 goes only with enable operation;
  * every SDO request is answered (an expedited answer or an abort, decoded) before the next one to that node;
  * after a drive's EMCY (error code not 0) the master's second RPDO1 to every drive is a stop (quick stop or
    disable voltage, or a fault reset's edge): one failing drive stops every axis.
usage: decode_cia402.py CANDUMP.log --nodes 2 3 [--visco-node 1] [--self-test]
"""
import argparse
import re
import statistics
import struct
import sys

ABORTS = {0x05040000: "SDO protocol timed out", 0x05040001: "command specifier not valid",
          0x06010000: "unsupported access", 0x06010002: "write to a read-only object",
          0x06020000: "object does not exist", 0x06040041: "object cannot be mapped",
          0x06040042: "mapping exceeds the PDO length", 0x06070010: "data type / length mismatch",
          0x06090011: "sub-index does not exist", 0x06090030: "invalid value", 0x08000022: "device state"}
COMMANDS = {0x0000: "disable voltage", 0x0002: "quick stop", 0x0006: "shutdown", 0x0007: "switch on",
            0x000F: "enable operation", 0x0080: "fault reset"}
LINE = re.compile(r"^\((\d+\.\d+)\)\s+(\S+)\s+([0-9A-Fa-f]{3})#([0-9A-Fa-f]*)\s*$")


def frame_bits(dlc, worst):
    """A classic base frame on the wire: 47 + 8 dlc bits with the interframe space; worst-case stuffing adds one bit
    in four of the 34 + 8 dlc stuffed bits."""
    return 47 + 8 * dlc + ((34 + 8 * dlc - 1) // 4 if worst else 0)


def kind_of(cid, dlc, nodes, visco, master):
    if cid == 0x700 + master:
        return "heartbeat" if dlc == 1 else None
    if cid == 0x000:
        return "NMT" if dlc == 2 else None
    if cid == 0x080:
        return "SYNC" if dlc == 0 else None
    base, node = cid & 0x780, cid & 0x7F
    if node == visco and base in (0x080, 0x180, 0x200, 0x280, 0x380, 0x480, 0x700):
        return {0x200: "visco command", 0x180: "visco status", 0x280: "visco position", 0x380: "visco force",
                0x480: "visco session", 0x700: "visco heartbeat", 0x080: "visco EMCY"}[base]
    if node not in nodes:
        return None
    return {(0x080, 8): "EMCY", (0x180, 6): "TPDO1", (0x200, 6): "RPDO1", (0x280, 4): "TPDO2",
            (0x580, 8): "SDO answer", (0x600, 8): "SDO request", (0x700, 1): "heartbeat"}.get((base, dlc))


def analyse(lines, nodes, visco, master=127, quiet=False):
    failures = []

    def fail(what):
        failures.append(what)
        if not quiet:
            print("FAIL " + what)

    frames = []
    for line in lines:
        m = LINE.match(line.strip())
        if not m:
            continue
        t, iface, cid, data = float(m.group(1)), m.group(2), int(m.group(3), 16), bytes.fromhex(m.group(4))
        frames.append((t, iface, cid, data))
    # In the order the frames were sent: the kernel stamps a frame when it is sent, but on two CPUs the receive
    # queues are per CPU and candump may read a drive's answer before the request it answers (seen in the VM).
    frames.sort(key=lambda f: f[0])
    pending = {}      # node -> (time, index, sub) of an unanswered SDO request
    emcy_watch = []   # (node of the EMCY, time, {node: RPDOs seen since})
    counts = {}
    aborts = []
    for t, iface, cid, data in frames:
        kind = kind_of(cid, len(data), nodes, visco, master)
        if kind is None:
            fail("%.6f %s: unknown frame %03X#%s" % (t, iface, cid, data.hex().upper()))
            continue
        counts.setdefault(iface, {}).setdefault(kind, []).append((t, len(data)))
        node = cid & 0x7F
        if kind == "NMT" and data[1] == 0:
            fail("%.6f %s: NMT command 0x%02X broadcast to every node" % (t, iface, data[0]))
        elif kind == "RPDO1":
            cw, target = struct.unpack("<Hi", data)
            if cw not in COMMANDS:
                fail("%.6f node %d: controlword 0x%04X is no CiA 402 command" % (t, node, cw))
            if target != 0 and cw != 0x000F:
                fail("%.6f node %d: target velocity %d with %s" % (t, node, target, COMMANDS.get(cw, hex(cw))))
            for source, since, seen in emcy_watch:
                seen.setdefault(node, []).append(cw)
                if len(seen[node]) == 2 and cw not in (0x0000, 0x0002, 0x0080):
                    fail("%.6f node %d: %s %.1f ms after node %d's EMCY (a stop expected)" %
                         (t, node, COMMANDS.get(cw, hex(cw)), (t - since) * 1e3, source))
            emcy_watch = [w for w in emcy_watch if len(w[2]) < len(nodes) or min(map(len, w[2].values())) < 2]
        elif kind == "SDO request":
            if node in pending:
                fail("%.6f node %d: SDO request before the answer to %04X:%02X" % ((t, node) + pending[node][1:]))
            pending[node] = (t, data[1] | data[2] << 8, data[3])
        elif kind == "SDO answer":
            if node not in pending:
                fail("%.6f node %d: SDO answer without a request" % (t, node))
            elif data[0] == 0x80:
                code = struct.unpack("<I", data[4:8])[0]
                aborts.append((node, pending[node][1], pending[node][2], code))
                if not quiet:
                    print("     node %d aborted the SDO of %04X:%02X: 0x%08X %s" %
                          (node, pending[node][1], pending[node][2], code, ABORTS.get(code, "(unknown code)")))
            pending.pop(node, None)
        elif kind == "EMCY":
            code = struct.unpack("<H", data[:2])[0]
            if code != 0:
                emcy_watch.append((node, t, {}))
    latencies = command_latencies(frames, nodes, visco)
    for node, (t, index, sub) in pending.items():
        # A request still unanswered at the end of a case that ended by refusing: the log shows it went unanswered.
        if not quiet:
            print("     node %d: SDO request for %04X:%02X at %.6f not answered" % (node, index, sub, t))
    return failures, counts, aborts, frames, latencies


def command_latencies(frames, nodes, visco):
    """Seconds from each controller command that changes the x velocity (the visco protocol's command 0x200 + visco
    node, vx int16 at bytes 2-3) to the first RPDO1 of the x axis' drive (nodes[0]) whose target velocity changes to a
    value of the same sign, other than 0, within a second: the driver's and the master's part of the path to the
    drive."""
    out = []
    last_vx, last_target, waiting = 0, 0, None
    for t, iface, cid, data in frames:
        if cid == 0x200 + visco and len(data) == 8:
            vx = struct.unpack("<h", data[2:4])[0]
            if vx != last_vx and vx != 0 and waiting is None:
                waiting = (t, vx)
            last_vx = vx
        elif cid == 0x200 + nodes[0] and len(data) == 6:
            target = struct.unpack("<Hi", data)[1]
            if waiting is not None and target != last_target and target != 0 and (target > 0) == (waiting[1] > 0):
                # Over a second: the drives were down when the command came (a test that restarts them).
                if t - waiting[0] < 1.0:
                    out.append(t - waiting[0])
                waiting = None
            last_target = target
    return out


def figures(counts):
    for iface, kinds in sorted(counts.items()):
        times = [t for frames in kinds.values() for t, _ in frames]
        if not times:
            continue
        start, end = min(times), max(times)
        # Per 1 s window: frames and bits.
        windows = {}
        for kind, frames in kinds.items():
            for t, dlc in frames:
                w = windows.setdefault(int(t - start), {"frames": 0, "bits": 0, "worst": 0, "kinds": {}})
                w["frames"] += 1
                w["bits"] += frame_bits(dlc, False)
                w["worst"] += frame_bits(dlc, True)
                w["kinds"][kind] = w["kinds"].get(kind, 0) + 1
        busiest = max(windows.values(), key=lambda w: w["bits"])
        total = sum(len(f) for f in kinds.values())
        print("%s: %d frames in %.1f s; busiest second: %d frames (%s), bus load %.2f %% of 1 Mbit/s "
              "(%.2f %% with worst-case bit stuffing)" %
              (iface, total, end - start, busiest["frames"],
               ", ".join("%s %d" % kv for kv in sorted(busiest["kinds"].items())),
               busiest["bits"] / 1e4, busiest["worst"] / 1e4))
        # The steady state: seconds of cyclic exchange (SYNC at no less than 80 % of its busiest rate) without SDO;
        # on a bus without SYNC, seconds of the controller's commands at no less than 80 % of their busiest rate.
        cyclic = "SYNC" if "SYNC" in kinds else "visco command"
        top = max(w["kinds"].get(cyclic, 0) for w in windows.values())
        steady = [w for w in windows.values() if top and w["kinds"].get(cyclic, 0) >= 0.8 * top
                  and "SDO request" not in w["kinds"]]
        if steady:
            per_kind = {k: statistics.median(w["kinds"].get(k, 0) for w in steady)
                        for k in sorted({k for w in steady for k in w["kinds"]})}
            print("%s: cyclic exchange, median of %d seconds: %d frames/s (%s), bus load %.2f %% of 1 Mbit/s "
                  "(%.2f %% worst case)" %
                  (iface, len(steady), statistics.median(w["frames"] for w in steady),
                   ", ".join("%s %g" % kv for kv in per_kind.items()),
                   statistics.median(w["bits"] for w in steady) / 1e4,
                   statistics.median(w["worst"] for w in steady) / 1e4))
        syncs = sorted(t for t, _ in kinds.get("SYNC", []))
        gaps = [b - a for a, b in zip(syncs, syncs[1:]) if b - a < 0.5]
        if len(gaps) > 10:
            gaps.sort()
            print("%s: SYNC period p50 %.2f ms, p99 %.2f ms, max %.2f ms (%d periods)" %
                  (iface, statistics.median(gaps) * 1e3, gaps[int(0.99 * (len(gaps) - 1))] * 1e3, gaps[-1] * 1e3,
                   len(gaps)))


def self_test():
    """The checks fail where they must."""
    ok = ["(1.000000) vcan1 602#2F60600009000000", "(1.001000) vcan1 582#6060600000000000",
          "(1.002000) vcan1 000#0102", "(1.010000) vcan1 202#0F0010270000", "(1.011000) vcan1 080#",
          "(1.012000) vcan1 182#37021027000000"[:-2], "(1.013000) vcan1 282#10270000", "(1.014000) vcan1 702#05"]
    cases = {
        "clean log": (ok + ["(1.02) vcan1 77F#05"], 0),
        "unknown frame": (ok + ["(2.0) vcan1 123#00"], 1),
        "NMT broadcast": (ok + ["(2.0) vcan1 000#0100"], 1),
        "bad controlword": (ok + ["(2.0) vcan1 202#1F0000000000"], 1),
        "velocity without enable": (ok + ["(2.0) vcan1 202#070010000000"], 1),
        "answer logged before its request": (ok + ["(2.001) vcan1 582#6000100000000000",
                                                   "(2.000) vcan1 602#4000100000000000"], 0),
        "request unanswered, then another": (ok + ["(2.0) vcan1 602#4000100000000000",
                                                    "(2.1) vcan1 602#4000100000000000"], 1),
        "no stop after an EMCY": (ok + ["(2.0) vcan1 082#1023010000000000", "(2.01) vcan1 202#0F0000000000",
                                        "(2.02) vcan1 202#0F0000000000"], 1),
        "stop after an EMCY": (ok + ["(2.0) vcan1 082#1023010000000000", "(2.01) vcan1 202#0F0000000000",
                                     "(2.02) vcan1 202#020000000000"], 0),
    }
    bad = 0
    for name, (lines, expected) in cases.items():
        failures = analyse(lines, [2], 1, 127, quiet=True)[0]
        good = (len(failures) > 0) == (expected > 0)
        print(("ok   " if good else "FAIL ") + "self-test: %s -> %d failure(s)" % (name, len(failures)))
        bad += not good
    return bad


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("log", nargs="?")
    parser.add_argument("--nodes", type=int, nargs="+", default=[2, 3])
    parser.add_argument("--visco-node", type=int, default=1)
    parser.add_argument("--master-node", type=int, default=127)
    parser.add_argument("--self-test", action="store_true")
    args = parser.parse_args()
    if args.self_test:
        return 1 if self_test() else 0
    with open(args.log, errors="replace") as f:
        failures, counts, aborts, frames, latencies = analyse(f, args.nodes, args.visco_node, args.master_node)
    figures(counts)
    if latencies:
        latencies.sort()
        print("controller command -> the drive's new target velocity (RPDO1): p50 %.1f ms, max %.1f ms (%d changes)" %
              (statistics.median(latencies) * 1e3, latencies[-1] * 1e3, len(latencies)))
    print("decode_cia402: %d frames, %d SDO abort(s), %d failure(s)" % (len(frames), len(aborts), len(failures)))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

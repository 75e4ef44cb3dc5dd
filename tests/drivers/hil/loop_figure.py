#!/usr/bin/python3 -S
"""Draws the whole loop's traffic as an SVG (docs/your_own_robot.md's figure): from the candump of both buses
(whole_loop_test.py's candump.log), per second of the run, the frames of each interface by kind (the controller's
commands on vcan0, the drives' SYNC and PDOs on vcan1) and each interface's bus load against 1 Mbit/s; from the
controller's log, each camera frame's latency to the drives' target (loop_latency.py's measure) at the time it was used.

usage: loop_figure.py CANDUMP.log CONTROLLER.lcmlog OUT.svg
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import decode_cia402  # noqa: E402
import loop_latency  # noqa: E402

W, H, LEFT, RIGHT, TOP, PANEL, GAP = 900, 800, 60, 60, 30, 190, 60
SERIES = [("vcan0", "visco command", "#1f77b4", "commands (vcan0)"), ("vcan1", "SYNC", "#2ca02c", "SYNC (vcan1)"),
          ("vcan1", "RPDO1", "#ff7f0e", "RPDO1: target velocity (vcan1)"),
          ("vcan1", "TPDO", "#9467bd", "TPDO1 + TPDO2: status, velocity, position (vcan1)")]


def main():
    candump, log, svg = sys.argv[1:4]
    frames = []
    for line in open(candump, errors="replace"):
        m = decode_cia402.LINE.match(line.strip())
        if m:
            frames.append((float(m.group(1)), m.group(2), int(m.group(3), 16), len(m.group(4)) // 2))
    frames.sort()
    t0, t1 = frames[0][0], frames[-1][0]
    seconds = int(t1 - t0) + 1
    counts = {}
    bits = {"vcan0": [0] * seconds, "vcan1": [0] * seconds}
    for t, iface, cid, dlc in frames:
        kind = decode_cia402.kind_of(cid, dlc, [2, 3], 1, 127) or "other"
        if kind.startswith("TPDO"):
            kind = "TPDO"
        s = int(t - t0)
        counts.setdefault((iface, kind), [0] * seconds)[s] += 1
        if iface in bits:
            bits[iface][s] += decode_cia402.frame_bits(dlc, False)
    # The latency of each camera frame used while the drives ran, at its controller period's time.
    rpdo = sorted(t for t, iface, cid, dlc in frames if iface == "vcan1" and cid in (0x202, 0x203))
    points = [(used - t0, target - capture) for capture, used, target in loop_latency.frame_times(log, rpdo)
              if target is not None]

    x = lambda s: LEFT + (W - LEFT - RIGHT) * s / seconds  # noqa: E731
    out = ['<svg xmlns="http://www.w3.org/2000/svg" width="%d" height="%d" font-family="sans-serif" font-size="11">'
           % (W, H), '<rect width="100%" height="100%" fill="white"/>']

    def panel(top, title, ymax, unit, series):
        y = lambda v: top + PANEL - PANEL * min(v, ymax) / ymax  # noqa: E731
        out.append('<text x="%d" y="%d" font-size="13">%s</text>' % (LEFT, top - 8, title))
        out.append('<rect x="%d" y="%d" width="%d" height="%d" fill="none" stroke="#888"/>' %
                   (LEFT, top, W - LEFT - RIGHT, PANEL))
        for k in range(5):
            v = ymax * k / 4
            out.append('<text x="%d" y="%.0f" text-anchor="end">%g%s</text>' % (LEFT - 4, y(v) + 4, v, unit))
        for k in range(0, seconds, 20):
            out.append('<text x="%.0f" y="%d" text-anchor="middle">%d s</text>' % (x(k), top + PANEL + 14, k))
        for i, (values, colour, label, dots) in enumerate(series):
            if dots:
                out.extend('<circle cx="%.1f" cy="%.1f" r="2.5" fill="%s"/>' % (x(s), y(v), colour) for s, v in values)
            else:
                path = " ".join("%.1f,%.1f" % (x(s + 0.5), y(v)) for s, v in enumerate(values))
                out.append('<polyline points="%s" fill="none" stroke="%s" stroke-width="1.2"/>' % (path, colour))
            out.append('<text x="%d" y="%d" fill="%s">%s</text>' % (LEFT + 300, top + 14 + 13 * i, colour, label))

    top = TOP
    panel(top, "frames per second on each bus", 120, "", [(counts.get((i, k), [0] * seconds), c, label, False)
                                                          for i, k, c, label in SERIES])
    top += PANEL + GAP
    panel(top, "bus load, % of 1 Mbit/s", 3, " %",
          [([b / 1e4 for b in bits["vcan0"]], "#1f77b4", "vcan0: the visco protocol", False),
           ([b / 1e4 for b in bits["vcan1"]], "#2ca02c", "vcan1: CiA 402 (SYNC, PDOs, heartbeats, SDO)", False)])
    top += PANEL + GAP
    median = sorted(p[1] for p in points)[len(points) // 2] if points else 0.0
    panel(top, "a camera frame (its V4L2 capture) -> the drives' target velocity, s: %d frames, p50 %.2f s" %
          (len(points), median), 5, " s", [(points, "#d62728", "at the time the controller used the frame", True)])
    out.append("</svg>")
    with open(svg, "w") as f:
        f.write("\n".join(out) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

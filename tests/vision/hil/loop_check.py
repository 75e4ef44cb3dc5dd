#!/usr/bin/env python3
"""Checks and figures of the closed loop through V4L2 (tests/vision/hil/run_in_vm.sh, step 6) from the run's LCM log.

    loop_check.py RUN_DIR

RUN_DIR holds what the demo wrote (summary.json, camera.json, run.lcmlog). The log and its messages are read with
tests/replay/logtool.py (the lcm-gen layouts, big-endian): it shares no code with visco.

Checks: the goal was reached; every image vision processed, from the world's first frame on, is one the rendered
camera wrote, byte for byte (by the pixel digest vision recorded against the one the world recorded when it wrote the
frame to vivid's output); vision's robot estimate of each such frame is within 10 cm of where the simulated robot
truly was when the frame was rendered (it is within 1.5 cm standing and sliding in contact, up to 5 cm moving freely:
one tag 12 m away, about 2 cm a pixel). Writes RUN_DIR/replay_to: empty, or the log time up to which `visco replay
--check` can compare when the logger lost an image vision processed. Prints the figures: render time per frame, frames written and published per second,
image_t.seq gaps (dropped by the driver or skipped as stale; the frames --max-fps held back are not gaps: checked),
vision's time per frame, and the
latency from the render to the first command after vision's estimate of that frame.
"""
import bisect
import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "replay"))
import logtool  # noqa: E402  (lcm-logger's format, standard library only)


def quantiles(values):
    values = sorted(values)
    pick = lambda p: values[min(len(values) - 1, int(p * (len(values) - 1) + 0.5))]
    return "p50 %.0f, p95 %.0f, max %.0f" % (pick(0.5), pick(0.95), values[-1]) if values else "none"


def main():
    run_dir = sys.argv[1]
    summary = json.load(open(run_dir + "/summary.json"))
    run = summary["runs"][0]
    camera = json.load(open(run_dir + "/camera.json"))

    first_ts = None
    image_ts = {}  # image_t.seq -> log time
    detection_ts = {}  # frame seq -> log time of vision's detections
    written = {}  # pixel digest -> (render utime, written utime)
    written_seqs = set()
    images, detections, estimates, commands, truth = [], {}, [], [], []
    for _, ts, ch, d in logtool.read(run_dir + "/run.lcmlog"):
        first_ts = ts if first_ts is None else first_ts
        r = logtool.Message(d)
        if ch == "VISCO_SIM_FRAME":
            r.take("q")
            r.string(), r.string()
            rec = json.loads(r.string())
            written[rec["pixel_digest"]] = (rec["render_utime"], rec["written_utime"])
            written_seqs.add(rec["seq"])
        elif ch == "VISCO_CAMERA_IMAGE":
            utime, seq = r.take("qq")
            images.append((ts, utime, seq))
            image_ts[seq] = ts
        elif ch == "VISCO_TAG_DETECTIONS":
            _utime, _frame_utime, frame_seq = r.take("qqq")
            r.string()
            processing_s = r.take("d")
            detections[frame_seq] = (r.take("q"), processing_s)
            detection_ts[frame_seq] = ts
        elif ch == "VISCO_ROBOT_ESTIMATE":
            _utime, frame_seq, valid, x, y = r.take("qqbdd")
            estimates.append((ts, frame_seq, valid, x, y))
        elif ch == "VISCO_COMMAND":
            utime, _node, _session, _seq, vx, vy = r.take("qiiidd")
            commands.append((ts, utime, vx, vy))
        elif ch == "VISCO_SIM_TRUTH":
            utime, _node, x, y = r.take("qidd")
            truth.append((utime, x, y))
    truth.sort()

    ok = True

    def check(cond, what):
        nonlocal ok
        print(("ok: " if cond else "FAILED: ") + what)
        ok = ok and cond

    check(run["success"], "goal reached (%s; final error %s m)" % (run["reason"], run["goal_error_m"]))

    # Every processed image was written by the rendered camera (byte-exact through the loop). Before the world's
    # first frame reaches the output, vivid's capture shows its test pattern.
    # The records travel over UDP like every message: one the logger lost under load leaves its frame unknown, which
    # is allowed only as many times as records are missing from the run of frame numbers (and said).
    digests = [detections[s][0] for _, _, s in images if s in detections]
    first = next((k for k, d in enumerate(digests) if d in written), len(digests))
    foreign = len(set(d for d in digests[first:] if d not in written))
    lost = sorted(set(range(min(written_seqs), max(written_seqs) + 1)) - written_seqs) if written_seqs else []
    check(len(digests) - first >= 5 and foreign <= len(lost),
          "%d of %d images processed by vision, every one from the world's first on a frame it rendered, byte for "
          "byte (%d unknown, %d frame records missing from the log: %s; %d of vivid's test pattern before the first)"
          % (len(digests), len(images), foreign, len(lost), lost, first))

    # Vision's estimate against the truth at the frame's render time.
    errors = []
    for ts, seq, valid, x, y in estimates:
        if seq not in detections or detections[seq][0] not in written or not valid:
            continue
        render_utime = written[detections[seq][0]][0]
        k = bisect.bisect_right(truth, (render_utime, float("inf"), 0)) - 1
        if k >= 0:
            errors.append(((x - truth[k][1]) ** 2 + (y - truth[k][2]) ** 2) ** 0.5)
    check(len(errors) >= 5 and max(errors) < 0.1,
          "vision's robot estimate of %d frames within 10 cm of the truth at their render (max %.1f mm)"
          % (len(errors), 1e3 * max(errors or [0])))

    # Messages travel over UDP: under load the logger can lose one. An image vision processed but the log lacks
    # leaves the replay's tracker one frame short from there on: the replay is checked up to it (REPLAY_TO, seconds
    # after the log's first event, for `visco replay --to`), and the loss said.
    lost_images = sorted(seq for seq in detections if seq not in image_ts)
    with open(run_dir + "/replay_to", "w") as f:
        before = [ts for seq, ts in image_ts.items() if lost_images and seq < lost_images[0]]
        if before:
            f.write("%.6f\n" % ((max(before) - first_ts) / 1e6 + 1e-3))  # up to the last image before the loss
    print("figure: images vision processed that the logger lost: %s%s"
          % (lost_images, " (the replay is checked up to the first)" if lost_images else ""))

    # Figures.
    def rate(times):
        times = sorted(times)
        return (len(times) - 1) / ((times[-1] - times[0]) / 1e6) if len(times) > 2 else 0.0

    gaps = sum(b[2] - a[2] - 1 for a, b in zip(images, images[1:]) if b[2] > a[2] + 1)
    cap = run.get("capture") or {}
    print("figure: render %.0f ms per frame (mean, the first included: the table and obstacles once)"
          % camera["mean_render_ms"])
    print("figure: frames written by the world %d (%.2f /s); published by visco capture %d (%.2f /s), %s held back by "
          "--max-fps; image_t.seq gaps %d frames (the capture counted %s dropped by the driver, %s skipped as "
          "stale)" % (len(written), rate([w[1] for w in written.values()]), len(images), rate([i[1] for i in images]),
                       cap.get("held_back"), gaps, cap.get("dropped"), cap.get("skipped")))
    # The frames --max-fps holds back are not lost: image_t.seq counts published frames, so vision keeps its
    # tracking prediction. The gaps are the frames the driver dropped or the capture skipped, and images the logger
    # lost (UDP; allowed up to a tenth of the published frames); counted as gaps, the held-back frames would exceed it.
    held_back = cap.get("held_back") or 0
    lost_frames = (cap.get("dropped") or 0) + (cap.get("skipped") or 0) + (cap.get("bad_frames") or 0)
    check(gaps <= lost_frames + max(5, len(images) // 10),
          "image_t.seq gaps (%d) are frames lost (%d dropped, skipped or bad), not the %d held back by --max-fps"
          % (gaps, lost_frames, held_back))
    print("figure: vision, frame arrival to publication, %d frames: %s ms"
          % (len(detections), quantiles([1e3 * p for _, p in detections.values()])))
    latencies = []
    for ts, seq, valid, _x, _y in estimates:
        if seq not in detections or detections[seq][0] not in written or not valid:
            continue
        after = next((c for c in commands if c[0] >= ts), None)
        if after is not None:
            latencies.append((after[1] - written[detections[seq][0]][0]) / 1e3)
    print("figure: render to the first command after vision's estimate of that frame, %d frames: %s ms"
          % (len(latencies), quantiles(latencies)))
    check(len(latencies) > 0, "latency measured")
    print("figure: the run %.1f s (motion %.1f s); capture summary %s" % (run["time_s"], run["motion_s"] or 0,
                                                                          json.dumps(cap)))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

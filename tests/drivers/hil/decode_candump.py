#!/usr/bin/python3 -S
"""Decodes a `candump -L vcan0,0:0,#FFFFFFFF` log of a HIL run with the DBC file (drivers/visco.dbc; node N's frames use
node 1's layouts at base + N) and checks the bus record on its own, with a model of the driver's acceptance rule
(drivers/README.md, "Sessions") written from the README alone:

- every frame is one the DBC describes;
- the driver's own frames are always valid: session frames (plain CRC) and status triples (status, position, force
  with the same counter, each with the CRC over the session nonce and the counter, the counter +1 per update); a
  driver frame that fails is a FAIL, not an "injected" fault;
- every command frame is judged as the driver must judge it (the session's tag and CRC over the nonce and the
  counter reconstructed 1..8 ahead of the last accepted command); the driver's statuses may only acknowledge
  commands the rule accepted, and must acknowledge those; a command frame identical to one of an earlier session
  (a replay) is never accepted, unless the two sessions share their tag byte (the 8-bit CRC then passes 1 frame in
  256: the protocol cannot tell them apart) and are not within the last RECENT_TAGS sessions of one driver run, whose
  tags the driver never reuses (checked too: a boot-up heartbeat starts a run);
- the safety story from the bus alone: every watchdog EMCY comes no earlier than the watchdog period after that
  node's last accepted command and no later than the period plus --slack-ms, and is followed by a zero-velocity
  STOPPED status.

usage: decode_candump.py DBC LOG --watchdog-ms NODE=MS [NODE=MS ...] [--slack-ms MS] [--expect-faults]
       decode_candump.py --self-test DBC
"""
import argparse
import re
import struct
import sys

ERR_FLAG = 0x20000000
WINDOW = 8         # README: a command is accepted 1..8 ahead of the last accepted one
RECENT_TAGS = 64   # README: a new session's tag byte differs from those of the driver's last 64 sessions
STATUS_WINDOW = 127


def parse_dbc(path):
    messages = {}
    current = None
    values = {}
    for line in open(path, encoding="utf-8"):
        m = re.match(r"^BO_ (\d+) (\w+): (\d+) (\w+)", line)
        if m:
            current = {"id": int(m.group(1)), "name": m.group(2), "dlc": int(m.group(3)), "signals": {}}
            messages[current["id"]] = current
            continue
        m = re.match(r"^ SG_ (\w+) : (\d+)\|(\d+)@([01])([+-]) \(([^,]+),([^)]+)\)", line)
        if m and current is not None:
            if m.group(4) != "1":
                raise SystemExit("only Intel byte order is supported")
            current["signals"][m.group(1)] = (int(m.group(2)), int(m.group(3)), m.group(5) == "-",
                                             float(m.group(6)), float(m.group(7)))
            continue
        m = re.match(r"^VAL_ (\d+) (\w+) (.*);", line)
        if m:
            pairs = re.findall(r'(\d+) "([^"]*)"', m.group(3))
            values[(int(m.group(1)), m.group(2))] = {int(k): v for k, v in pairs}
        if not line.strip():
            current = None
    return messages, values


def signal(sig, data):
    start, length, signed, scale, offset = sig
    raw = 0
    for i in range(length):
        bit = start + i
        if data[bit // 8] >> (bit % 8) & 1:
            raw |= 1 << i
    if signed and raw >> (length - 1) & 1:
        raw -= 1 << length
    return raw * scale + offset, raw


def crc8_j1850(data):
    crc = 0xFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc ^ 0xFF


def plain_crc(can_id, data):
    return crc8_j1850(struct.pack("<H", can_id & 0x7FF) + bytes(data[:7]))


def fmix32(h):
    """murmur3's 32-bit finaliser."""
    h = ((h ^ (h >> 16)) * 0x85EBCA6B) & 0xFFFFFFFF
    h = ((h ^ (h >> 13)) * 0xC2B2AE35) & 0xFFFFFFFF
    return h ^ (h >> 16)


def session_crc(can_id, session, counter, data):
    """README: CRC-8/SAE-J1850 over the id (2 bytes LE), the session key fmix32(nonce ^ fmix32(counter ^ fmix32(id)))
    (4 bytes LE), the counter's bits 8..31 (3 bytes LE) and bytes 0..6."""
    key = fmix32((session ^ fmix32((counter ^ fmix32(can_id & 0x7FF)) & 0xFFFFFFFF)) & 0xFFFFFFFF)
    return crc8_j1850(struct.pack("<HI", can_id & 0x7FF, key) +
                      ((counter >> 8) & 0xFFFFFF).to_bytes(3, "little") + bytes(data[:7]))


def judge_command(can_id, data, session, last, last_wrap=None):
    """The README's acceptance rule: (verdict, counter). `last_wrap`: low byte -> the last accepted frame with it."""
    if data[6] != session & 0xFF:
        return "wrong-session", None
    k = (data[0] - last) & 0xFF
    ahead = last + (k if k else 256)
    if ahead - last <= WINDOW and session_crc(can_id, session, ahead, data) == data[7]:
        if last_wrap is not None and last_wrap.get(data[0]) == bytes(data[:8]):
            return "repeat (replay of the last wrap)", ahead
        return "accepted", ahead
    behind = ahead - 256
    if session_crc(can_id, session, behind, data) == data[7]:
        return "stale", behind
    if ahead - last > WINDOW and session_crc(can_id, session, ahead, data) == data[7]:
        return "ahead", ahead
    return "bad-checksum", None


class Node:
    def __init__(self):
        self.session = None
        self.sessions = 0
        self.epoch = 0
        self.status_counter = None
        self.last = 0                 # the model's last accepted command counter in the session
        self.recent = [0]             # the last 255 accepted counters (0: none yet)
        self.acked = 0                # the newest counter a status acknowledged
        self.unacked = None           # (time, low byte) of the newest accepted command not yet acknowledged
        self.last_accepted_t = None
        self.triple = None            # (counter, next expected kind "Position" / "Force")
        self.replay_triple = None     # the same for a replayed (injected) copy of an earlier status triple
        self.stop_pending = None      # time of a watchdog EMCY not yet followed by a zero-velocity STOPPED status
        self.frames_of_session = {}   # command payload -> session it was first seen in
        self.run = 0                  # driver runs (boot-ups) seen
        self.run_sessions = []        # this run's sessions, oldest first
        self.session_place = {}       # nonce -> (run, index in that run)
        self.last_wrap = {}           # low byte -> the last accepted command frame with it, in the session


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("dbc")
    parser.add_argument("log", nargs="?")
    parser.add_argument("--watchdog-ms", nargs="+", default=[])
    parser.add_argument("--slack-ms", type=float, default=200.0)
    parser.add_argument("--expect-faults", action="store_true")
    parser.add_argument("--self-test", action="store_true")
    args = parser.parse_args()
    if args.self_test:
        return self_test(args.dbc)
    messages, values = parse_dbc(args.dbc)
    watchdog = {int(k): float(v) / 1000.0 for k, v in (w.split("=") for w in args.watchdog_ms)}
    return check(messages, values, open(args.log, encoding="utf-8", errors="replace"), watchdog,
                 args.slack_ms / 1000.0, args.expect_faults)


def check(messages, values, lines, watchdog, slack, expect_faults, quiet=False):
    lines = list(lines)  # (a file or a list: looked ahead into)
    problems = []
    counts = {}
    verdicts = {}
    errors = 0
    nodes = {}
    watchdog_emcy = []        # (time, node, seconds since the last accepted command)
    stopped_after = []
    emcy_names = {}
    frames = 0
    replays = 0               # command frames identical to one of an earlier session
    replays_accepted = 0
    replays_colliding = 0     # accepted replays the protocol cannot reject (same tag, CRC collision, sessions apart)
    acked = 0
    unacked = 0
    status_gaps = 0

    def node_of(n):
        return nodes.setdefault(n, Node())

    def lookahead(index, wanted_id, reach=60):
        """Data of the next frame with `wanted_id` within `reach` lines after `index`, or None."""
        for later in lines[index + 1:index + 1 + reach]:
            mm = re.match(r"^\(\S+\) \w+ ([0-9A-Fa-f]{3})#([0-9A-Fa-f]*)", later)
            if mm and int(mm.group(1), 16) == wanted_id:
                return bytes.fromhex(mm.group(2)) + bytes(8)
        return None

    last_time = 0.0
    for index, line in enumerate(lines):
        m = re.match(r"^\((\d+\.\d+)\) (\w+) ([0-9A-Fa-f]+)#([0-9A-Fa-f]*)", line)
        if not m:
            # candump -d: its own socket's queue overflowed, frames on the bus are missing from the log (every
            # check after that point would judge a hole, not the driver).
            drop = re.match(r"^DROPCOUNT: dropped (\d+) CAN frames?", line)
            if drop:
                problems.append("candump itself dropped %s frames after %.3f: the log has holes (a larger -r buffer)"
                                % (drop.group(1), last_time))
            continue
        last_time = float(m.group(1))
        frames += 1
        t = float(m.group(1))
        can_id = int(m.group(3), 16)
        data = bytes.fromhex(m.group(4)) + bytes(8)
        dlc = len(m.group(4)) // 2
        if can_id & ERR_FLAG:
            errors += 1
            continue
        if len(m.group(3)) > 3:
            problems.append("extended frame %s on the bus" % m.group(3))
            continue
        n = can_id & 0x7F
        base = can_id & 0x780
        key = 0 if can_id == 0 else base + 1
        message = messages.get(key)
        if message is None or (can_id != 0 and n == 0):
            problems.append("frame %03X is not described by the DBC" % can_id)
            continue
        name = message["name"].split("_")[0]
        counts[name] = counts.get(name, 0) + 1
        sigs = message["signals"]
        if name == "Command":
            node = node_of(n)
            if dlc != 8 or data[1] & 0xF8 or signal(sigs["VelocityX"], data)[1] == -32768 or \
                    signal(sigs["VelocityY"], data)[1] == -32768:
                verdicts["malformed (length, reserved bits)"] = verdicts.get("malformed (length, reserved bits)", 0) + 1
                continue
            if node.session is None:
                verdicts["before any session"] = verdicts.get("before any session", 0) + 1
                continue
            verdict, counter = judge_command(can_id, data, node.session, node.last, node.last_wrap)
            verdicts[verdict] = verdicts.get(verdict, 0) + 1
            payload = bytes(data[:8])
            first_session = node.frames_of_session.setdefault(payload, node.session)
            replay = first_session != node.session
            replays += replay
            if verdict == "accepted" and replay:
                run, index = node.session_place.get(first_session, (None, None))
                recent = run == node.run and len(node.run_sessions) - 1 - index <= RECENT_TAGS
                if first_session & 0xFF == node.session & 0xFF and not recent:
                    replays_colliding += 1
                else:
                    replays_accepted += 1
            if verdict == "accepted":
                node.last = counter
                node.last_wrap[data[0]] = bytes(data[:8])
                # The last 255 (their low bytes, which statuses carry, stay unique): a driver that was not scheduled
                # for a while reads its backlog in order and acknowledges commands hundreds of ms after the bus saw
                # them (0.4 s, about 200 commands, on a loaded emulated CPU).
                node.recent = (node.recent + [counter])[-255:]
                node.unacked = (t, counter & 0xFF)
                node.last_accepted_t = t
            continue
        if name == "Session":
            if dlc != 8 or plain_crc(can_id, data) != data[7]:
                problems.append("node %d: session frame at %.3f with a bad CRC or length (the driver's own frame)" %
                                (n, t))
                continue
            node = node_of(n)
            nonce = struct.unpack("<I", data[:4])[0]
            if nonce != node.session:
                if node.unacked is not None and node.unacked[0] < t - 0.05:
                    unacked += 1
                for back, earlier in enumerate(reversed(node.run_sessions[-RECENT_TAGS:]), 1):
                    if earlier & 0xFF == nonce & 0xFF:
                        problems.append("node %d: session %08X at %.3f reuses the tag byte of the session %d before "
                                        "it in the same driver run (%08X)" % (n, nonce, t, back, earlier))
                        break
                node.session_place[nonce] = (node.run, len(node.run_sessions))
                node.run_sessions.append(nonce)
                node.session = nonce
                node.sessions += 1
                node.epoch = int.from_bytes(data[4:7], "little")
                node.status_counter = None
                node.last = 0
                node.recent = [0]
                node.acked = 0
                node.unacked = None
                node.last_wrap = {}
                node.triple = None
            continue
        if name in ("Status", "Position", "Force"):
            node = node_of(n)
            if node.session is None:
                continue  # before the first session frame of a driver seen in this log
            if dlc != 8:
                problems.append("node %d: %s frame with %d bytes at %.3f" % (n, name, dlc, t))
                continue
            if name == "Status":
                low = data[0]
                if node.status_counter is None:
                    candidates = [(node.epoch << 8) | low, ((node.epoch + 1) << 8) | low]
                else:
                    k = (low - node.status_counter) & 0xFF
                    candidates = [node.status_counter + (k if k else 256)]
                # A copy of an earlier status of this session (a replay) has its counter 1..256 behind.
                behind = [candidates[0] - 256] if node.status_counter is not None else []
                # Every reading the CRC passes: with the session key a wrong one passes by chance (1 in 256), so the
                # triple's next frame (the position frame, which the driver sends right after) decides.
                passing = [c for c in candidates + behind if session_crc(can_id, node.session, c, data) == data[7]]
                if len(passing) > 1:
                    position = lookahead(index, 0x280 + n)
                    if position is not None:
                        confirmed = [c for c in passing if session_crc(0x280 + n, node.session, c, position) ==
                                     position[7]]
                        passing = confirmed or passing
                if passing and passing[0] in behind:
                    # Injected (a replay), not the driver's.
                    verdicts["replayed status (injected)"] = verdicts.get("replayed status (injected)", 0) + 1
                    node.replay_triple = ([passing[0]], "Position")
                    continue
                if node.triple is not None:
                    problems.append("node %d: incomplete status triple before %.3f" % (n, t))
                counter = passing[0] if passing else None
                if counter is None:
                    problems.append("node %d: status frame at %.3f fails the CRC for its session (the driver's own "
                                    "frame)" % (n, t))
                    node.triple = None
                    continue
                if node.status_counter is not None:
                    if counter - node.status_counter > STATUS_WINDOW:
                        problems.append("node %d: status counter jumped from %d to %d at %.3f" %
                                        (n, node.status_counter, counter, t))
                    status_gaps += counter - node.status_counter - 1
                node.status_counter = counter
                node.triple = (passing, "Position")
                decoded = {s: signal(sig, data)[0] for s, sig in sigs.items()}
                command_seq = int(decoded["CommandSeq"])
                matches = [c for c in node.recent if c & 0xFF == command_seq]
                if not matches:
                    problems.append("node %d: status at %.3f acknowledges command %d, which the acceptance rule did not "
                                    "accept in this session" % (n, t, command_seq))
                elif max(matches) < node.acked:
                    problems.append("node %d: status at %.3f acknowledges command %d after %d: the driver took a stale "
                                    "command" % (n, t, max(matches), node.acked))
                else:
                    node.acked = max(matches)
                if node.unacked is not None and command_seq == node.unacked[1]:
                    node.unacked = None
                    acked += 1
                if node.stop_pending is not None and decoded["VelocityX"] == 0 and decoded["VelocityY"] == 0 and \
                        int(decoded["State"]) == 3:
                    stopped_after.append(t - node.stop_pending)
                    node.stop_pending = None
                continue

            def fits(triple):
                """The triple's candidate counters this frame verifies with (empty: it does not belong)."""
                if triple is None or triple[1] != name:
                    return []
                return [c for c in triple[0]
                        if data[0] == c & 0xFF and session_crc(can_id, node.session, c, data) == data[7]]

            ok = fits(node.triple)
            replay_ok = fits(node.replay_triple) if not ok else []
            if ok:
                node.status_counter = ok[0]
                node.triple = (ok, "Force") if name == "Position" else None
            elif replay_ok:
                node.replay_triple = (replay_ok, "Force") if name == "Position" else None
            else:
                problems.append("node %d: %s frame at %.3f out of its triple (or failing its CRC)" % (n, name, t))
                node.triple = None
            continue
        if dlc != message["dlc"]:
            problems.append("%s frame %03X with %d bytes (DBC: %d)" % (name, can_id, dlc, message["dlc"]))
            continue
        decoded = {s: signal(sig, data)[0] for s, sig in sigs.items()}
        if name == "Emcy":
            code = int(decoded["ErrorCode"])
            label = values.get((key, "ErrorCode"), {}).get(code, "0x%04X" % code)
            emcy_names[label] = emcy_names.get(label, 0) + 1
            if code == 0x8250:
                node = node_of(n)
                since = t - (node.last_accepted_t if node.last_accepted_t is not None else t)
                watchdog_emcy.append((t, n, since))
                node.stop_pending = t
        elif name == "Heartbeat" and int(decoded["NmtState"]) == 0:
            node = node_of(n)
            node.status_counter = None  # a boot-up: the counter may restart; the next session frame gives it
            node.triple = None
            node.run += 1  # a new driver run: it knows nothing of the tags used before
            node.run_sessions = []

    for n, node in nodes.items():
        if node.unacked is not None:
            unacked += 1
    out = [] if quiet else None
    report = out.append if quiet else print
    report("candump: %d frames, %d error frames; per message %s; commands judged by the acceptance rule %s; "
           "replays of an earlier session's command frames %d (accepted %d; %d more where an earlier run's session had "
           "the same tag and the CRC collided); EMCY %s" %
           (frames, errors, counts, verdicts, replays, replays_accepted, replays_colliding, emcy_names))
    report("  sessions per node %s; accepted commands acknowledged %d, never acknowledged %d; status counter gaps %d" %
           ({n: node.sessions for n, node in nodes.items() if node.sessions}, acked, unacked, status_gaps))
    for t, n, since in watchdog_emcy:
        period = watchdog.get(n)
        report("  node %d: watchdog EMCY %.1f ms after its last accepted command (watchdog %s ms)" %
               (n, since * 1e3, "?" if period is None else "%.0f" % (period * 1e3)))
        if period is not None and since < period * 0.98:
            problems.append("node %d: watchdog EMCY only %.1f ms after an accepted command" % (n, since * 1e3))
        if period is not None and since > period + slack:
            problems.append("node %d: watchdog EMCY %.1f ms after the last accepted command (watchdog %.0f ms + %.0f "
                            "ms slack)" % (n, since * 1e3, period * 1e3, slack * 1e3))
    for n, node in nodes.items():
        if node.stop_pending is not None:
            problems.append("node %d: no zero-velocity STOPPED status after the watchdog EMCY at %.3f" %
                            (n, node.stop_pending))
    if stopped_after:
        report("  zero-velocity STOPPED status at most %.1f ms after each watchdog EMCY" % (max(stopped_after) * 1e3))
    if replays_accepted:
        problems.append("%d command frames of an earlier session were accepted by the rule" % replays_accepted)
    if unacked > max(1, verdicts.get("accepted", 0) // 100):
        problems.append("%d accepted commands were never acknowledged by a status" % unacked)
    for name in ("Command", "Status", "Position", "Force", "Session", "Heartbeat", "Emcy"):
        if counts.get(name, 0) == 0:
            problems.append("no %s frame in the log" % name)
    if expect_faults:
        if not watchdog_emcy:
            problems.append("no watchdog EMCY in the log")
        if verdicts.get("bad-checksum", 0) + verdicts.get("malformed (length, reserved bits)", 0) == 0:
            problems.append("no injected malformed command in the log")
        if verdicts.get("stale", 0) == 0:
            problems.append("no stale (replayed) command in the log")
        if replays < 100:
            problems.append("no replay of an earlier session's command frames in the log (%d)" % replays)
        if verdicts.get("replayed status (injected)", 0) == 0:
            problems.append("no replayed status frame in the log")
        if errors == 0:
            problems.append("no error frame in the log")
    for p in problems[:50]:
        report("FAIL " + p)
    if len(problems) > 50:
        report("FAIL ... and %d more problems (the first 50 are listed)" % (len(problems) - 50))
    if quiet:
        return problems
    return 1 if problems else 0


def self_test(dbc):
    """The checker must fail on what it is meant to catch: a driver that accepts a replayed command (its status
    acknowledges a frame the rule rejects), a driver status with a bad CRC, a watchdog EMCY that comes too late."""
    messages, values = parse_dbc(dbc)
    session = 0x1234ABCD

    def frame(t, can_id, data):
        return "(%.6f) vcan0 %03X#%s\n" % (t, can_id, bytes(data).hex().upper())

    def session_frame(t, nonce, epoch):
        d = bytearray(struct.pack("<I", nonce) + epoch.to_bytes(3, "little") + b"\0")
        d[7] = plain_crc(0x481, d)
        return frame(t, 0x481, d)

    def command(t, counter, nonce, vx=0, reset=False):
        d = bytearray(struct.pack("<BBhhB", counter & 0xFF, 2 if reset else 0, vx, 0, nonce & 0xFF) + b"\0")
        d[7] = session_crc(0x201, nonce, counter, d)
        return frame(t, 0x201, d)

    def triple(t, counter, command_seq, state=1, vx=0, bad=False):
        out = []
        for can_id, payload in ((0x181, struct.pack("<BBhhB", counter & 0xFF, command_seq, vx, 0, state)),
                                (0x281, struct.pack("<B", counter & 0xFF) + bytes(6)),
                                (0x381, struct.pack("<B", counter & 0xFF) + bytes(6))):
            d = bytearray(payload + b"\0")
            d[7] = session_crc(can_id, session, counter, d) ^ (1 if bad else 0)
            out.append(frame(t, can_id, d))
        return out

    def emcy(t, code):
        return frame(t, 0x081, struct.pack("<HBBHBB", code, 0x11, 4, 1, 1, 0))

    def base():
        log = [frame(0.0, 0x701, b"\0"), session_frame(0.001, session, 0)]
        log += triple(0.002, 1, 0, state=0)
        log.append(command(0.010, 1, session, reset=True))
        log += triple(0.011, 2, 1)
        log.append(command(0.012, 2, session, vx=1000))
        log += triple(0.013, 3, 2, state=2, vx=1000)
        log.append(frame(0.05, 0x701, b"\5"))
        return log

    def tail(counter):
        return [emcy(0.313, 0x8250)] + triple(0.314, counter, 2, state=3)

    # A second session with the first one's tag byte whose CRC collides with it for the command (2, vx 1000) of
    # base(): that frame, replayed, is valid in both sessions.
    replayed = command(0.012, 2, session, vx=1000)
    twin = next(session & 0xFF | k << 8 for k in range(1, 1 << 24)
                if command(0.012, 2, session & 0xFF | k << 8, vx=1000) == replayed)

    def replay_into(twin_session, boot_up):
        log = base() + tail(4) + ([frame(0.400, 0x701, b"\0")] if boot_up else [])
        return log + [session_frame(0.401, twin_session, 1), command(0.402, 1, twin_session, reset=True),
                      replayed.replace("(0.012000)", "(0.403000)")]

    cases = {
        "clean log": (base() + tail(4), None),
        "a session reusing the tag of a recent one of the same run": (
            base() + tail(4) + [session_frame(0.400, session ^ 0x100, 1)], "reuses the tag byte"),
        "a replay the protocol cannot reject (same tag, CRC collision), the sessions in two runs": (
            replay_into(twin, True), None),
        "the same replay within one run": (replay_into(twin, False), "were accepted by the rule"),
        "a status acknowledges a command of another session": (
            base() + [command(0.100, 3, session ^ 0x55)] + triple(0.101, 4, 3, state=2, vx=1000) + tail(5),
            "did not accept"),
        "a status acknowledges a replayed (stale) command": (
            base() + [command(0.100, 1, session)] + triple(0.101, 4, 1) + tail(5), "stale"),
        "a driver status with a bad CRC": (base() + triple(0.100, 4, 2, state=2, bad=True) + tail(5), "fails the CRC"),
        "a watchdog EMCY far too late": (
            base() + [emcy(0.900, 0x8250)] + triple(0.901, 4, 2, state=3), "slack"),
        "a watchdog EMCY too early": (base() + [emcy(0.100, 0x8250)] + triple(0.101, 4, 2, state=3), "only"),
        "an incomplete status triple": (base() + triple(0.100, 4, 2)[:1] + triple(0.101, 5, 2) + tail(6),
                                        "incomplete"),
        "candump's own drops": (base() + ["DROPCOUNT: dropped 7 CAN frames on 'vcan0' socket (total drops 7)\n"] +
                                tail(4), "candump itself dropped 7 frames after 0.050"),
        "a replayed status triple is not the driver's fault": (base() + triple(0.014, 2, 1) + tail(4), None),
        "no STOPPED status after a watchdog EMCY": (base() + [emcy(0.313, 0x8250)], "no zero-velocity"),
    }
    failures = 0
    for what, (log, expected) in cases.items():
        problems = check(messages, values, log, {1: 0.3}, 0.2, False, quiet=True)
        ok = not problems if expected is None else any(expected in p for p in problems)
        failures += not ok
        print("%s %s: %s" % ("ok  " if ok else "FAIL", what, "; ".join(problems) if problems else "no problem found"))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

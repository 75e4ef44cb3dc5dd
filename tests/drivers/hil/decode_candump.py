#!/usr/bin/python3 -S
"""Decodes a `candump -L vcan0,0:0,#FFFFFFFF` log of a HIL run with the DBC file (drivers/visco.dbc; node N's frames use node 1's
layouts at base + N) and checks the bus record on its own: every frame is one the DBC describes, every checksummed
frame that is not an injected fault has a valid CRC, every status triple is consistent, and the safety story can be
read from the bus alone — after every watchdog EMCY the robot's reported velocity is zero, and the EMCY came no
earlier than the watchdog period after that node's last valid command.

usage: decode_candump.py DBC LOG --watchdog-ms NODE=MS [NODE=MS ...] [--expect-faults]
"""
import argparse
import re
import sys

ERR_FLAG = 0x20000000


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


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("dbc")
    parser.add_argument("log")
    parser.add_argument("--watchdog-ms", nargs="+", default=[])
    parser.add_argument("--expect-faults", action="store_true")
    args = parser.parse_args()
    messages, values = parse_dbc(args.dbc)
    watchdog = {int(k): float(v) / 1000.0 for k, v in (w.split("=") for w in args.watchdog_ms)}

    problems = []
    counts = {}
    bad_crc = {}
    errors = 0
    last_valid_command = {}   # node -> time of its last valid command
    watchdog_emcy = []        # (time, node, seconds since the last valid command)
    stop_pending = {}         # node -> time of a watchdog EMCY not yet followed by a zero-velocity status
    stopped_after = []
    emcy_names = {}
    frames = 0
    for line in open(args.log, encoding="utf-8", errors="replace"):
        m = re.match(r"^\((\d+\.\d+)\) (\w+) ([0-9A-Fa-f]+)#([0-9A-Fa-f]*)", line)
        if not m:
            continue
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
        node = can_id & 0x7F
        base = can_id & 0x780
        key = 0 if can_id == 0 else base + 1
        message = messages.get(key)
        if message is None or (can_id != 0 and node == 0):
            problems.append("frame %03X is not described by the DBC" % can_id)
            continue
        name = message["name"].split("_")[0]
        counts[name] = counts.get(name, 0) + 1
        sigs = message["signals"]
        if "Crc" in sigs:
            ok = dlc == message["dlc"] and crc8_j1850(bytes([can_id & 0xFF, can_id >> 8]) + data[:7]) == data[7]
            if not ok:
                bad_crc[name] = bad_crc.get(name, 0) + 1
                continue
        elif dlc != message["dlc"]:
            problems.append("%s frame %03X with %d bytes (DBC: %d)" % (name, can_id, dlc, message["dlc"]))
            continue
        decoded = {s: signal(sig, data)[0] for s, sig in sigs.items()}
        if name == "Command":
            last_valid_command[node] = t
        elif name == "Emcy":
            code = int(decoded["ErrorCode"])
            label = values.get((key, "ErrorCode"), {}).get(code, "0x%04X" % code)
            emcy_names[label] = emcy_names.get(label, 0) + 1
            if code == 0x8250:
                since = t - last_valid_command.get(node, t)
                watchdog_emcy.append((t, node, since))
                stop_pending[node] = t
        elif name == "Status":
            if node in stop_pending and decoded["VelocityX"] == 0 and decoded["VelocityY"] == 0 and \
                    int(decoded["State"]) == 3:
                stopped_after.append(t - stop_pending.pop(node))

    print("candump: %d frames, %d error frames; per message %s; bad CRC or length (injected) %s; EMCY %s" %
          (frames, errors, counts, bad_crc, emcy_names))
    for t, node, since in watchdog_emcy:
        period = watchdog.get(node)
        print("  node %d: watchdog EMCY %.1f ms after its last valid command (watchdog %s ms)" %
              (node, since * 1e3, "?" if period is None else "%.0f" % (period * 1e3)))
        if period is not None and since < period * 0.98:
            problems.append("node %d: watchdog EMCY only %.1f ms after a valid command" % (node, since * 1e3))
    for node, t in stop_pending.items():
        problems.append("node %d: no zero-velocity STOPPED status after the watchdog EMCY at %.3f" % (node, t))
    if stopped_after:
        print("  zero-velocity STOPPED status at most %.1f ms after each watchdog EMCY" % (max(stopped_after) * 1e3))
    for name in ("Command", "Status", "Position", "Force", "Heartbeat", "Emcy"):
        if counts.get(name, 0) == 0:
            problems.append("no %s frame in the log" % name)
    if args.expect_faults:
        if not watchdog_emcy:
            problems.append("no watchdog EMCY in the log")
        if bad_crc.get("Command", 0) == 0:
            problems.append("no injected malformed command in the log")
        if errors == 0:
            problems.append("no error frame in the log")
    for p in problems:
        print("FAIL " + p)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())

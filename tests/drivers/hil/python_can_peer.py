#!/usr/bin/python3 -S
"""An independent peer for `visco driver`, written with python-can from the README's protocol table alone (its own
CRC and packing, no visco code): learns the driver's session from its session frame, commands it over vcan0 in that
session and checks its answers (their CRCs with the session and the status counter), that it boots disabled, a
malformed frame, the command watchdog and the new session it starts, the reset, and that an e-stop is not cleared by
a reset. Runs inside the HIL VM. Exit 0 when every check passes.

usage: python_can_peer.py --node N --watchdog-ms W
"""
import argparse
import struct
import sys
import time
import types

# python-can imports pkg_resources only to look up plugin interfaces; under the emulated CPU that alone costs
# ~10 s, so give it an empty stand-in (the socketcan interface is built in).
sys.path.append("/usr/lib/python3/dist-packages")
_stub = types.ModuleType("pkg_resources")
_stub.iter_entry_points = lambda *args, **kwargs: iter(())
sys.modules.setdefault("pkg_resources", _stub)
import can  # noqa: E402

FAILURES = []


def check(condition, what):
    print(("ok   " if condition else "FAIL ") + what, flush=True)
    if not condition:
        FAILURES.append(what)


def crc8_j1850(data):
    crc = 0xFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc ^ 0xFF


def fmix32(h):
    h = ((h ^ (h >> 16)) * 0x85EBCA6B) & 0xFFFFFFFF
    h = ((h ^ (h >> 13)) * 0xC2B2AE35) & 0xFFFFFFFF
    return h ^ (h >> 16)


def session_crc(can_id, session, counter, payload7):
    """README "CRC": the 11-bit id (2 bytes LE), the session key fmix32(nonce ^ fmix32(counter ^ fmix32(id))) (4 bytes
    LE), the counter's bits 8..31 (3 bytes LE), bytes 0..6."""
    key = fmix32(session ^ fmix32((counter ^ fmix32(can_id)) & 0xFFFFFFFF))
    return crc8_j1850(struct.pack("<HI", can_id, key) + (counter >> 8).to_bytes(3, "little") + bytes(payload7))


class Peer:
    def __init__(self, node):
        self.node = node
        ids = [0x080 + node, 0x180 + node, 0x280 + node, 0x380 + node, 0x480 + node, 0x700 + node]
        self.bus = can.Bus(interface="socketcan", channel="vcan0",
                           can_filters=[{"can_id": i, "can_mask": 0x7FF, "extended": False} for i in ids])
        self.session = None  # the driver's nonce, from its session frame
        self.epoch = 0       # status counter bits 8..31 from the session frame
        self.status_counter = None  # full counter of the last status accepted
        self.sessions_seen = 0
        self.seq = 0         # our command counter in the session
        self.sent = {}       # low byte of the number -> the last frame sent with it, in the session
        self.status = None  # (cmd_seq, vx, vy, state, contact)
        self.emcy = []      # (error_code, fault_code, fault_bits, stopped, cleared)
        self.heartbeats = 0
        self.bad_status_crc = 0

    def command(self, vx, vy, estop=False, reset=False, corrupt=False):
        can_id = 0x200 + self.node
        flags = (1 if estop else 0) | (2 if reset else 0)
        # README "Replays": a frame identical to the one sent a wrap earlier under its low byte would be taken for a
        # replay; such a number is skipped.
        for _ in range(4):
            self.seq += 1
            payload = struct.pack("<BBhhB", self.seq & 0xFF, flags, round(vx / 1e-4), round(vy / 1e-4),
                                  self.session & 0xFF)
            data = bytearray(payload + bytes([session_crc(can_id, self.session, self.seq, payload)]))
            if self.sent.get(self.seq & 0xFF) != bytes(data):
                break
        if corrupt:
            data[7] ^= 0xA5
            self.seq -= 1  # the driver never accepted it
        else:
            self.sent[self.seq & 0xFF] = bytes(data)
        self.bus.send(can.Message(arbitration_id=can_id, data=bytes(data), is_extended_id=False))

    def drain(self, seconds):
        end = time.monotonic() + seconds
        while True:
            left = end - time.monotonic()
            msg = self.bus.recv(timeout=max(0.0, left))
            if msg is None:
                return
            self.handle(msg)
            if time.monotonic() >= end:
                return

    def handle(self, msg):
        fc = msg.arbitration_id - self.node
        d = bytes(msg.data)
        if fc == 0x700:
            self.heartbeats += 1
        elif fc == 0x480:
            if len(d) != 8 or crc8_j1850(struct.pack("<H", msg.arbitration_id) + d[:7]) != d[7]:
                check(False, "session frame CRC")
                return
            nonce = struct.unpack("<I", d[:4])[0]
            if nonce != self.session:
                self.session = nonce
                self.epoch = int.from_bytes(d[4:7], "little")
                self.status_counter = None
                self.seq = 0  # a new session: numbering from 1
                self.sent = {}
                self.sessions_seen += 1
        elif fc == 0x180:
            if self.session is None:
                return
            low = d[0]
            if self.status_counter is None:
                candidates = [(self.epoch << 8) | low, ((self.epoch + 1) << 8) | low]
            else:
                candidates = [self.status_counter + ((low - self.status_counter) & 0xFF)]
            for counter in candidates:
                if len(d) == 8 and session_crc(msg.arbitration_id, self.session, counter, d[:7]) == d[7]:
                    self.status_counter = counter
                    _, cmd_seq, vx, vy, state_byte = struct.unpack("<BBhhB", d[:7])
                    self.status = (cmd_seq, vx * 1e-4, vy * 1e-4, state_byte & 0x0F, bool(state_byte & 0x10))
                    return
            self.bad_status_crc += 1
        elif fc == 0x080:
            code, _reg, fault_code, bits, flags, _counter = struct.unpack("<HBBHBB", d)
            self.emcy.append((code, fault_code, bits, bool(flags & 1), bool(flags & 2)))

    def wait(self, predicate, seconds, keep_commanding=None):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if keep_commanding is not None:
                self.command(*keep_commanding)
            self.drain(0.02)
            if predicate():
                return True
        return False


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--node", type=int, default=3)
    parser.add_argument("--watchdog-ms", type=float, default=500.0)
    args = parser.parse_args()
    peer = Peer(args.node)
    watchdog = args.watchdog_ms / 1000.0

    check(peer.wait(lambda: peer.heartbeats > 0, 120.0), "driver heartbeat 0x%03X seen" % (0x700 + args.node))
    check(peer.wait(lambda: peer.session is not None and peer.status is not None, 3.0),
          "session frame 0x%03X seen, a status with a valid CRC for it" % (0x480 + args.node))
    check(peer.status is not None and peer.status[3] == 0, "the driver boots DISABLED")
    peer.command(0.1, 0.0)
    peer.drain(0.1)
    check(peer.status[3] == 0 and peer.status[1] == 0.0, "a velocity command does not move a disabled driver")
    peer.command(0, 0, reset=True)
    check(peer.wait(lambda: peer.status is not None and peer.status[0] == peer.seq & 0xFF and peer.status[3] == 1,
                    3.0), "reset answered: READY with the reset's sequence number")
    answered = 0
    for _ in range(40):
        peer.command(0.1, 0.05)
        if peer.wait(lambda: peer.status is not None and peer.status[0] == peer.seq & 0xFF, 1.0):
            answered += 1
    check(answered == 40, "every command answered with its sequence number (%d/40)" % answered)
    check(peer.status is not None and peer.status[3] == 2, "driver state MOVING")
    check(peer.wait(lambda: abs(peer.status[1] - 0.1) < 2e-4 and abs(peer.status[2] - 0.05) < 2e-4, 3.0, (0.1, 0.05)),
          "robot velocity reaches the command (0.1, 0.05) m/s")

    peer.emcy.clear()
    peer.command(0.4, 0.0, corrupt=True)
    check(peer.wait(lambda: any(e[0] == 0x8200 for e in peer.emcy), 2.0, (0.1, 0.05)),
          "bad CRC reported with EMCY 0x8200")
    check(abs(peer.status[1] - 0.1) < 2e-4, "the corrupted command was not applied")

    peer.emcy.clear()
    silent = time.monotonic()
    stopped = peer.wait(lambda: peer.status is not None and peer.status[3] == 3 and peer.status[1] == 0.0 and
                        peer.status[2] == 0.0, watchdog + 2.0)
    took = time.monotonic() - silent
    check(stopped, "silent controller: driver STOPPED with zero velocity")
    # The peer itself is slow on the emulated CPU: it may notice the stop late, never early.
    check(watchdog * 0.9 <= took, "not before the watchdog period (%.0f ms >= %.0f ms)" % (took * 1e3, watchdog * 900))
    check(any(e[0] == 0x8250 and e[3] for e in peer.emcy), "watchdog reported with EMCY 0x8250, robot stopped")

    check(peer.wait(lambda: peer.sessions_seen >= 2 and peer.seq == 0, 1.0),
          "the watchdog stop started a new session (session frame)")

    peer.emcy.clear()
    peer.command(0, 0, reset=True)
    check(peer.wait(lambda: peer.status[3] == 1, 3.0), "reset in the new session: READY again")
    check(any(e[0] == 0 and e[4] for e in peer.emcy), "EMCY 0x0000 announces the cleared faults")
    check(peer.wait(lambda: peer.status[3] == 2, 3.0, (0.0, -0.1)), "moving again after the reset")
    peer.command(0, 0, estop=True)
    check(peer.wait(lambda: peer.status[3] == 4, 3.0), "e-stop flag: ESTOP")
    peer.drain(0.1)  # the e-stop started a new session
    peer.emcy.clear()
    check(not peer.wait(lambda: peer.status[3] != 4, 0.5, (0.0, 0.0, False, True)),
          "resets do not clear the e-stop")
    check(any(e[0] == 0xFF01 for e in peer.emcy), "the refused reset is reported with EMCY 0xFF01")
    check(peer.bad_status_crc == 0, "every status CRC of the driver matched its session (%d bad)" % peer.bad_status_crc)
    peer.bus.shutdown()
    print("python-can peer: %d failure(s)" % len(FAILURES), flush=True)
    return 1 if FAILURES else 0


if __name__ == "__main__":
    sys.exit(main())

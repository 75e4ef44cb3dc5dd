#!/usr/bin/env python3
"""Small tools on LCM event logs (lcm-logger's format) for the replay tests: list, damage, rename, trim and
re-encode images as PNG (lossless, so vision sees the same pixels).  Standard library only.

usage: logtool.py list LOG
       logtool.py diff LOG1 LOG2 [CHANNEL] [BEFORE_S]
                                                     compare the payloads (channel and bytes, receive timestamps
                                                     aside) event by event (only CHANNEL's if given and not "-";
                                                     only the events of the first BEFORE_S seconds if given); exit
                                                     0 if identical, 1 at the first difference (printed)
       logtool.py corrupt-image LOG OUT SEQ         XOR every pixel byte of the image with image_t.seq SEQ with 0x08
       logtool.py damage LOG OUT KIND               KIND: truncate | flip-header | bad-sync | unknown-channel |
                                                     undecodable | garbage | empty | only-undecodable |
                                                     lose-image (an image vision processed, not written)
       logtool.py extract-images LOG DIR            write the PNG images of the log as DIR/frame_NNNN.png
       logtool.py rename LOG OUT PREFIX             prefix every channel name
       logtool.py corrupt-cycle LOG OUT K           flip the lowest bit of the commanded x velocity in the K-th
                                                     controller record; prints its cycle number
       logtool.py fixture LOG OUT MAX_BYTES [STRATEGY SCENE RAYS]
                                                     keep the camera, vision and controller channels from the start
                                                     while the file stays under MAX_BYTES, images as PNG; the run's
                                                     configuration at the end, its file names replaced by these
                                                     (written relative to OUT's folder, as replay resolves them)
       logtool.py files LOG OUT STRATEGY SCENE RAYS  LOG with the file names of its run's configuration replaced
                                                     by these (written relative to OUT's folder)
"""
import struct
import sys
import zlib

SYNC = 0xEDA1DA01
CYCLE, ANNOTATION = "VISCO_CONTROLLER_CYCLE", "VISCO_LOG_ANNOTATION"
VISION = {"VISCO_CAMERA_IMAGE", "VISCO_CAMERA_INFO", "VISCO_VISION_CONFIG", "VISCO_TAG_DETECTIONS", "VISCO_OBJECT_POSES",
          "VISCO_ROBOT_ESTIMATE", "VISCO_VISUAL_EVENTS", "VISCO_FAULT"}
GRAY8, PNG = 1, 5


def read(path):
    data = open(path, "rb").read()
    events, pos = [], 0
    while pos + 28 <= len(data):
        sync, num, ts, clen, dlen = struct.unpack(">IqqII", data[pos:pos + 28])
        if sync != SYNC:
            raise SystemExit("%s: not a clean log at byte %d" % (path, pos))
        channel = data[pos + 28:pos + 28 + clen].decode()
        payload = data[pos + 28 + clen:pos + 28 + clen + dlen]
        events.append([num, ts, channel, bytearray(payload)])
        pos += 28 + clen + dlen
    return events


def encode(events):
    out = bytearray()
    for i, (_, ts, channel, payload) in enumerate(events):
        c = channel.encode()
        out += struct.pack(">IqqII", SYNC, i, ts, len(c), len(payload)) + c + payload
    return out


def write(path, data):
    open(path, "wb").write(data)


class Message:
    """Reads an lcm-gen encoded message field by field: big-endian, booleans as one byte, strings with a length that
    counts their NUL."""

    def __init__(self, payload):
        self.data, self.pos = payload, 8  # after the type's fingerprint

    def take(self, fmt):
        values = struct.unpack_from(">" + fmt, self.data, self.pos)
        self.pos += struct.calcsize(">" + fmt)
        return values[0] if len(values) == 1 else values

    def string(self):
        n = self.take("i")
        text = bytes(self.data[self.pos:self.pos + n - 1]).decode(errors="replace")
        self.pos += n
        return text


def image_fields(payload):
    """Offsets in an encoded visco.image_t: (seq, offset of width, offset of data, data length)."""
    seq = struct.unpack(">q", payload[16:24])[0]
    (clen,) = struct.unpack(">I", payload[24:28])
    p = 28 + clen  # the string's bytes include its terminating NUL
    width, height, stride, fmt, size = struct.unpack(">iiiii", payload[p:p + 20])
    return seq, p, p + 20, size, (width, height, stride, fmt)


def png_gray(width, height, stride, pixels):
    raw = b"".join(b"\x00" + bytes(pixels[r * stride:r * stride + width]) for r in range(height))
    chunk = lambda kind, body: struct.pack(">I", len(body)) + kind + body + struct.pack(
        ">I", zlib.crc32(kind + body) & 0xFFFFFFFF)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def set_files(note, names):
    """Replaces the strategy, scene and rays files named by a controller_config annotation event."""
    import json
    payload = note[3]
    # log_annotation_t: fingerprint, utime, then three strings (source, kind, text).
    p = 16
    strings = []
    for _ in range(3):
        (n,) = struct.unpack(">I", payload[p:p + 4])
        strings.append(bytes(payload[p + 4:p + 4 + n - 1]).decode())
        p += 4 + n
    config = json.loads(strings[2])
    config["strategy"], config["scene"], config["rays"] = names
    body = bytearray(payload[:16])
    for text in strings[:2] + [json.dumps(config, sort_keys=True)]:
        raw = text.encode() + b"\0"
        body += struct.pack(">I", len(raw)) + raw
    note[3] = body


def rebase_files(events, log, out):
    """A log written elsewhere names the same files: relative names (relative to the log's folder, as replay resolves
    them) are rewritten relative to OUT's folder."""
    import json
    import os
    notes = [e for e in events if e[2] == ANNOTATION]
    if not notes:
        return
    p, strings = 16, []
    for _ in range(3):
        (n,) = struct.unpack(">I", notes[-1][3][p:p + 4])
        strings.append(bytes(notes[-1][3][p + 4:p + 4 + n - 1]).decode())
        p += 4 + n
    if strings[1] != "controller_config":
        return
    config = json.loads(strings[2])
    source, target = (os.path.dirname(os.path.abspath(p)) for p in (log, out))
    names = []
    for key in ("strategy", "scene", "rays"):
        name = config.get(key, "")
        relative = name and not os.path.isabs(name)
        names.append(os.path.relpath(os.path.join(source, name), target) if relative else name)
    set_files(notes[-1], names)


def relative_to(log, names):
    """The names as `visco replay` resolves them: relative to the log's folder."""
    import os
    folder = os.path.dirname(os.path.abspath(log))
    return [os.path.relpath(os.path.abspath(n), folder) for n in names]


def main():
    cmd = sys.argv[1]
    if cmd == "files":
        events = read(sys.argv[2])
        notes = [e for e in events if e[2] == ANNOTATION]
        if not notes:
            raise SystemExit("%s: no controller_config annotation" % sys.argv[2])
        set_files(notes[-1], relative_to(sys.argv[3], sys.argv[4:7]))
        write(sys.argv[3], encode(events))
        return
    if cmd == "diff":
        channel = sys.argv[4] if len(sys.argv) > 4 and sys.argv[4] != "-" else None
        before = float(sys.argv[5]) if len(sys.argv) > 5 else None

        def selected(path):
            events = read(path)
            t0 = events[0][1] if events else 0
            return [e for e in events if (channel is None or e[2] == channel) and
                    (before is None or e[1] - t0 < before * 1e6)]
        a, b = selected(sys.argv[2]), selected(sys.argv[3])
        what = "%s events" % channel if channel else "events"
        for i, (x, y) in enumerate(zip(a, b)):
            if x[2] != y[2] or x[3] != y[3]:
                at = next((k for k in range(min(len(x[3]), len(y[3]))) if x[3][k] != y[3][k]), None)
                print("payloads differ at %s %d: %s (%d bytes) against %s (%d bytes), first differing byte %s" %
                      (what, i, x[2], len(x[3]), y[2], len(y[3]), at))
                sys.exit(1)
        if len(a) != len(b):
            print("payloads identical for %d %s; then %d against %d" % (min(len(a), len(b)), what, len(a), len(b)))
            sys.exit(1)
        print("payloads identical: %d %s" % (len(a), what))
        sys.exit(0)
    if cmd == "list":
        for num, ts, channel, payload in read(sys.argv[2]):
            extra = ""
            if channel == "VISCO_CAMERA_IMAGE":
                extra = " seq %d" % image_fields(payload)[0]
            print("%d %d %s %d%s" % (num, ts, channel, len(payload), extra))
        return
    events = read(sys.argv[2])
    out = sys.argv[3]
    rebase_files(events, sys.argv[2], out)
    if cmd == "extract-images":
        import os
        os.makedirs(out, exist_ok=True)
        n = 0
        for e in events:
            if e[2] == "VISCO_CAMERA_IMAGE":
                _, _, data_at, size, (_, _, _, fmt) = image_fields(e[3])
                if fmt == PNG:
                    open(os.path.join(out, "frame_%04d.png" % n), "wb").write(e[3][data_at:data_at + size])
                    n += 1
        print(n)
        return
    if cmd == "corrupt-image":
        seq = int(sys.argv[4])
        for e in events:
            if e[2] == "VISCO_CAMERA_IMAGE" and image_fields(e[3])[0] == seq:
                _, _, data_at, size, _ = image_fields(e[3])
                for k in range(data_at, data_at + size):
                    e[3][k] ^= 0x08
                write(out, encode(events))
                return
        raise SystemExit("no image with seq %d" % seq)
    if cmd == "corrupt-cycle":
        k = int(sys.argv[4])
        cycles = [e for e in events if e[2] == CYCLE]
        e = cycles[k]
        # controller_cycle_t ends with command_velocity[2] (16 bytes) and 9 bytes of flags, mode, step, holding.
        e[3][len(e[3]) - 9 - 16 + 7] ^= 0x01
        write(out, encode(events))
        print(struct.unpack(">q", bytes(e[3][24:32]))[0])
        return
    if cmd == "rename":
        for e in events:
            e[2] = sys.argv[4] + e[2]
        write(out, encode(events))
        return
    if cmd == "fixture":
        limit = int(sys.argv[4])
        kept, size = [], 0
        notes = [e for e in events if e[2] == ANNOTATION]
        if notes:
            if len(sys.argv) > 7:
                set_files(notes[-1], relative_to(sys.argv[3], sys.argv[5:8]))
            size += 28 + len(ANNOTATION) + len(notes[-1][3])
        for e in events:
            if e[2] not in VISION and e[2] != CYCLE:
                continue
            if e[2] == "VISCO_CAMERA_IMAGE":
                seq, fmt_at, data_at, n, (w, h, stride, fmt) = image_fields(e[3])
                if fmt == GRAY8:
                    png = png_gray(w, h, stride, e[3][data_at:data_at + n])
                    head = bytearray(e[3][:fmt_at]) + struct.pack(">iiiii", w, h, w, PNG, len(png))
                    e[3] = head + png
            # lcm-gen's fingerprint stays the same: only the field values changed.
            grown = size + 28 + len(e[2]) + len(e[3])
            if grown > limit:
                break
            kept.append(e)
            size = grown
        if notes:
            notes[-1][1] = kept[-1][1] if kept else notes[-1][1]
            kept.append(notes[-1])
        write(out, encode(kept))
        print("%d events, %d bytes" % (len(kept), size))
        return
    if cmd == "damage":
        kind = sys.argv[4]
        data = encode(events)
        offsets, pos = [], 0
        for e in events:
            offsets.append(pos)
            pos += 28 + len(e[2]) + len(e[3])
        mid = offsets[len(offsets) // 2]
        if kind == "truncate":
            data = data[:len(data) - 1000]
        elif kind == "flip-header":
            data[mid + 26] ^= 0x40  # data length of the middle event
        elif kind == "bad-sync":
            data[mid] ^= 0xFF
        elif kind == "unknown-channel":
            c = b"SOMEONE_ELSES_CHANNEL"
            data += struct.pack(">IqqII", SYNC, len(events), events[-1][1] + 1, len(c), 4) + c + b"abcd"
        elif kind == "undecodable":
            c = b"VISCO_CAMERA_IMAGE"
            junk = bytes(range(200))
            data += struct.pack(">IqqII", SYNC, len(events), events[-1][1] + 1, len(c), len(junk)) + c + junk
        elif kind == "lose-image":
            # The image of a frame vision processed, a third into the run, never reached the logger (UDP under load):
            # the event is not written at all, so no event number is missing.
            images = [k for k, e in enumerate(events) if e[2] == "VISCO_CAMERA_IMAGE"]
            kept = events[:images[len(images) // 3]] + events[images[len(images) // 3] + 1:]
            data = encode(kept)
        elif kind == "garbage":
            data = bytearray((i * 7919) % 251 for i in range(20000))
        elif kind == "empty":
            data = bytearray()
        elif kind == "only-undecodable":
            c = b"VISCO_CAMERA_IMAGE"
            data = bytearray()
            for i in range(3):
                data += struct.pack(">IqqII", SYNC, i, 1000 + i, len(c), 10) + c + bytes(10)
        else:
            raise SystemExit("unknown damage " + kind)
        write(out, data)
        return
    raise SystemExit(__doc__)


if __name__ == "__main__":
    main()

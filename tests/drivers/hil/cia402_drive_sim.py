#!/usr/bin/python3 -S
"""CiA 402 drives simulated on a SocketCAN bus, for the HIL tests of visco's CiA 402 backend. Written from CiA 301
(object dictionary, expedited SDO server with abort codes, NMT slave, heartbeat producer and consumer, PDO mapping
set by SDO, SYNC consumer, EMCY producer) and CiA 402 (the drive state machine, profile velocity (3) and cyclic
synchronous velocity (9) modes, quick stop option code, abort connection option code), with python-can alone: it
shares no code with visco. Each drive moves one axis: its velocity tracks the target within its profile
acceleration/deceleration (its quick stop deceleration after a quick stop or in a fault reaction), clamped to its max
profile velocity, times a gain in [1 - U, 1 + U] that a seeded random adversary changes now and then (U:
--speed-uncertainty; docs/semantics.md's uncertainty, one axis at a time).

With --plant HOST:PORT the drives move a physical plant instead of an axis of their own: each tick a drive sends its
axis's velocity to the plant (visco's simulated world, `visco sim --plant`: contact, friction and the velocity cone
decide where the robot goes) and takes the plant's position and velocity as its encoder (0x6064, 0x606C), in counts
of --counts-per-metre (an absolute encoder homed at the world's origin). The wire format, one UDP datagram each way,
little-endian: drive -> plant "VPL1", axis (u8), 3 zero bytes, velocity (f64, m/s); plant -> drive "VPL1", axis,
3 zero bytes, position (f64, m), velocity (f64, m/s).

Run standalone (`cia402_drive_sim.py --interface vcan1 --nodes 2 3`) or imported by a test, which drives it through
the methods of Sim (inject_fault, silence, power_on, ...) and reads what each drive did from Drive.history.
"""
import argparse
import json
import signal
import random
import socket
import struct
import sys
import threading
import time
import types

# python-can imports pkg_resources only to look up plugin interfaces; under the emulated CPU that alone costs ~10 s.
sys.path.append("/usr/lib/python3/dist-packages")
_stub = types.ModuleType("pkg_resources")
_stub.iter_entry_points = lambda *args, **kwargs: iter(())
sys.modules.setdefault("pkg_resources", _stub)
import can  # noqa: E402

# CiA 301 SDO abort codes.
ABORT_COMMAND = 0x05040001
ABORT_UNSUPPORTED_ACCESS = 0x06010000
ABORT_READ_ONLY = 0x06010002
ABORT_NO_OBJECT = 0x06020000
ABORT_NOT_MAPPABLE = 0x06040041
ABORT_PDO_LENGTH = 0x06040042
ABORT_LENGTH = 0x06070010
ABORT_NO_SUBINDEX = 0x06090011
ABORT_VALUE = 0x06090030
ABORT_STATE = 0x08000022

# NMT states as the heartbeat carries them.
BOOT, STOPPED, OPERATIONAL, PRE_OPERATIONAL = 0x00, 0x04, 0x05, 0x7F

# CiA 402 states and their statusword bits (6 switch on disabled, 5 quick stop, 3 fault, 2 operation enabled,
# 1 switched on, 0 ready to switch on) plus bit 9, remote.
NOT_READY, SWITCH_ON_DISABLED, READY, SWITCHED_ON, ENABLED, QUICK_STOP, FAULT_REACTION, FAULT = (
    "NOT READY TO SWITCH ON", "SWITCH ON DISABLED", "READY TO SWITCH ON", "SWITCHED ON", "OPERATION ENABLED",
    "QUICK STOP ACTIVE", "FAULT REACTION ACTIVE", "FAULT")
STATUS_BITS = {NOT_READY: 0x00, SWITCH_ON_DISABLED: 0x40, READY: 0x21, SWITCHED_ON: 0x23, ENABLED: 0x27,
               QUICK_STOP: 0x07, FAULT_REACTION: 0x0F, FAULT: 0x08}

# (format, writable, mappable, default) per (index, sub). Formats are struct codes: B/H/I unsigned, b/h/i signed.
U8, U16, U32, I8, I16, I32 = "B", "H", "I", "b", "h", "i"


def default_dictionary(node):
    od = {
        (0x1000, 0): (U32, False, False, 0x00020192),  # device type: CiA 402, servo drive
        (0x1001, 0): (U8, False, False, 0),            # error register
        (0x1016, 0): (U8, False, False, 1),
        (0x1016, 1): (U32, True, False, 0),            # consumer heartbeat: node << 16 | ms (0: off)
        (0x1017, 0): (U16, True, False, 0),            # producer heartbeat, ms (0: off)
        (0x6007, 0): (I16, True, False, 1),            # abort connection option: 1 = fault
        (0x6040, 0): (U16, True, True, 0),             # controlword
        (0x6041, 0): (U16, False, True, 0),            # statusword
        (0x605A, 0): (I16, True, False, 2),            # quick stop option code
        (0x6060, 0): (I8, True, True, 3),              # modes of operation
        (0x6061, 0): (I8, False, True, 3),             # modes of operation display
        (0x6064, 0): (I32, False, True, 0),            # position actual value
        (0x606C, 0): (I32, False, True, 0),            # velocity actual value
        (0x607F, 0): (U32, True, False, 200000),       # max profile velocity
        (0x6083, 0): (U32, True, False, 400000),       # profile acceleration
        (0x6084, 0): (U32, True, False, 400000),       # profile deceleration
        (0x6085, 0): (U32, True, False, 4000000),      # quick stop deceleration
        (0x60FF, 0): (I32, True, True, 0),             # target velocity
        (0x6502, 0): (U32, False, False, (1 << 2) | (1 << 8)),  # supported drive modes: pv, csv
    }
    # CiA 301 default PDOs: RPDO1/2 at 0x200/0x300 + node, TPDO1/2 at 0x180/0x280 + node; mapped with the
    # controlword and statusword only, TPDO2 and RPDO2 empty.
    for k, (rx_cob, tx_cob) in enumerate(((0x200, 0x180), (0x300, 0x280))):
        od[(0x1400 + k, 0)] = (U8, False, False, 2)
        od[(0x1400 + k, 1)] = (U32, True, False, rx_cob + node)
        od[(0x1400 + k, 2)] = (U8, True, False, 255)
        od[(0x1800 + k, 0)] = (U8, False, False, 2)
        od[(0x1800 + k, 1)] = (U32, True, False, tx_cob + node)
        od[(0x1800 + k, 2)] = (U8, True, False, 255)
        for mapping in (0x1600 + k, 0x1A00 + k):
            od[(mapping, 0)] = (U8, True, False, 0)
            for sub in range(1, 9):
                od[(mapping, sub)] = (U32, True, False, 0)
    od[(0x1600, 0)] = (U8, True, False, 1)
    od[(0x1600, 1)] = (U32, True, False, 0x60400010)
    od[(0x1A00, 0)] = (U8, True, False, 1)
    od[(0x1A00, 1)] = (U32, True, False, 0x60410010)
    return od


class Drive:
    """One CiA 402 drive (one axis) on the bus."""

    def __init__(self, sim, node, boot_delay=0.0, abort=None, max_velocity=None):
        self.sim = sim
        self.node = node
        self.abort = abort            # (index, sub, code): an SDO on this object is aborted with this code
        self.max_velocity = max_velocity
        self.powered = boot_delay <= 0.0
        self.power_at = None if self.powered else time.monotonic() + boot_delay
        self.silent = False           # a dead drive: sends and answers nothing
        self.history = []             # (time, what, value): states, NMT states, EMCYs, SDO aborts
        self.sdo_log = []             # (index, sub, "r"/"w", value or abort code)
        self.position = 0.0           # counts (float, the motion model's)
        self.velocity = 0.0           # units/s, the model's actual velocity
        self.max_speed_seen = 0.0
        self.gain = 1.0
        self.next_gain_change = 0.0
        self.axis = None              # with a plant: (axis index, counts per metre)
        self.boot()

    # --- object dictionary ---
    def boot(self, communication_only=False):
        fresh = default_dictionary(self.node)
        if communication_only:
            for key, entry in fresh.items():
                if 0x1000 <= key[0] <= 0x1FFF:
                    self.od[key] = list(entry)
        else:
            self.od = {key: list(entry) for key, entry in fresh.items()}
            self.state = NOT_READY
            self.set_state(SWITCH_ON_DISABLED)  # transition 1, at once
            if self.max_velocity is not None:
                self.od[(0x607F, 0)][3] = self.max_velocity
        self.nmt = PRE_OPERATIONAL
        self.sync_count = {}
        self.rpdo_buffer = {}
        self.consumer_seen = None     # last heartbeat of the consumed node (None: not yet, the consumer waits)
        self.heartbeat_event = False
        self.next_heartbeat = time.monotonic()
        self.previous_controlword = 0
        self.fault_code = 0
        self.record("nmt", "boot-up")
        self.send(0x700 + self.node, [BOOT])

    def get(self, index, sub=0):
        return self.od[(index, sub)][3]

    def put(self, index, value, sub=0):
        self.od[(index, sub)][3] = value

    def record(self, what, value):
        self.history.append((time.monotonic(), what, value))

    def send(self, can_id, data):
        if not self.silent and self.powered:
            self.sim.send(can_id, data)

    def set_state(self, state):
        if state != self.state:
            self.state = state
            self.record("state", state)
        self.put(0x6041, STATUS_BITS[state] | 0x0200)

    def emcy(self, code, register=0x01):
        self.record("emcy", code)
        self.put(0x1001, register if code else 0)
        self.send(0x080 + self.node, list(struct.pack("<HB5x", code, register if code else 0)))

    def fault(self, code):
        """A fault: EMCY, then the fault reaction (a quick stop ramp), then FAULT."""
        if self.state in (FAULT, FAULT_REACTION):
            return
        self.fault_code = code
        self.emcy(code)
        self.set_state(FAULT_REACTION)

    # --- frames ---
    def on_frame(self, msg, now):
        if not self.powered or self.silent:
            return
        cid, data = msg.arbitration_id, bytes(msg.data)
        if cid == 0x000 and len(data) == 2 and data[1] in (0, self.node):
            self.on_nmt(data[0])
        elif cid == 0x600 + self.node:
            if self.nmt in (PRE_OPERATIONAL, OPERATIONAL):
                self.on_sdo(data)
        elif cid == 0x080 and self.nmt == OPERATIONAL:
            self.on_sync()
        elif cid == 0x700 + (self.get(0x1016, 1) >> 16) and self.get(0x1016, 1) & 0xFFFF:
            self.consumer_seen = now
        elif self.nmt == OPERATIONAL:
            for k in (0, 1):
                cob = self.get(0x1400 + k, 1)
                if not cob & 0x80000000 and cid == cob & 0x7FF:
                    if self.get(0x1400 + k, 2) <= 240:
                        self.rpdo_buffer[k] = data  # synchronous: applied at the next SYNC
                    else:
                        self.apply_rpdo(k, data)

    def on_nmt(self, command):
        if command == 0x01:
            self.nmt = OPERATIONAL
        elif command == 0x02:
            self.nmt = STOPPED
        elif command == 0x80:
            self.nmt = PRE_OPERATIONAL
        elif command in (0x81, 0x82):
            self.boot(communication_only=command == 0x82)
            self.sim.refilter()  # the default COB-IDs, no consumer
            return
        else:
            return
        self.record("nmt", {0x01: "operational", 0x02: "stopped", 0x80: "pre-operational"}[command])

    def on_sdo(self, data):
        if len(data) != 8:
            return
        ccs, index, sub = data[0] >> 5, data[1] | data[2] << 8, data[3]

        def abort(code):
            self.sdo_log.append((index, sub, "abort", code))
            self.record("sdo abort", (index, sub, code))
            self.send(0x580 + self.node, list(struct.pack("<BHBI", 0x80, index, sub, code)))

        if ccs not in (1, 2):
            return abort(ABORT_COMMAND) if ccs != 4 else None
        if self.abort and (index, sub) == self.abort[:2]:
            return abort(self.abort[2])
        if (index, sub) not in self.od:
            return abort(ABORT_NO_SUBINDEX if any(i == index for i, _ in self.od) else ABORT_NO_OBJECT)
        fmt, writable, _, value = self.od[(index, sub)]
        size = struct.calcsize(fmt)
        if ccs == 2:  # upload
            raw = struct.pack("<" + fmt, value)
            self.sdo_log.append((index, sub, "r", value))
            return self.send(0x580 + self.node,
                             [0x43 | ((4 - size) << 2), data[1], data[2], sub] + list(raw) + [0] * (4 - size))
        if not data[0] & 0x02:
            return abort(ABORT_COMMAND)  # segmented download: not this drive
        if data[0] & 0x01 and 4 - ((data[0] >> 2) & 3) != size:
            return abort(ABORT_LENGTH)
        if not writable:
            return abort(ABORT_READ_ONLY)
        new = struct.unpack("<" + fmt, data[4:4 + size])[0]
        code = self.check_write(index, sub, new)
        if code:
            return abort(code)
        self.od[(index, sub)][3] = new
        self.sdo_log.append((index, sub, "w", new))
        if index == 0x6060:
            self.put(0x6061, new)
        if index == 0x1016:
            self.consumer_seen = None
            self.heartbeat_event = False
        if index in (0x1016, 0x1400, 0x1401):
            self.sim.refilter()
        self.send(0x580 + self.node, [0x60, data[1], data[2], sub, 0, 0, 0, 0])

    def check_write(self, index, sub, value):
        """CiA 301 7.4.7.1: a PDO's mapping changes only while it is disabled and its count is 0; the count is
        checked against 64 bits and every entry must name a mappable object."""
        if index == 0x6060 and value not in (3, 9):
            return ABORT_VALUE
        if index == 0x605A and not 0 <= value <= 8:
            return ABORT_VALUE
        if index in (0x1600, 0x1601, 0x1A00, 0x1A01):
            comm = (0x1400 if index < 0x1A00 else 0x1800) + (index & 1)
            if not self.get(comm, 1) & 0x80000000:
                return ABORT_UNSUPPORTED_ACCESS
            if sub == 0:
                if value > 8:
                    return ABORT_PDO_LENGTH
                bits = 0
                for s in range(1, value + 1):
                    entry = self.get(index, s)
                    key = (entry >> 16, (entry >> 8) & 0xFF)
                    if key not in self.od or not self.od[key][2]:
                        return ABORT_NOT_MAPPABLE
                    bits += entry & 0xFF
                if bits > 64:
                    return ABORT_PDO_LENGTH
            elif self.get(index, 0) != 0:
                return ABORT_UNSUPPORTED_ACCESS
            else:
                key = (value >> 16, (value >> 8) & 0xFF)
                if value and (key not in self.od or not self.od[key][2]):
                    return ABORT_NOT_MAPPABLE if key in self.od else ABORT_NO_OBJECT
                if value and struct.calcsize(self.od[key][0]) * 8 != value & 0xFF:
                    return ABORT_LENGTH
        if index in (0x1400, 0x1401, 0x1800, 0x1801) and sub == 1 and not value & 0x80000000 \
                and not self.get(index, 1) & 0x80000000 and value != self.get(index, 1):
            return ABORT_VALUE  # the COB-ID of a valid PDO cannot change
        return 0

    def mapped(self, mapping):
        return [(e >> 16, (e >> 8) & 0xFF) for e in (self.get(mapping, s) for s in range(1, self.get(mapping, 0) + 1))]

    def apply_rpdo(self, k, data):
        entries = self.mapped(0x1600 + k)
        fmt = "<" + "".join(self.od[key][0] for key in entries)
        if len(data) < struct.calcsize(fmt):
            return self.emcy(0x8210)  # PDO not processed due to length error
        for key, value in zip(entries, struct.unpack(fmt, data[:struct.calcsize(fmt)])):
            self.od[key][3] = value
        self.on_controlword(self.get(0x6040))

    def on_sync(self):
        for k, data in list(self.rpdo_buffer.items()):
            self.apply_rpdo(k, data)
        self.rpdo_buffer.clear()
        for k in (0, 1):
            cob, kind = self.get(0x1800 + k, 1), self.get(0x1800 + k, 2)
            if cob & 0x80000000 or not 1 <= kind <= 240:
                continue
            self.sync_count[k] = self.sync_count.get(k, 0) + 1
            if self.sync_count[k] >= kind:
                self.sync_count[k] = 0
                entries = self.mapped(0x1A00 + k)
                fmt = "<" + "".join(self.od[key][0] for key in entries)
                self.send(cob & 0x7FF, list(struct.pack(fmt, *(self.get(*key) for key in entries))))

    # --- CiA 402 state machine (controlword bits 7, 3..0) ---
    def on_controlword(self, cw):
        edge = cw & 0x80 and not self.previous_controlword & 0x80
        self.previous_controlword = cw
        s = self.state
        shutdown, switch_on, enable = (cw & 0x87) == 0x06, (cw & 0x8F) == 0x07, (cw & 0x8F) == 0x0F
        disable_voltage, quick_stop = (cw & 0x82) == 0x00, (cw & 0x86) == 0x02
        if s == FAULT:
            if edge:
                self.fault_code = 0
                self.heartbeat_event = False
                self.emcy(0x0000)          # error reset
                self.set_state(SWITCH_ON_DISABLED)  # 15
        elif s == SWITCH_ON_DISABLED:
            if shutdown:
                self.set_state(READY)  # 2
        elif s == READY:
            if switch_on or enable:
                self.set_state(SWITCHED_ON)  # 3
            elif disable_voltage or quick_stop:
                self.set_state(SWITCH_ON_DISABLED)  # 7
        elif s == SWITCHED_ON:
            if enable:
                self.set_state(ENABLED)  # 4
            elif shutdown:
                self.set_state(READY)  # 6
            elif disable_voltage or quick_stop:
                self.set_state(SWITCH_ON_DISABLED)  # 10
        elif s == ENABLED:
            if quick_stop:
                self.set_state(QUICK_STOP)  # 11
            elif switch_on:
                self.set_state(SWITCHED_ON)  # 5
            elif shutdown:
                self.set_state(READY)  # 8
            elif disable_voltage:
                self.set_state(SWITCH_ON_DISABLED)  # 9
        elif s == QUICK_STOP:
            if disable_voltage:
                self.set_state(SWITCH_ON_DISABLED)  # 12
            elif enable and 5 <= self.get(0x605A) <= 8:
                self.set_state(ENABLED)  # 16

    # --- time ---
    def tick(self, now, dt, read_up_to=None):
        """read_up_to: the time up to which every frame the bus delivered has been read (now unless frames still wait
        in the socket); the heartbeat consumer judges only that far."""
        if not self.powered:
            if self.power_at is not None and now >= self.power_at:
                self.powered = True
                self.boot()
                self.sim.refilter()
            return
        if self.silent:
            return
        period = self.get(0x1017) / 1000.0
        if period > 0 and now >= self.next_heartbeat:
            self.send(0x700 + self.node, [self.nmt])
            self.next_heartbeat = now + period
        consumer = self.get(0x1016, 1)
        judged = now if read_up_to is None else read_up_to
        if consumer & 0xFFFF and self.consumer_seen is not None and not self.heartbeat_event \
                and judged - self.consumer_seen > (consumer & 0xFFFF) / 1000.0:
            self.heartbeat_event = True  # CiA 301 heartbeat event, CiA 402 0x6007 abort connection
            self.record("heartbeat lost", consumer >> 16)
            option = self.get(0x6007)
            if option == 1:
                self.fault(0x8130)
            elif option == 3 and self.state == ENABLED:
                self.emcy(0x8130)
                self.set_state(QUICK_STOP)
            elif option == 2:
                self.emcy(0x8130)
                self.set_state(SWITCH_ON_DISABLED)
        self.move(now, dt)

    def move(self, now, dt):
        units = 1.0
        state = self.state
        max_v = self.get(0x607F)
        if state == ENABLED:
            target = max(-max_v, min(max_v, self.get(0x60FF)))
            rate = self.get(0x6083) if abs(target) > abs(self.velocity) else self.get(0x6084)
        elif state in (QUICK_STOP, FAULT_REACTION):
            target, rate = 0.0, self.get(0x6085)
        else:
            target, rate = 0.0, float("inf") if state in (SWITCH_ON_DISABLED, READY, FAULT, NOT_READY) else 0.0
            if state == SWITCHED_ON:  # powered, drive function disabled: the axis is held
                rate = float("inf")
        step = rate * dt * units
        change = target - self.velocity
        self.velocity = target if abs(change) <= step else self.velocity + (step if change > 0 else -step)
        if now >= self.next_gain_change:
            u = self.sim.speed_uncertainty
            self.gain = 1.0 + self.sim.rng.uniform(-u, u) if u > 0 else 1.0
            self.next_gain_change = now + self.sim.rng.expovariate(1 / 0.05)
        if self.axis is not None:
            # The plant moves: the drive's velocity is its input, its answer the axis's position and velocity.
            axis, counts_per_metre = self.axis
            self.sim.to_plant(axis, self.velocity / counts_per_metre)
            position, actual = self.sim.plant_state[axis]
            self.position, actual = position * counts_per_metre, actual * counts_per_metre
        else:
            actual = self.velocity * self.gain
            self.position += actual * dt
        self.max_speed_seen = max(self.max_speed_seen, abs(actual))
        self.put(0x606C, int(round(actual)))
        self.put(0x6064, int(round(self.position)))
        if state == FAULT_REACTION and self.velocity == 0.0:
            self.set_state(FAULT)  # 14
        if state == QUICK_STOP and self.velocity == 0.0 and self.get(0x605A) in (1, 2):
            self.set_state(SWITCH_ON_DISABLED)  # the quick stop ramp done: 12 by itself


class Sim:
    """Drives on one bus, run by one thread (start()/stop()); the methods below are for the test's thread."""

    def __init__(self, interface, nodes, boot_delays=None, aborts=None, max_velocities=None, speed_uncertainty=0.0,
                 seed=1, plant=None, axes=None, tick=0.002):
        """plant: (host, port) of the physical plant; axes: {node: (axis index, counts per metre)}; tick: seconds
        between the drives' time steps."""
        self.bus = can.Bus(interface="socketcan", channel=interface, receive_own_messages=False)
        self.tick_s = tick
        try:
            # The kernel counts about 1 kB per CAN frame against the receive buffer: the default holds 0.6 s of a busy
            # bus, and a drive stalled longer (Python on an emulated CPU beside the whole loop) lost heartbeats and
            # faulted.
            self.bus.socket.setsockopt(socket.SOL_SOCKET, 33, 4 << 20)  # SO_RCVBUFFORCE (root)
        except (AttributeError, OSError):
            pass
        self.filters = None
        self.lock = threading.Lock()
        self.rng = random.Random(seed)
        self.speed_uncertainty = speed_uncertainty
        self.sent = 0
        # What the simulator's own thread went through, for a test that fails to tell a slow simulator (its loop
        # behind the bus, on a loaded emulated CPU) from a drive that misbehaved.
        self.frames = 0
        self.max_lag = 0.0        # longest time a frame waited in the socket before the drives read it, s
        self.max_tick_gap = 0.0   # longest time between two time steps, s
        self.running = False
        boot_delays, aborts, max_velocities = boot_delays or {}, aborts or {}, max_velocities or {}
        self.plant = plant
        self.plant_state = {}  # axis -> (position m, velocity m/s), the plant's last answer
        if plant is not None:
            if speed_uncertainty:
                raise ValueError("with a plant the uncertainty is the plant's physics: no --speed-uncertainty")
            self.plant_socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.plant_socket.setblocking(False)
            # The encoder at power-on: the plant's position before the drives boot.
            deadline = time.monotonic() + 30.0
            while set(self.plant_state) != {a for a, _ in axes.values()}:
                if time.monotonic() > deadline:
                    raise RuntimeError("no answer from the plant at %s:%d" % plant)
                for axis, _ in axes.values():
                    self.to_plant(axis, 0.0)
                time.sleep(0.05)
                self.from_plant()
        with self.lock:
            self.drives = {n: Drive(self, n, boot_delays.get(n, 0.0), aborts.get(n), max_velocities.get(n))
                           for n in nodes}
            self.refilter()
            for n, axis in (axes or {}).items():
                self.drives[n].axis = axis
                self.drives[n].position = self.plant_state[axis[0]][0] * axis[1]
                self.drives[n].put(0x6064, int(round(self.drives[n].position)))

    def refilter(self):
        """Only the frames the drives can need, filtered by the kernel (the bus's other traffic costs Python time
        on the emulated CPU): NMT, SYNC, each drive's SDO requests and valid RPDOs, the heartbeat each consumes.
        Called again when a drive's RPDO COB-ID or consumer changes."""
        ids = {0x000, 0x080}
        for d in self.drives.values():
            ids.add(0x600 + d.node)
            for k in (0, 1):
                cob = d.get(0x1400 + k, 1)
                if not cob & 0x80000000:
                    ids.add(cob & 0x7FF)
            if d.get(0x1016, 1) & 0xFFFF:
                ids.add(0x700 + ((d.get(0x1016, 1) >> 16) & 0x7F))
        if ids != self.filters:
            self.filters = ids
            self.bus.set_filters([{"can_id": i, "can_mask": 0x7FF, "extended": False} for i in sorted(ids)])

    def to_plant(self, axis, velocity):
        try:
            self.plant_socket.sendto(struct.pack("<4sB3xd", b"VPL1", axis, velocity), self.plant)
        except OSError:
            pass  # the plant is gone: the drive keeps its last position

    def from_plant(self):
        while True:
            try:
                data = self.plant_socket.recv(64)
            except (BlockingIOError, InterruptedError):
                return
            if len(data) == 24 and data[:4] == b"VPL1":
                _, axis, position, velocity = struct.unpack("<4sB3xdd", data)
                self.plant_state[axis] = (position, velocity)

    def send(self, can_id, data):
        # A struct can_frame written to the bus's socket: python-can's Message and send() cost the emulated CPU
        # several times more, and a drive sends four TPDOs every SYNC.
        try:
            self.bus.socket.send(struct.pack("=IB3x8s", can_id, len(data), bytes(data)))
            self.sent += 1
        except OSError:
            pass  # the interface is down or its queue full: a real drive's frames would be lost the same way

    def run(self):
        last = time.monotonic()
        while self.running:
            try:
                msg = self.bus.recv(timeout=self.tick_s)
            except can.CanError:
                msg = None
                time.sleep(0.01)
            with self.lock:
                # The frames received so far, each at the time the kernel received it, for at most a time step: a drive
                # whose reading falls behind the bus (Python on a loaded emulated CPU) still produces its heartbeat and
                # moves on time. Its heartbeat consumer judges only up to the last frame read, so heartbeats still
                # waiting in the socket are not taken for lost ones.
                started = time.monotonic()
                read_up_to = None
                while msg is not None:
                    now, wall = time.monotonic(), time.time()
                    lag = min(max(0.0, wall - msg.timestamp), 10.0) if msg.timestamp else 0.0
                    if not msg.is_error_frame and not msg.is_remote_frame:
                        self.frames += 1
                        self.max_lag = max(self.max_lag, lag)
                        for drive in self.drives.values():
                            drive.on_frame(msg, now - lag)
                    if now - started >= self.tick_s:
                        read_up_to = now - lag  # the socket may hold more: judged up to this frame
                        break
                    try:
                        msg = self.bus.recv(timeout=0)
                    except can.CanError:
                        msg = None
                now = time.monotonic()
                if now - last >= self.tick_s:
                    if self.plant is not None:
                        self.from_plant()
                    for drive in self.drives.values():
                        drive.tick(now, now - last, read_up_to)
                    self.max_tick_gap = max(self.max_tick_gap, now - last)
                    last = now

    def start(self):
        self.running = True
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()
        return self

    def stop(self):
        self.running = False
        self.thread.join()
        self.bus.shutdown()

    # --- the test's controls ---
    def inject_fault(self, node, code):
        with self.lock:
            self.drives[node].fault(code)

    def silence(self, node, silent=True):
        with self.lock:
            self.drives[node].silent = silent

    def drive(self, node):
        return self.drives[node]

    def load(self):
        """The simulator's own figures: frames read and sent, the longest a frame waited to be read, the longest
        between two time steps (ms)."""
        with self.lock:
            return "frames read %d, sent %d, longest wait of a frame %.0f ms, longest time step %.0f ms" % (
                self.frames, self.sent, self.max_lag * 1e3, self.max_tick_gap * 1e3)

    def snapshot(self, node):
        with self.lock:
            d = self.drives[node]
            return {"state": d.state, "nmt": d.nmt, "position": d.position, "velocity": d.velocity * d.gain,
                    "target": d.get(0x60FF), "max_speed": d.max_speed_seen}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--interface", default="vcan1")
    parser.add_argument("--nodes", type=int, nargs="+", default=[2, 3])
    parser.add_argument("--speed-uncertainty", type=float, default=0.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--duration", type=float, default=0.0, help="seconds (0: until interrupted)")
    parser.add_argument("--plant", help="HOST:PORT of the plant (`visco sim --plant`) the drives move")
    parser.add_argument("--axes", type=int, nargs="+", help="with --plant: each node's axis (0 x, 1 y)")
    parser.add_argument("--counts-per-metre", type=float, nargs="+",
                        help="with --plant: each node's encoder counts per metre of its axis")
    parser.add_argument("--max-velocity", type=int, nargs="+", help="each node's max profile velocity 0x607F")
    parser.add_argument("--tick-ms", type=float, default=2.0, help="the drives' time step, ms")
    args = parser.parse_args()
    plant, axes = None, None
    if args.plant:
        host, _, port = args.plant.rpartition(":")
        if not (args.axes and args.counts_per_metre and len(args.axes) == len(args.counts_per_metre) == len(args.nodes)):
            parser.error("--plant needs --axes and --counts-per-metre, one per node")
        plant = (host, int(port))
        axes = {n: (a, c) for n, a, c in zip(args.nodes, args.axes, args.counts_per_metre)}
    max_velocities = dict(zip(args.nodes, args.max_velocity)) if args.max_velocity else None
    sim = Sim(args.interface, args.nodes, speed_uncertainty=args.speed_uncertainty, seed=args.seed, plant=plant,
              axes=axes, max_velocities=max_velocities, tick=args.tick_ms / 1000.0).start()
    print("drives %s on %s: ready" % (" ".join(map(str, args.nodes)), args.interface), flush=True)

    def on_term(*_):
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, on_term)
    try:
        end = time.monotonic() + args.duration
        while args.duration <= 0 or time.monotonic() < end:
            time.sleep(0.1)
    except KeyboardInterrupt:
        pass
    sim.stop()
    print("drives: " + sim.load(), flush=True)
    for node in args.nodes:
        print(node, sim.snapshot(node), flush=True)
        # What the drive did and when (CLOCK_MONOTONIC seconds): for a test that judges a stop by its cause.
        events = [(t, what, value) for t, what, value in sim.drive(node).history
                  if what in ("heartbeat lost", "emcy") or (what == "state" and value in (QUICK_STOP, FAULT_REACTION,
                                                                                         FAULT, ENABLED))]
        print(json.dumps({"node": node, "events": events[-20:]}), flush=True)


if __name__ == "__main__":
    main()

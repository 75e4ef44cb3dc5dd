#!/usr/bin/python3 -S
"""The whole closed loop through the kernel's interfaces, inside the VM of scripts/hil-vm --vivid (run_in_vm.sh's step
"whole loop"): the robot is two simulated CiA 402 drives (cia402_drive_sim.py, one process per drive, on vcan1) that
move the physics of visco's simulated world (`visco sim --plant`: the scene's C-obstacles, contact, friction, the
velocity cone; the drives' velocities are its input, their encoders its output), and the camera is the world's picture
of the robot where the physics put it, through vivid's video output and V4L2 capture:

  visco sim --plant --v4l2-output /dev/video1 (renders the robot) -> vivid's HDMI output, looped to its HDMI input
  -> visco capture --device /dev/video0 (V4L2 capture; image_t + the calibration on LCM) -> visco track --lcm
  -> visco run --can vcan0 -> the visco protocol on vcan0 -> visco-rt driver --robot cia402 -> CiA 402 on vcan1
  -> the drives -> UDP -> the plant

vivid's loop must be set up before (run_in_vm.sh: vision_v4l2_hil_test --setup-loop). Cases, in this order (the
robot goes on from where the last one left it):
  1. the controller killed (SIGKILL) while the robot moves: the driver's command watchdog quick-stops both drives;
  2. a drive killed while the robot moves: the driver's consumer of its heartbeat (EMCY 0x8130) quick-stops the other,
     the plant brakes the dead drive's axis, the controller stops on the relayed fault;
  3. the driver killed while the robot moves: both drives fault on their consumer of the master's heartbeat, the
     controller stops on the driver's silence;
  4. the goal: `visco run --log` to the end (vision restarted after the log opened, so that the log holds every image
     vision saw); the robot's true position in the goal, the controller's result "done"; then `visco replay LOG
     --check` with no file but the log: vision and every controller period identical.
After each kill the drives and the driver are started afresh (a power cycle). Each stop is judged on the plant's trace
(the robot's true velocity) against the watchdog that should have fired.

Time is scaled for the emulated CPU (QEMU TCG, about 60 times slower than the host for this floating-point code) as
`visco demo --slow-machine` scales it: slower robot, camera and loops, longer watchdogs; the figures are printed with
the settings they were measured with.

usage: whole_loop_test.py BUILD_DIR OUT_DIR     (working directory: the repository top)
"""
import json
import os
import signal
import subprocess
import sys
import time

build, out = sys.argv[1], sys.argv[2]
os.makedirs(out, exist_ok=True)
VISCO, VISCO_RT = build + "/bin/visco", build + "/bin/visco-rt"
HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = "data/scenes/slot.json"
# The default scene's camera, 640x480 (vivid's HDMI loop at its 640x480 timings carries it unscaled).
CALIBRATION = ["--camera", "data/sim/slot_camera.xml", "--extrinsics", "data/sim/slot_extrinsics.json"]
OBJECTS = ["--objects", "data/sim/slot_objects.json"]
CAM = CALIBRATION + OBJECTS
OUTPUT_DEVICE, CAPTURE_DEVICE, CAPTURE_INPUT = "/dev/video1", "/dev/video0", "1"
URL = "udpm://239.255.76.67:7671?ttl=0"
BUS = URL + "&recv_buf_size=4194304"
PLANT = "127.0.0.1:47000"
START = (4.1, 1.7)  # in the plan's preimage, in the slot 0.9 m above the goal
COUNTS = 100000     # counts per metre (x; y counts the other way)
# The rates and time limits, scaled for the emulated CPU. Vision's full detections take 0.5-2 s a frame in the VM
# (the first frame, and every frame after a lost one or a lost tag), and the controller's vision is up to 5 s old
# when a frame reaches it on a loaded host. Its age limit covers that and the next frame's period.
CAMERA_HZ = 1        # frames rendered per second (`visco sim --camera-hz`)
# Frames published per second at most (`visco capture --max-fps`), below vision's rate here: vision takes the
# oldest of the newest four frames waiting, so a camera faster than vision adds up to four frame periods of latency.
CAPTURE_FPS = 0.5
VISION_AGE_MS = 8000
SPEED = 0.1          # m/s, the controller's limit (the demo's 1 m/s divided by 10)
RATE = 25            # Hz, the controller's loop (500 Hz divided by 20)
WATCHDOG_MS = 1000   # the driver's command watchdog (the demo's 500 ms; 100 ms on a real machine)
SYNC_MS = 40         # the drives' SYNC period
HEARTBEAT_MS = 200   # the drives' and the master's heartbeat producer time
HEARTBEAT_TIMEOUT_MS = 1500  # the consumer time both ways on vcan1
QUICK_STOP = 20.0    # m/s^2
# What a stop may take beyond its watchdog on the emulated CPU: SYNC periods, the ramp, the plant's 10 ms trace, and
# the emulated CPU's stalls (the figures are printed; the bound is what CI holds to).
SLACK_S = 0.8
# Files written often go to the guest's memory, copied to OUT_DIR at the end: written through 9p they cost the
# emulated CPU what the loop needs (the plant's trace every 10 ms, candump every frame of both buses).
PLANT_TRACE, CANDUMP = "/tmp/whole_loop_plant_trace.txt", "/tmp/whole_loop_candump.log"
FAILURES = []
FIGURES = []
procs = {}
procs_out = {}  # every process started: its stdout file


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what, flush=True)
    if not ok:
        FAILURES.append(what)
    return ok


def figure(what):
    print("     " + what, flush=True)
    FIGURES.append(what)


def start(name, argv, cpu=None, nice=0):
    log = open(os.path.join(out, name + ".log"), "w")
    stdout = open(os.path.join(out, name + ".out"), "w")
    if cpu is not None:
        # vcan's receive queues are per CPU: a CAN sender that migrates can have its frames reordered (run_in_vm.sh).
        argv = ["/usr/bin/taskset", "-c", str(cpu)] + argv
    if nice:
        argv = ["/usr/bin/nice", "-n", str(nice)] + argv
    p = subprocess.Popen(argv, stdout=stdout, stderr=log)
    p.name, p.log_path, p.out_path, p.started = name, log.name, stdout.name, time.monotonic()
    procs[name] = p
    procs_out[name] = p.out_path
    return p


def text(path):
    try:
        with open(path, errors="replace") as f:
            return f.read()
    except OSError:
        return ""


def last_json(path, key=None):
    """The last JSON object line of a file (with `key`: the last that has it)."""
    for line in reversed(text(path).splitlines()):
        if line.startswith("{"):
            try:
                j = json.loads(line)
            except ValueError:
                continue
            if key is None or key in j:
                return j
    return {}


def wait_for(predicate, seconds, step=0.05):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(step)
    return predicate()


CPU = {}  # process kind (its name before "_", without a node number) -> [CPU seconds, seconds alive]


def poll(p):
    """Popen.poll, reaping with wait4 so that the process's CPU time (user + system) is added to its kind's."""
    if p.returncode is None:
        pid, status, usage = os.wait4(p.pid, os.WNOHANG)
        if pid:
            p.returncode = os.waitstatus_to_exitcode(status)
            kind = CPU.setdefault(p.name.split("_")[0].rstrip("0123456789"), [0.0, 0.0])
            kind[0] += usage.ru_utime + usage.ru_stime
            kind[1] += time.monotonic() - p.started
    return p.returncode


def wait(p, seconds=None):
    end = None if seconds is None else time.monotonic() + seconds
    while poll(p) is None:
        if end is not None and time.monotonic() > end:
            return None
        time.sleep(0.02)
    return p.returncode


def stop(name, sig=signal.SIGTERM, seconds=8.0):
    p = procs.pop(name, None)
    if p is None:
        return None
    if poll(p) is None:
        p.send_signal(sig)
        if wait(p, seconds) is None:
            p.kill()
            wait(p)
    return p.returncode


TRACE = {"rows": [], "offset": 0}


def trace():
    """The plant's trace: (t, x, y, vx, vy, contact) every 10 ms, read on from where the last call stopped (the
    emulated CPU is the scarce resource here)."""
    try:
        with open(PLANT_TRACE) as f:
            f.seek(TRACE["offset"])
            chunk = f.read()
    except OSError:
        return TRACE["rows"]
    end = chunk.rfind("\n") + 1
    TRACE["offset"] += end
    for line in chunk[:end].splitlines():
        fields = line.split()
        if len(fields) == 6:
            TRACE["rows"].append(tuple(float(v) for v in fields))
    return TRACE["rows"]


def speed(row):
    return (row[3] ** 2 + row[4] ** 2) ** 0.5


def moving_since(t0, threshold=0.03):
    rows = trace()
    return bool(rows) and rows[-1][0] >= t0 and speed(rows[-1]) > threshold


def slowing():
    """The robot's speed fell over the trace's last 50 ms (a stop under way)."""
    rows = trace()
    return len(rows) < 6 or speed(rows[-1]) < speed(rows[-6]) - 0.005


def vision_frames(tag):
    return [line for line in text(os.path.join(out, "track_%s.jsonl" % tag)).splitlines() if '"seq"' in line]


def still_at(t_kill, threshold=1e-3):
    """The first time after t_kill from which the robot stays still (None: it never did)."""
    rows = [r for r in trace() if r[0] >= t_kill]
    still = None
    for r in rows:
        if speed(r) > threshold:
            still = None
        elif still is None:
            still = r[0]
    return still


def drives_config():
    path = os.path.join(out, "drives.json")
    with open(path, "w") as f:
        json.dump({"format": "visco-cia402-1", "interface": "vcan1", "mode": "cyclic_synchronous_velocity",
                   "sync_period_ms": SYNC_MS, "heartbeat_ms": HEARTBEAT_MS,
                   "heartbeat_timeout_ms": HEARTBEAT_TIMEOUT_MS, "boot_timeout_ms": 10000, "sdo_timeout_ms": 1000,
                   "state_timeout_ms": 3000, "quick_stop_option": 6, "workspace": [0, 0, 10, 8],
                   "axes": [{"node": 2, "counts_per_metre": COUNTS, "acceleration": 2.0,
                             "quick_stop_deceleration": QUICK_STOP},
                            {"node": 3, "counts_per_metre": -COUNTS, "acceleration": 2.0,
                             "quick_stop_deceleration": QUICK_STOP}]}, f)
    return path


def start_drive(node, axis, counts, tag):
    return start("drive%d_%s" % (node, tag),
                 ["/usr/bin/python3", "-S", HERE + "/cia402_drive_sim.py", "--interface", "vcan1", "--nodes",
                  str(node), "--plant", PLANT, "--axes", str(axis), "--counts-per-metre", str(counts), "--tick-ms",
                  "20"], cpu=0)


def start_robot(tag):
    """Power on: both drives (they read their encoders from the plant), then the driver (their NMT master)."""
    d2, d3 = start_drive(2, 0, COUNTS, tag), start_drive(3, 1, -COUNTS, tag)
    ready = wait_for(lambda: "ready" in text(d2.out_path) and "ready" in text(d3.out_path), 60)
    if not check(ready, "%s: drives 2 and 3 up on vcan1, their encoders read from the plant" % tag):
        return False
    driver = start("driver_" + tag, [VISCO_RT, "driver", "--can", "vcan0", "--node", "1", "--watchdog-ms",
                                     str(WATCHDOG_MS), "--heartbeat-ms", str(HEARTBEAT_MS), "--status-period-ms",
                                     "50", "--period-us", "5000", "--max-speed", "0.5", "--robot", "cia402",
                                     "--robot-config", drives_config()], cpu=1)
    up = wait_for(lambda: "switched on" in text(driver.log_path) or poll(driver) is not None, 40)
    return check(up and poll(driver) is None, "%s: visco-rt driver --robot cia402 configured and switched on "
                                                "both drives" % tag)


def stop_robot(tag):
    for name in ("driver_" + tag, "drive2_" + tag, "drive3_" + tag):
        stop(name)


def controller(tag, extra=(), binary=VISCO_RT):
    """`visco-rt run` of the plan on vcan0 (the drives enabled by its reset): the real-time binary, without planner
    and vision, starts in a second where the whole `visco` took 30 s beside the camera on the emulated CPU (only the
    whole one writes logs)."""
    argv = [binary, "run", os.path.join(out, "plan.json"), "--scene", SCENE, "--rays", os.path.join(out, "rays.json"),
            "--can", "vcan0", "--node", "1", "--lcm-url", BUS, "--max-speed", str(SPEED), "--max-accel", "1",
            "--max-vision-age-ms", str(VISION_AGE_MS), "--max-hold", "40", "--startup-timeout", "120",
            "--status-timeout-ms", "2000", "--heartbeat-timeout-ms", "2000", "--rate", str(RATE), "--telemetry-hz",
            "5", "--no-realtime"] + CAM + list(extra)
    return start("run_" + tag, argv, cpu=0)


def start_vision(tag):
    """`visco track --lcm` with the calibration from the bus (the camera process publishes it)."""
    return start("track_" + tag, [VISCO, "track", "--lcm", "--lcm-url", BUS, "--calibration-timeout", "120",
                                  "--out", os.path.join(out, "track_%s.jsonl" % tag)] + OBJECTS, nice=5)


def drive_events(name):
    """The drive process's events (its last line per node, written when it ends): [(t, what, value)]."""
    return [tuple(e) for e in last_json(procs_out.get(name, ""), "events").get("events", [])]


def kill_case(tag, victim, limit_s, mechanism):
    """Runs the controller until the robot moves, kills a process while it moves, judges the stop on the plant's
    trace, and checks that the stop came from the watchdog meant to catch that death (`mechanism`)."""
    if not start_robot(tag):
        return
    run = controller(tag)
    t_run = time.monotonic()
    moving = wait_for(lambda: moving_since(t_run) or poll(run) is not None, 120, 0.2)
    if not check(moving and poll(run) is None, "%s: the controller moves the robot (true speed above 3 cm/s, "
                                                "%.1f s after its start)" % (tag, time.monotonic() - t_run)):
        print(text(run.log_path)[-2000:])
        stop("run_" + tag)
        stop_robot(tag)
        return
    # Killed while the robot moves, just after vision delivered a frame (so that no hold for a late frame stops the
    # robot meanwhile): the trace's newest sample at most 100 ms old, above 3 cm/s and not slowing down.
    frames = len(vision_frames("kills"))
    wait_for(lambda: len(vision_frames("kills")) > frames, 20, 0.05)
    fresh = wait_for(lambda: moving_since(time.monotonic() - 0.1) and not slowing(), 20, 0.02)
    v_kill = speed(trace()[-1])
    log_lines = len(text(os.path.join(out, "driver_%s.log" % tag)).splitlines())
    t_kill = time.monotonic()
    procs[victim].send_signal(signal.SIGKILL)
    wait(procs[victim])
    check(fresh, "%s: killed while the robot moved at %.0f mm/s" % (tag, v_kill * 1e3))
    # The controller, where it lives on, must stop too (it is told by the driver, or misses the driver).
    if victim != "run_" + tag:
        ended = wait_for(lambda: poll(run) is not None, limit_s + 4, 0.1)
        t_end = time.monotonic()
    time.sleep(max(0.0, t_kill + limit_s + SLACK_S + 0.5 - time.monotonic()))
    t_still = still_at(t_kill)
    taken = (t_still - t_kill) if t_still is not None else float("inf")
    check(taken <= limit_s + SLACK_S, "%s: %s killed -> the robot still (true speed < 1 mm/s) after %.0f ms "
          "(limit %.0f ms + %.0f ms)" % (tag, victim.split("_")[0], taken * 1e3, limit_s * 1e3, SLACK_S * 1e3))
    if victim != "run_" + tag:
        summary = last_json(run.out_path)
        check(ended and summary.get("result") == "stopped",
              "%s: the controller stopped %.0f ms after the kill: %s" %
              (tag, (t_end - t_kill) * 1e3, summary.get("reason", "(no summary)")))
    stop("run_" + tag)
    stop_robot(tag)
    # What the driver logged after the kill.
    driver_log = "\n".join(text(os.path.join(out, "driver_%s.log" % tag)).splitlines()[log_lines:])
    mechanism(tag, t_kill, taken, limit_s, driver_log)


def controller_killed(tag, t_kill, taken, limit_s, driver_log):
    fired = [l for l in driver_log.splitlines() if "no valid command for" in l and "watchdog" in l]
    check(len(fired) > 0, "%s: the driver's command watchdog (%d ms) fired: %s" %
          (tag, WATCHDOG_MS, fired[0].split(" ", 3)[-1] if fired else "no such line in the driver's log"))
    figure("controller killed: the robot still after %.0f ms (the driver's command watchdog, %d ms, quick-stopped "
           "both drives)" % (taken * 1e3, WATCHDOG_MS))


def drive_killed(tag, t_kill, taken, limit_s, driver_log):
    fired = [l for l in driver_log.splitlines() if "0x8130" in l]
    check(len(fired) > 0, "%s: the driver's consumer of node 3's heartbeat (%d ms) fired: %s" %
          (tag, HEARTBEAT_TIMEOUT_MS, fired[0].split(" ", 3)[-1] if fired else "no EMCY 0x8130 in the driver's log"))
    stopped = [t for t, what, value in drive_events("drive2_" + tag) if what == "state" and value == "QUICK STOP ACTIVE"
               and t >= t_kill]
    check(stopped and stopped[0] - t_kill <= limit_s + SLACK_S, "%s: node 2 quick-stopped %s after the kill" %
          (tag, "%.0f ms" % ((stopped[0] - t_kill) * 1e3) if stopped else "(not: no QUICK STOP ACTIVE)"))
    figure("a drive (node 3) killed: the robot still after %.0f ms (the driver's consumer of its heartbeat, %d ms: "
           "EMCY 0x8130, node 2 quick-stopped, the plant braked the dead drive's axis)" %
           (taken * 1e3, HEARTBEAT_TIMEOUT_MS))


def driver_killed(tag, t_kill, taken, limit_s, driver_log):
    for node in (2, 3):
        lost = [t for t, what, value in drive_events("drive%d_%s" % (node, tag)) if what == "heartbeat lost"
                and t >= t_kill]
        faulted = [t for t, what, value in drive_events("drive%d_%s" % (node, tag)) if what == "state"
                   and value == "FAULT" and t >= t_kill]
        check(lost and faulted and faulted[0] - t_kill <= limit_s + SLACK_S,
              "%s: node %d lost the master's heartbeat %s after the kill and faulted %s after" %
              (tag, node, "%.0f ms" % ((lost[0] - t_kill) * 1e3) if lost else "(not)",
               "%.0f ms" % ((faulted[0] - t_kill) * 1e3) if faulted else "(not)"))
    figure("the driver killed: the robot still after %.0f ms (each drive's consumer of the master's heartbeat, %d ms: "
           "both drives FAULT, quick stop ramp)" % (taken * 1e3, HEARTBEAT_TIMEOUT_MS))


def frame_costs(path):
    """Vision's latency (capture time -> output) per frame of a track output, and how many were full detections."""
    lat, full = [], 0
    for line in text(path).splitlines():
        if '"seq"' in line:
            try:
                j = json.loads(line)
            except ValueError:
                continue
            lat.append(j.get("latency_ms", 0.0))
            full += bool(j.get("full_detection"))
    lat.sort()
    return lat, full


def main():
    subprocess.call(["ip", "link", "set", "lo", "up"])
    subprocess.call(["ip", "link", "set", "lo", "multicast", "on"])
    subprocess.call(["ip", "route", "add", "224.0.0.0/4", "dev", "lo"], stderr=subprocess.DEVNULL)
    # A 640x480 image_t is 300 kB: the guest's default socket buffer limit holds one.
    with open("/proc/sys/net/core/rmem_max", "w") as f:
        f.write("8388608")
    t0 = time.monotonic()
    for name in os.listdir(out):  # what an earlier run left
        if name.endswith((".log", ".out", ".txt", ".lcmlog", ".jsonl")):
            os.remove(os.path.join(out, name))
    if not os.path.exists(os.path.join(out, "plan.json")):  # the host's CTest fixture plans it (seconds, not minutes)
        subprocess.check_call([VISCO, "plan", SCENE, "--out", os.path.join(out, "plan.json")])
        subprocess.check_call([VISCO, "vcrays", SCENE, "--out", os.path.join(out, "rays.json")])
    dump = subprocess.Popen(["candump", "-L", "-D", "-r", "16777216", "vcan0", "vcan1"],
                            stdout=open(CANDUMP, "w"), stderr=subprocess.STDOUT)
    # The camera and vision below the drives, the driver and the controller: their watchdogs must not fire because
    # a frame takes a second to render and another through vision on the emulated CPU. The world renders without
    # supersampling, noise or blur (per-pixel floating point, what the emulator does slowest).
    sim = start("sim", [VISCO, "sim", SCENE, "--plant", PLANT, "--plant-period-ms", "2", "--plant-axis-timeout-ms",
                        "400", "--plant-trace", PLANT_TRACE, "--start", str(START[0]),
                        str(START[1]), "--seed", "5", "--max-acceleration", "50", "--lcm-url", BUS, "--camera-hz",
                        str(CAMERA_HZ), "--supersample", "1", "--image-noise", "0", "--blur-px", "0",
                        "--v4l2-output", OUTPUT_DEVICE] + CAM, nice=5)
    up = wait_for(lambda: len(trace()) > 0 and "sim: scene" in text(sim.log_path) or poll(sim) is not None, 120,
                  0.2)
    if not check(up and poll(sim) is None, "visco sim --plant --v4l2-output up (the plant steps, the camera renders "
                                            "to vivid's output)"):
        print(text(sim.log_path)[-3000:])
        return finish(dump)
    # The camera process, as a real camera's: the HDMI input shows what the world wrote to the output.
    capture = start("capture", [VISCO, "capture", "--device", CAPTURE_DEVICE, "--input", CAPTURE_INPUT, "--width",
                                "640", "--height", "480", "--pixel-format", "GREY", "--max-fps", str(CAPTURE_FPS),
                                "--timeout-ms", "5000", "--lcm-url", URL] + CALIBRATION, nice=5)
    start_vision("kills")
    seen = wait_for(lambda: '"seq"' in text(os.path.join(out, "track_kills.jsonl")) or poll(capture) is not None,
                    120, 0.2)
    if not check(seen and poll(capture) is None, "the world's frames through vivid, visco capture and visco track "
                                                  "(the robot seen %.1f s after the start)" % (time.monotonic() - t0)):
        print(text(capture.log_path)[-2000:])
        return finish(dump)

    ramp = SPEED / QUICK_STOP
    kill_case("controller", "run_controller", WATCHDOG_MS / 1e3 + 2 * SYNC_MS / 1e3 + ramp, controller_killed)
    kill_case("drive", "drive3_drive", HEARTBEAT_TIMEOUT_MS / 1e3 + 2 * SYNC_MS / 1e3 + ramp, drive_killed)
    kill_case("driver", "driver_driver", HEARTBEAT_TIMEOUT_MS / 1e3 + 2 * SYNC_MS / 1e3 + ramp, driver_killed)
    stop("track_kills", signal.SIGINT)

    # The goal, logged for `visco replay --check`: the controller's log opens first, then vision starts afresh, so
    # the log holds every image vision saw.
    # The whole `visco` (for its --log) starts first, then vision, then the robot: the whole `visco` takes many
    # seconds to start on the emulated CPU, and a controller commanding the robot beside them was starved past the
    # driver's watchdog. The log is written to the guest's memory (through 9p writes stall on the emulated CPU).
    log = "/tmp/whole_loop_controller.lcmlog"
    if os.path.exists(log):
        os.remove(log)
    run = controller("goal", ["--log", log], binary=VISCO)
    t_run = time.monotonic()
    opened = wait_for(lambda: os.path.exists(log) or poll(run) is not None, 120, 0.2)
    time.sleep(0.5)
    start_vision("goal")
    seen = wait_for(lambda: '"seq"' in text(os.path.join(out, "track_goal.jsonl")) or poll(run) is not None, 120, 0.2)
    if check(opened and seen and poll(run) is None, "goal: visco run --log and vision started (%.1f s)" %
             (time.monotonic() - t_run)) and start_robot("goal"):
        ended = wait_for(lambda: poll(run) is not None, 240, 0.2)
        check(ended, "goal: the controller ended within 240 s")
        stop("run_goal")
        summary = last_json(run.out_path)
        print("     controller: " + json.dumps(summary), flush=True)
        check(summary.get("result") == "done", "goal: the controller recognised the goal (result %r, %s)" %
              (summary.get("result"), summary.get("reason", "")))
        rows = trace()
        x, y = rows[-1][1], rows[-1][2]
        goal = json.load(open(SCENE))["goal"]["polygon"]
        xs, ys = [p[0] for p in goal], [p[1] for p in goal]
        check(min(xs) <= x <= max(xs) and min(ys) <= y <= max(ys),
              "goal: the robot's true position (%.3f, %.3f) is in the goal (the plant's physics)" % (x, y))
        figure("goal run: %.1f s from the controller's start, %s commands sent" %
               (time.monotonic() - t_run, summary.get("commands_sent")))
        stop_robot("goal")
        stop("track_goal", signal.SIGINT)
        # The run's log through vision and the controller again, here: with no file but the log (the calibration,
        # vision's configuration, the strategy's files are named or held in it).
        t_replay = time.monotonic()
        replay = subprocess.run([VISCO, "replay", log, "--check", "--fast", "--no-publish"], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, universal_newlines=True)
        subprocess.call(["cp", log, os.path.join(out, "controller.lcmlog")])
        with open(os.path.join(out, "replay.out"), "w") as f:
            f.write(replay.stdout + replay.stderr)
        lines = [l for l in replay.stdout.splitlines() if l.startswith("{")]
        result = json.loads(lines[-1]) if lines else {}
        check(replay.returncode == 0 and result.get("identical") is True and result.get("frames", 0) > 0,
              "goal: visco replay controller.lcmlog --check (no other file): identical (exit %d; %d frames, %s "
              "vision messages, %s controller periods compared; %.1f s)" %
              (replay.returncode, result.get("frames", 0), result.get("compared"),
               (result.get("control") or {}).get("compared"), time.monotonic() - t_replay))
        if replay.returncode != 0:
            print(replay.stderr[-1500:])
    return finish(dump)


def finish(dump):
    for name in list(procs):
        stop(name, signal.SIGINT)
    dump.send_signal(signal.SIGTERM)
    dump.wait()
    for path, name in ((PLANT_TRACE, "plant_trace.txt"), (CANDUMP, "candump.log")):
        subprocess.call(["cp", path, os.path.join(out, name)])
    # What each stage of the camera's path cost here.
    world = last_json(os.path.join(out, "sim.out"))
    if world:
        figure("world: %d frames rendered and written to %s, %.0f ms per render; plant: %s" %
               (world.get("frames", 0), OUTPUT_DEVICE, world.get("mean_render_ms", 0), json.dumps(world.get("plant"))))
    cap = last_json(os.path.join(out, "capture.out"), "summary").get("summary")
    if cap:
        figure("capture: %d frames published (%d held back, %d dropped by vivid), %.1f ms CPU per frame, capture -> "
               "publish p50 %.0f ms" % (cap["frames"], cap["held_back"], cap["dropped"], cap["cpu_ms_per_frame"],
                                        cap["capture_to_publish_ms"]["p50"]))
    for tag in ("kills", "goal"):
        lat, full = frame_costs(os.path.join(out, "track_%s.jsonl" % tag))
        if lat:
            figure("vision (%s): %d frames, %d full detections; latency capture -> output p50 %.0f ms, max %.0f ms" %
                   (tag, len(lat), full, lat[len(lat) // 2], lat[-1]))
    for kind, (cpu, alive) in sorted(CPU.items(), key=lambda kv: -kv[1][0]):
        figure("CPU: %-8s %6.1f s over %6.1f s alive (%3.0f %% of one emulated CPU)" %
               (kind, cpu, alive, 100 * cpu / max(alive, 1e-9)))
    print("whole loop: %d failure(s)" % len(FAILURES), flush=True)
    return 1 if FAILURES else 0


if __name__ == "__main__":
    sys.exit(main())

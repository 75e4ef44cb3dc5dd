#!/usr/bin/env bash
# `visco demo` as a user runs it: the embedded default scene is planned and executed in closed loop by separate
# processes over LCM (the driver process with the simulated robot, the rendered camera, vision, controller,
# lcm-logger), each from a parameter file; exit 0 with the
# goal recognisably reached, every output written (the pictures drawn, the log readable by LCM's own tools). Ctrl-C
# stops every process it started (no orphans) and exits non-zero.
set -uo pipefail
visco="$1"
tmp=$(mktemp -d)
trap 'pkill -f "$tmp" 2>/dev/null; rm -rf "$tmp"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

"$visco" demo --out "$tmp/d" >"$tmp/out.txt" 2>"$tmp/err.txt"
status=$?
[[ $status -eq 0 ]] || { fail "visco demo exited $status"; cat "$tmp/out.txt" "$tmp/err.txt"; tail -20 "$tmp"/d/*.log; }
grep -q "1 of 1 run(s) reached the goal recognisably" "$tmp/out.txt" || fail "summary line: $(cat "$tmp/out.txt")"
grep -q "visco demo: planning" "$tmp/err.txt" || fail "no progress on stderr"
for f in scene.json world.json rays.json plan.json plan.svg run.svg run.lcmlog summary.json run.log driver.json camera.json track.jsonl; do
  [[ -s "$tmp/d/$f" ]] || fail "$f missing or empty"
done
python3 - "$tmp/d" <<'PY' || fail "outputs are not what the summary says"
import json, re, sys, xml.etree.ElementTree as ET
d = sys.argv[1]
s = json.load(open(d + "/summary.json"))
run = s["runs"][0]
assert s["camera"] == "rendered" and s["transport"] == "lcm", s
assert run["success"] and run["result"] == "done" and run["goal_error_m"] == 0.0, run
assert run["steps_completed"] == s["steps"] >= 1, run
assert run["commands_sent"] > 100 and run["logged_messages"] > 100, run
plan = json.load(open(d + "/plan.json"))
assert plan["feasible"] and len(plan["steps"]) == s["steps"], plan
svg = open(d + "/run.svg").read()
ET.fromstring(svg.split("?>", 1)[1])
assert len(re.findall('class="trajectory"', svg)) > 10, "run.svg draws no trajectory"
# run.svg draws the camera and the rays the plan uses, with a legend in words.
assert 'class="camera"' in svg and 'class="active-ray step' in svg, "run.svg draws no camera or rays"
legend = re.findall(r'class="legend" fill="black">([^<]*)<', svg)
assert any(w.startswith("executed trajectory") for w in legend) and "start region" in legend, legend
ET.fromstring(open(d + "/plan.svg").read().split("?>", 1)[1])
# Each process ran as its own program from its parameter file, kept in params/; the driver is the real-time binary.
cmds = run["commands"]
assert set(cmds) == {"lcm-logger", "driver", "camera", "track", "run"}, cmds
assert cmds["driver"][0].endswith("visco-rt") and cmds["driver"][1] == "driver", cmds["driver"]
for name, command in (("driver", "driver"), ("camera", "sim"), ("track", "track"), ("run", "run")):
    argv = cmds[name]
    params = argv[argv.index("--config") + 1]
    assert params == d + "/params/" + name + ".json", argv
    p = json.load(open(params))
    assert list(p) == [command] and p[command], p
assert json.load(open(d + "/params/driver.json"))["driver"]["world"] == d + "/world.json"
world = json.load(open(d + "/world.json"))
assert world["format"] == "visco-world-1" and len(world["obstacles"]) >= 1, world
# The driver's summary holds the robot's true final position: the one the demo judged.
drv = json.load(open(d + "/driver.json"))
assert drv["position"] == run["final_position"], (drv, run)
PY
# The log is lcm-logger's format: LCM's own player reads it.
if command -v lcm-logplayer >/dev/null; then
  timeout 20 lcm-logplayer --speed=20 --lcm-url="udpm://239.255.76.67:$((30000 + $$ % 20000))?ttl=0" \
    "$tmp/d/run.lcmlog" >/dev/null 2>&1 || fail "lcm-logplayer cannot play run.lcmlog"
fi

# Ctrl-C during the run: every process stops, the demo exits non-zero.
"$visco" demo --out "$tmp/int" >"$tmp/int.out" 2>"$tmp/int.err" &
demo=$!
for _ in $(seq 1 300); do
  grep -q "executing" "$tmp/int.err" 2>/dev/null && break
  sleep 0.1
done
sleep 2
kill -INT $demo
wait $demo
status=$?
[[ $status -ne 0 ]] || fail "an interrupted demo exited 0"
sleep 1
left=$(pgrep -f "$tmp/int" | wc -l)
[[ $left -eq 0 ]] || { fail "$left process(es) left after Ctrl-C"; pgrep -af "$tmp/int"; }
grep -q '"interrupted": true' "$tmp/int/summary.json" || fail "the summary does not say it was interrupted"

# Bad input: exit 2 naming what is wrong.
out=$("$visco" demo --scene "$tmp/nonexistent.json" --out "$tmp/bad" 2>&1); status=$?
[[ $status -eq 2 ]] || fail "a missing scene exited $status, expected 2: $out"
out=$("$visco" demo --runs 0 --out "$tmp/bad" 2>&1); status=$?
[[ $status -eq 2 ]] || fail "--runs 0 exited $status, expected 2: $out"
out=$("$visco" demo --slow-machine 0.5 --out "$tmp/bad" 2>&1); status=$?
[[ $status -eq 2 ]] || fail "--slow-machine 0.5 exited $status, expected 2: $out"
[[ $out == *"--slow-machine"* ]] || fail "the --slow-machine error does not name the option: $out"
out=$("$visco" demo --v4l2-output /dev/video1 --out "$tmp/bad" 2>&1); status=$?
[[ $status -eq 2 && $out == *"--v4l2-capture"* ]] || fail "--v4l2-output alone exited $status, expected 2: $out"
out=$("$visco" demo --v4l2-output /dev/video1 --v4l2-capture /dev/video0 --lockstep --out "$tmp/bad" 2>&1); status=$?
[[ $status -eq 2 ]] || fail "--v4l2-output with --lockstep exited $status, expected 2: $out"
# The rendered camera's V4L2 output: a path that is no device, a device that is no V4L2 output.
data="$(dirname "$0")/../../data"
cam=(--objects "$data/sim/slot_objects.json" --camera "$data/sim/slot_camera.xml" --extrinsics
     "$data/sim/slot_extrinsics.json")
out=$("$visco" sim "$data/scenes/slot.json" --no-driver "${cam[@]}" --v4l2-output "$tmp/none" 2>&1); status=$?
[[ $status -eq 2 && $out == *"$tmp/none"*"no such device"* ]] || fail "a missing output device exited $status: $out"
out=$("$visco" sim "$data/scenes/slot.json" --no-driver "${cam[@]}" --v4l2-output /dev/null 2>&1); status=$?
[[ $status -eq 2 && $out == *"/dev/null"*"not a V4L2 device"* ]] || fail "/dev/null as output exited $status: $out"
out=$("$visco" sim "$data/scenes/slot.json" --no-driver "${cam[@]}" --v4l2-output /dev/null --blackout 1 1 2>&1)
status=$?
[[ $status -eq 2 && $out == *"--blackout"* ]] || fail "--blackout with --v4l2-output exited $status: $out"

echo "$(( failures == 0 ? 1 : 0 )) passed, $(( failures == 0 ? 0 : 1 )) failed"
exit $(( failures == 0 ? 0 : 1 ))

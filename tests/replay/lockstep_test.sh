#!/usr/bin/env bash
# Lockstep runs ("two runs with the same seed write logs with identical payloads"):
#   1. `visco demo --lockstep` plans the default scene and runs it as one process on a simulated clock
#      (`visco sim --lockstep`): it must reach the goal (exit 0; the summary's outcome).
#   2. The same lockstep run again, from the demo's parameter file, with the same seed: the log is byte-identical
#      (payloads and, since they are simulated, timestamps).
#   3. Another seed: the payloads differ (compared event by event).
#   4. `visco replay LOG --check` replays the lockstep log through the live vision and control code: identical, every
#      frame and every controller period compared.
#   5. Bad input: exit 2 with the option named.
# usage: lockstep_test.sh VISCO [SECONDS]   (SECONDS: a simulated time limit for sanitizer builds; then no goal)
set -uo pipefail
visco="$1"
limit="${2:-}"
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
here=tests/replay
cam=(--camera data/sim/slot_camera.xml --extrinsics data/sim/slot_extrinsics.json --objects data/sim/slot_objects.json)
tmp=$(mktemp -d)
trap '[[ -n "${KEEP_TMP:-}" ]] && echo "kept $tmp" || rm -rf "$tmp"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
field() { python3 -S -c 'import json, sys; print(json.load(open(sys.argv[1]))[sys.argv[2]])' "$@"; }

# 1. The demo in lockstep (plans, then runs one process).
start=$(date +%s.%N)
if [[ -z "$limit" ]]; then
  "$visco" demo --lockstep --seed 7 --out "$tmp/demo" >"$tmp/demo.out" 2>"$tmp/demo.log"
  status=$?
  cat "$tmp/demo.out"
  [[ $status -eq 0 ]] || { fail "visco demo --lockstep exited $status"; tail -n 5 "$tmp/demo.log" "$tmp/demo/lockstep.log"; }
  python3 -S -c '
import json, sys
s = json.load(open(sys.argv[1]))
run = s["runs"][0]
ok = s["lockstep"] and run["success"] and run["result"] == "done" and run["goal_error_m"] == 0 and run["visual_events"] > 0
print("demo --lockstep: %s (%s), %.1f s simulated in %.1f s, %d commands, %d visual events, final error %s m" %
      (run["result"], run["reason"], run["simulated_s"], run["time_s"], run["commands_sent"], run["visual_events"],
       run["goal_error_m"]))
sys.exit(0 if ok else 1)' "$tmp/demo/summary.json" || fail "the lockstep demo did not reach the goal recognisably"
  params="$tmp/demo/params/lockstep.json"
  first="$tmp/demo/run.lcmlog"
else
  # Sanitizer builds: the checked-in plan, a few simulated seconds (the loop, the log and the replay, not the goal).
  # The parameter file lies in the temporary folder and names files relative to itself: absolute paths here.
  python3 -S -c '
import json, os, sys
root = sys.argv[3]
def at(name): return os.path.join(root, name)
print(json.dumps({"sim": {"lockstep": True, "strategy": at("tests/control/data/slot_e2e_plan.json"),
                          "rays": at(sys.argv[1]), "camera-hz": 15, "supersample": 1, "latency-ms": 5,
                          "image-noise": 2, "blur-px": 0.5, "seed": 7, "watchdog-ms": 500,
                          "camera": at("data/sim/slot_camera.xml"), "extrinsics": at("data/sim/slot_extrinsics.json"),
                          "objects": at("data/sim/slot_objects.json"), "duration": float(sys.argv[2])}}))' \
    "$here/data/slot_e2e_rays.json" "$limit" "$PWD" >"$tmp/params.json"
  params="$tmp/params.json"
  first="$tmp/first.lcmlog"
  "$visco" sim tests/control/data/slot_e2e_scene.json --config "$params" --log "$first" >"$tmp/first.json" \
    2>"$tmp/first.log"
  status=$?
  [[ $status -eq 0 || $status -eq 1 ]] || { fail "the first lockstep run exited $status"; tail -n 3 "$tmp/first.log"; }
  grep -q '"result":"stopped"' "$tmp/first.json" || fail "the limited run did not end with its e-stop"
fi
scene_arg() { python3 -S -c 'import json, sys; print(json.load(open(sys.argv[1]))["runs"][0]["commands"]["lockstep"][2])' "$1"; }
if [[ -z "$limit" ]]; then scene="$(scene_arg "$tmp/demo/summary.json")"; else scene=tests/control/data/slot_e2e_scene.json; fi

# 2. The same seed again: the same bytes.
t0=$(date +%s.%N)
"$visco" sim "$scene" --config "$params" --log "$tmp/again.lcmlog" >"$tmp/again.json" 2>"$tmp/again.log"
status=$?
t1=$(date +%s.%N)
[[ -z "$limit" && $status -ne 0 ]] && { fail "the repeated lockstep run exited $status"; tail -n 3 "$tmp/again.log"; }
grep -q "event log $tmp/again.lcmlog: [0-9]* event(s), [0-9]* bytes written; 0 dropped" "$tmp/again.log" ||
  fail "the repeated run's log was not written without drops"
if cmp "$first" "$tmp/again.lcmlog"; then
  echo "same seed: byte-identical logs ($(stat -c %s "$first") bytes, $(grep -o '[0-9]* event(s)' "$tmp/again.log"))," \
    "$(field "$tmp/again.json" simulated_s) s simulated in $(python3 -S -c "print('%.1f' % ($t1 - $t0))") s"
else
  fail "two lockstep runs with the same seed wrote different logs"
  python3 -S $here/logtool.py diff "$first" "$tmp/again.lcmlog"
fi

# 3. Another seed: different payloads -- the driver's session nonces, the camera's noise, the adversary's motion.
#    (The first two simulated seconds suffice; the same seed for as long gives the first run's payloads up to there.)
"$visco" sim "$scene" --config "$params" --seed 8 --duration 2 --log "$tmp/other.lcmlog" >"$tmp/other.json" \
  2>"$tmp/other.log"
"$visco" sim "$scene" --config "$params" --duration 2 --log "$tmp/short.lcmlog" >"$tmp/short.json" 2>"$tmp/short.log"
[[ -s "$tmp/other.lcmlog" && -s "$tmp/short.lcmlog" ]] || fail "the two-second runs wrote no log"
python3 -S $here/logtool.py diff "$first" "$tmp/short.lcmlog" - 1.9 ||
  fail "the same seed for two seconds gave other payloads than the first run's"
for channel in - VISCO_CAMERA_IMAGE VISCO_SIM_TRUTH VISCO_ROBOT_ESTIMATE; do
  python3 -S $here/logtool.py diff "$first" "$tmp/other.lcmlog" $channel 1.9
  status=$?
  [[ $status -eq 1 ]] || fail "another seed gave the same payloads on ${channel/-/every channel} (logtool diff exited $status)"
done

# 3b. The camera's frames as PNG (lossless): the same two seconds, a smaller log, and the same pixels for vision (it
#     replays --check identically, every frame's pixel digest compared, with no file but the log).
#     (A run cut by --duration ends with its e-stop, exit 1, as the two-second runs above.)
"$visco" sim "$scene" --config "$params" --duration 2 --png-level 1 --log "$tmp/png.lcmlog" >"$tmp/png.json" \
  2>"$tmp/png.log"
grep -q "event log $tmp/png.lcmlog: [0-9]* event(s), [0-9]* bytes written; 0 dropped" "$tmp/png.log" ||
  { fail "the two-second PNG run wrote no whole log"; tail -n 3 "$tmp/png.log"; }
"$visco" replay "$tmp/png.lcmlog" --fast --check --no-publish >"$tmp/png_replay.json" 2>"$tmp/png_replay.log" ||
  { fail "replay --check of the PNG log exited $?"; tail -n 3 "$tmp/png_replay.log"; }
python3 -S - "$tmp/short.lcmlog" "$tmp/png.lcmlog" "$tmp/png_replay.json" <<'PY' || fail "PNG log"
import json, os, sys
sys.path.insert(0, "tests/replay")
import logtool
def images(path):
    return [(logtool.image_fields(p), len(p)) for _, _, c, p in logtool.read(path) if c == "VISCO_CAMERA_IMAGE"]
raw, png = images(sys.argv[1]), images(sys.argv[2])
s = json.load(open(sys.argv[3]))
assert len(raw) == len(png) > 0 and all(f[4][3] == logtool.GRAY8 for f, _ in raw), (len(raw), len(png))
assert all(f[4][3] == logtool.PNG for f, _ in png), "frames not PNG"
assert s["identical"] and s["frames"] == len(png) and s["compared"] > 0, s
ratio = sum(n for _, n in raw) / sum(n for _, n in png)
size = os.path.getsize(sys.argv[1]) / os.path.getsize(sys.argv[2])
assert ratio > 1.5, ratio
print("PNG (level 1): %d frames %.1fx smaller (log %.1fx), replayed identically with no other file" % (len(png), ratio, size))
PY
# Vision saw the very pixels of the raw run: its detections (with each frame's pixel digest) are the same bytes.
python3 -S $here/logtool.py diff "$tmp/short.lcmlog" "$tmp/png.lcmlog" VISCO_TAG_DETECTIONS ||
  fail "vision's detections differ between the raw and the PNG frames"

# 4. The lockstep log through vision and the controller again: identical.
"$visco" replay "$first" "${cam[@]}" --fast --check --no-publish >"$tmp/replay.json" 2>"$tmp/replay.log"
status=$?
tail -n 2 "$tmp/replay.log"
[[ $status -eq 0 ]] || fail "replay --check of the lockstep log exited $status"
python3 -S -c '
import json, sys
s = json.load(open(sys.argv[1]))
c = s["control"]
print("replay --check: %d frames, %d messages compared, %d controller periods compared (%d with the replayed vision), "
      "identical %s, %.0f frames/s" % (s["frames"], s["compared"], c["compared"], c["frames_from_vision"],
                                       s["identical"], s["frames_per_s"]))
ok = (s["identical"] and s["frames"] >= 20 and s["frames"] == s["images"] and s["skipped_frames"] == 0 and
      s["compared"] >= 4 * s["frames"] and c["compared"] >= 500 and c["compared"] == c["cycles"] and
      c["frames_from_vision"] >= c["cycles"] // 2 and c["frames_recorded"] == 0)
sys.exit(0 if ok else 1)' "$tmp/replay.json" || fail "the lockstep log does not replay identically in full"

# 5. Bad input.
expect2() {
  local what="$1" pattern="$2"
  shift 2
  "$visco" "$@" >/dev/null 2>"$tmp/bad.log"
  local status=$?
  [[ $status -eq 2 ]] || fail "$what: exit $status, expected 2"
  grep -q -- "$pattern" "$tmp/bad.log" || { fail "$what: no clear message"; cat "$tmp/bad.log"; }
}
# (the rays' own scene: rays of another scene are refused before anything else)
e2e=tests/control/data/slot_e2e_scene.json
expect2 "no strategy" "--strategy" sim $e2e --lockstep "${cam[@]}" --rays "$here/data/slot_e2e_rays.json"
expect2 "no camera" "--objects" sim $e2e --lockstep --strategy tests/control/data/slot_e2e_plan.json \
  --rays "$here/data/slot_e2e_rays.json"
expect2 "with --can" "--can" sim $e2e --lockstep --can vcan0 "${cam[@]}" \
  --strategy tests/control/data/slot_e2e_plan.json --rays "$here/data/slot_e2e_rays.json"
expect2 "--strategy without --lockstep" "only with --lockstep" sim data/scenes/slot.json \
  --strategy tests/control/data/slot_e2e_plan.json
expect2 "demo --lockstep --netns" "--netns" demo --lockstep --netns --out "$tmp/bad"

echo "lockstep test: $(python3 -S -c "import time; print('%.0f' % (time.time() - $start))") s"
echo "$((failures == 0 ? 1 : 0)) passed, $((failures == 0 ? 0 : 1)) failed"
exit $((failures == 0 ? 0 : 1))

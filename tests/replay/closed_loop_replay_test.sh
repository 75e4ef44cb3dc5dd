#!/usr/bin/env bash
# A closed-loop simulated run, logged and replayed (the replay's proof):
#   visco sim (robot + rendered camera) -> visco track --log (vision) -> visco run --log (the executor), over real LCM
#   (UDP multicast, private port, ttl=0); then
#   1. `visco replay TRACK_LOG --check`: the logged images through vision again: identical, field by field;
#   2. the same on the controller's log (it records the same bus), and the executor again on every recorded period
#      with the replayed vision: identical; one recorded command changed: found at its period;
#   3. two replays write byte-identical logs (--out): the replay is deterministic;
#   4. one image of the log corrupted: --check exits 1 naming that frame;
#   5. lcm-spy's type database decodes every channel of the log, from the file and played by lcm-logplayer.
# usage: closed_loop_replay_test.sh VISCO SPY_CHECK_CLASSES_DIR [FIXTURE_OUT]
#   FIXTURE_OUT: also write the small checked-in fixture (tests/replay/data/slot_run.lcmlog) from this run's log.
set -uo pipefail
visco="$1"
spy_check="$2"
fixture_out="${3:-}"
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
here=tests/replay
scene=tests/control/data/slot_e2e_scene.json
plan=tests/control/data/slot_e2e_plan.json
cam=(--camera data/sim/slot_camera.xml --extrinsics data/sim/slot_extrinsics.json --objects data/sim/slot_objects.json)
port=$((22000 + $$ % 20000))
url="udpm://239.255.76.67:$port?ttl=0"
tmp=$(mktemp -d)
pids=()
failures=0
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null; done
  # A failing run keeps its logs (it has failed now and then inside a full ctest run, never alone).
  if [[ -n "${KEEP_TMP:-}" || $failures -gt 0 ]]; then
    echo "kept $tmp"
    tail -n 5 "$tmp"/*.log 2>/dev/null
  else
    rm -rf "$tmp"
  fi
}
trap cleanup EXIT
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

noise=2
[[ -n "$fixture_out" ]] && noise=0  # the fixture's images compress to PNG without noise
"$visco" vcrays "$scene" >"$tmp/rays.json" || { echo "FAIL: visco vcrays"; exit 1; }
# The listeners first, then the images: the vision state (tracker windows, pose priors) carries from frame to frame,
# so the controller's log must hold every image vision saw to replay it identically; a log that starts after the
# live vision's first frames differs in its first frames (docs/replay.md). `visco run` opens its log at start and
# waits for the driver (the simulator) up to --startup-timeout.
# (The file is created just before the log subscribes to the bus, hence the short pause.)
wait_for_file() { for _ in $(seq 1 100); do [[ -e "$1" ]] && sleep 0.3 && return 0; sleep 0.1; done; return 1; }
"$visco" run "$plan" --scene "$scene" --rays "$tmp/rays.json" --lcm-url "$url" --max-speed 1 --max-accel 4 \
  "${cam[@]}" --max-vision-age-ms 400 --max-hold 4 --startup-timeout 30 --status-timeout-ms 500 \
  --heartbeat-timeout-ms 1000 --no-realtime --log "$tmp/run.lcmlog" >"$tmp/run.json" 2>"$tmp/run.log" &
run=$!
pids=($run)
wait_for_file "$tmp/run.lcmlog" || fail "visco run did not open its log"
"$visco" track --lcm --lcm-url "$url&recv_buf_size=4194304" "${cam[@]}" --log "$tmp/track.lcmlog" \
  >"$tmp/track.jsonl" 2>"$tmp/track.log" &
track=$!
pids+=($track)
wait_for_file "$tmp/track.lcmlog" || fail "visco track did not open its log"
"$visco" sim "$scene" "${cam[@]}" --camera-hz 15 --latency-ms 5 --supersample 2 --image-noise $noise --blur-px 0.5 \
  --seed 7 --lcm-url "$url" --duration 90 --watchdog-ms 500 --log "$tmp/sim.lcmlog" >"$tmp/sim.json" 2>"$tmp/sim.log" &
sim=$!
pids+=($sim)
wait $run
run_status=$?
kill -INT $sim $track
wait $sim $track
pids=()
echo "visco run exited $run_status"
grep -h "event log" "$tmp/track.log" "$tmp/run.log" "$tmp/sim.log"
[[ $run_status -eq 0 ]] || fail "the closed-loop run did not reach the goal (exit $run_status)"
grep -q '"result":"done"' "$tmp/run.json" || fail "run summary is not done"
grep -q "event log $tmp/track.lcmlog: [0-9]* event(s), [0-9]* bytes written; 0 dropped" "$tmp/track.log" ||
  fail "track's log was not written without drops"
grep -q "event log $tmp/run.lcmlog: [0-9]* event(s), [0-9]* bytes written; 0 dropped" "$tmp/run.log" ||
  fail "run's log was not written without drops"
grep -q "event log $tmp/sim.lcmlog: [0-9]* event(s), [0-9]* bytes written; 0 dropped" "$tmp/sim.log" ||
  fail "sim's log was not written without drops"
# The simulator's log holds the same bus: its images replay identically too.
"$visco" replay "$tmp/sim.lcmlog" "${cam[@]}" --fast --check --no-publish --no-control >/dev/null 2>"$tmp/replay_sim.log" ||
  { fail "replay --check of sim's log failed"; tail -n 2 "$tmp/replay_sim.log"; }

# 1. Replay through vision with --check.
"$visco" replay "$tmp/track.lcmlog" "${cam[@]}" --fast --check --no-publish --out "$tmp/replay1.lcmlog" \
  >"$tmp/replay1.json" 2>"$tmp/replay1.log"
status=$?
cat "$tmp/replay1.json"
tail -n 3 "$tmp/replay1.log"
[[ $status -eq 0 ]] || fail "replay --check of track's log exited $status"
python3 -S -c '
import json, sys
s = json.load(open(sys.argv[1]))
ok = s["identical"] and s["frames"] >= 30 and s["compared"] >= 4 * s["frames"] and s["differences"] == 0
print("replay: %d frames, %d messages compared, identical %s, %.1f frames/s against %.1f Hz logged" %
      (s["frames"], s["compared"], s["identical"], s["frames_per_s"], s["log"]["frame_rate_hz"]))
sys.exit(0 if ok else 1)' "$tmp/replay1.json" || fail "replay summary: not identical or too few frames"

# 2. The controller's log holds the same bus and every period of the loop: vision and the executor replayed, the
#    executor's visual input taken from the replayed vision, commands, modes and faults compared.
"$visco" replay "$tmp/run.lcmlog" "${cam[@]}" --fast --check --no-publish >"$tmp/replay_run.json" 2>"$tmp/replay_run.log"
status=$?
tail -n 2 "$tmp/replay_run.log"
[[ $status -eq 0 ]] || { fail "replay --check of run's log exited $status"; tail -n 3 "$tmp/replay_run.log"; }
python3 -S -c '
import json, sys
s = json.load(open(sys.argv[1]))
c = s["control"]
print("controller: %d periods replayed and compared, %d with the replayed vision" % (c["compared"], c["frames_from_vision"]))
sys.exit(0 if s["identical"] and c["compared"] >= 1000 and c["compared"] == c["cycles"] and
         c["frames_from_vision"] >= c["cycles"] // 2 else 1)' "$tmp/replay_run.json" ||
  fail "the controller was not replayed identically"
# One recorded command changed by one bit: the difference is found at that period.
cycle=$(python3 -S $here/logtool.py corrupt-cycle "$tmp/run.lcmlog" "$tmp/corrupt_cycle.lcmlog" 2000)
"$visco" replay "$tmp/corrupt_cycle.lcmlog" "${cam[@]}" --fast --check --no-publish >/dev/null 2>"$tmp/corrupt_cycle.log"
status=$?
tail -n 1 "$tmp/corrupt_cycle.log"
[[ $status -eq 1 ]] || fail "replay --check of a changed command exited $status, expected 1"
grep -q "first difference on VISCO_CONTROLLER_CYCLE at log time [0-9]* (controller cycle $cycle, .*field command.velocity\[0\]" \
  "$tmp/corrupt_cycle.log" || fail "the changed command is not reported at cycle $cycle"

# 3. Deterministic: a second replay writes the same bytes.
"$visco" replay "$tmp/track.lcmlog" "${cam[@]}" --fast --no-publish --out "$tmp/replay2.lcmlog" >/dev/null 2>&1 ||
  fail "second replay failed"
cmp "$tmp/replay1.lcmlog" "$tmp/replay2.lcmlog" || fail "two replays of the same log wrote different logs"
[[ -s "$tmp/replay1.lcmlog" ]] || fail "the replay wrote an empty log"

# 4. One corrupted image: the difference is reported at that frame.
seq=$(python3 -S -c '
import json, sys
frames = [d["seq"] for d in map(json.loads, open(sys.argv[1])) if "seq" in d]
print(frames[20])' "$tmp/track.jsonl")
python3 -S $here/logtool.py corrupt-image "$tmp/track.lcmlog" "$tmp/corrupt.lcmlog" "$seq" || fail "logtool"
"$visco" replay "$tmp/corrupt.lcmlog" "${cam[@]}" --fast --check --no-publish >"$tmp/corrupt.json" 2>"$tmp/corrupt.log"
status=$?
tail -n 1 "$tmp/corrupt.log"
[[ $status -eq 1 ]] || fail "replay --check of the corrupted log exited $status, expected 1"
grep -q "first difference on VISCO_[A-Z_]* at log time [0-9]* (frame seq $seq," "$tmp/corrupt.log" ||
  fail "the difference is not reported at frame seq $seq"
python3 -S -c '
import json, sys
s = json.load(open(sys.argv[1]))
sys.exit(0 if s["first_difference"]["frame_seq"] == int(sys.argv[2]) else 1)' "$tmp/corrupt.json" "$seq" ||
  fail "summary's first difference is not at frame $seq"

# 5. lcm-spy's type database (visco spy's class path) decodes every channel of the log, read from the file with LCM's
#    own log reader; and lcm-logplayer plays the log onto a bus where the same decoder listens. The decoder takes
#    SPYTEST_.* channels, so the copy has its channels prefixed. A 300 KB image crosses a udpm bus only if the
#    receiver's socket buffer holds its five 64 KB fragments. lcm-spy's Java LCM ignores the URL's recv_buf_size and
#    gets the kernel's default buffer (net.core.rmem_default, 208 KB unless raised): there a receiver that is not
#    instantly back at its socket loses the image (CI lost all 828 in three plays once), so the images are required on
#    the bus only where rmem_default holds them (they are decoded from the file in any case).
python3 -S $here/logtool.py rename "$tmp/track.lcmlog" "$tmp/spy.lcmlog" SPYTEST_ || fail "logtool rename"
classpath=$("$visco" spy --print | sed -e 's/.* -cp \([^ ]*\) .*/\1/')
channels=(CAMERA_IMAGE TAG_DETECTIONS OBJECT_POSES ROBOT_ESTIMATE VISUAL_EVENTS COMMAND STATUS TELEMETRY)
timeout 120 java -cp "$classpath:$spy_check" SpyDecodeCheck --log "$tmp/spy.lcmlog" >"$tmp/decode_file.out" 2>&1 ||
  fail "lcm-spy's decoder could not read the log file"
sort "$tmp/decode_file.out"
for channel in "${channels[@]}"; do
  grep -q "^decoded SPYTEST_VISCO_$channel visco\." "$tmp/decode_file.out" ||
    fail "lcm-spy did not decode VISCO_$channel in the log file"
done
# LCM_SELF_TEST is LCM's own start-up check of a udpm:// bus (recorded by the logger), not a visco message.
grep -E '^(undecodable|error)' "$tmp/decode_file.out" | grep -qv 'SPYTEST_LCM_SELF_TEST' &&
  fail "lcm-spy could not decode some channel of the log file"

bus_channels=("${channels[@]}")
rmem_default=$(cat /proc/sys/net/core/rmem_default 2>/dev/null || echo 0)
if ((rmem_default < 2097152)); then
  bus_channels=("${channels[@]:1}")
  echo "note: net.core.rmem_default is $rmem_default bytes (lcm-spy's receive buffer): images not required on the bus" \
    "(decoded from the file above)"
fi
spy_url="udpm://239.255.76.67:$((port + 1))?ttl=0&recv_buf_size=4194304"
timeout 90 java -Djava.net.preferIPv4Stack=true -cp "$classpath:$spy_check" SpyDecodeCheck "$spy_url" 80 \
  "${bus_channels[@]/#/SPYTEST_VISCO_}" >"$tmp/decode.out" 2>&1 &
checker=$!
for _ in $(seq 1 300); do grep -q '^listening' "$tmp/decode.out" 2>/dev/null && break; sleep 0.1; done
# Played until every channel was seen (a loaded machine may drop a datagram), three times at most.
for _ in 1 2 3; do
  kill -0 $checker 2>/dev/null || break
  timeout 30 lcm-logplayer -s 4 -l "$spy_url" "$tmp/spy.lcmlog" >/dev/null 2>&1 || fail "lcm-logplayer failed"
done
kill $checker 2>/dev/null
wait $checker
sort "$tmp/decode.out"
for channel in "${bus_channels[@]}"; do
  grep -q "^decoded SPYTEST_VISCO_$channel visco\." "$tmp/decode.out" || fail "lcm-spy did not decode VISCO_$channel"
done
grep -E '^(undecodable|error)' "$tmp/decode.out" | grep -qv 'SPYTEST_LCM_SELF_TEST' &&
  fail "lcm-spy could not decode some channel"

if [[ -n "$fixture_out" && $failures -eq 0 ]]; then
  cp "$tmp/rays.json" $here/data/slot_e2e_rays.json
  python3 -S $here/logtool.py fixture "$tmp/run.lcmlog" "$fixture_out" 2000000 "$plan" "$scene" $here/data/slot_e2e_rays.json
fi
echo "$((failures == 0 ? 1 : 0)) passed, $((failures == 0 ? 0 : 1)) failed"
exit $((failures == 0 ? 0 : 1))

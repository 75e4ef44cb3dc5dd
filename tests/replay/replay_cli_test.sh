#!/usr/bin/env bash
# `visco replay` on the small checked-in log of a rendered closed-loop run (tests/replay/data/slot_run.lcmlog: the
# first seconds of `visco run --log`, images as PNG, written by closed_loop_replay_test.sh with FIXTURE_OUT): vision and
# the controller identical with --check; a time window; damaged logs give
# a report and the documented exit statuses (never a crash); replay refuses CAN without --arm.
# Also: `visco driver --log` killed with SIGKILL leaves a log that replays; `visco-rt` refuses --log.
# usage: replay_cli_test.sh VISCO VISCO_RT
set -uo pipefail
visco="$1"
visco_rt="$2"
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
here=tests/replay
log=$here/data/slot_run.lcmlog
cam=(--camera data/sim/slot_camera.xml --extrinsics data/sim/slot_extrinsics.json --objects data/sim/slot_objects.json)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
replay() { "$visco" replay "$@" "${cam[@]}" --fast --no-publish >"$tmp/out.json" 2>"$tmp/err.log"; echo $?; }

size=$(stat -c %s "$log")
(( size <= 2000000 )) || fail "the fixture is $size bytes (at most 2 MB)"

# The fixture replays identically.
status=$(replay "$log" --check)
cat "$tmp/out.json"; tail -n 1 "$tmp/err.log"
[[ $status -eq 0 ]] || { fail "replay --check of the fixture exited $status"; cat "$tmp/err.log"; }
python3 -S -c '
import json, sys
s = json.load(open(sys.argv[1]))
c = s["control"]
print("fixture: %d frames, %d vision messages compared; controller: %d periods compared (%d with the replayed vision)" %
      (s["frames"], s["compared"], c["compared"], c["frames_from_vision"]))
sys.exit(0 if s["identical"] and s["frames"] >= 20 and s["compared"] >= 4 * s["frames"] and
         c["compared"] >= 1000 and c["frames_from_vision"] > 0 else 1)' "$tmp/out.json" ||
  fail "fixture: not identical or too few frames or periods compared"

# What the summary claims is what happened: with --no-publish nothing is "published"; without --check
# "identical" is not claimed.
python3 -S -c '
import json, sys
s = json.load(open(sys.argv[1]))
sys.exit(0 if s["published"] == 0 and s["republished"] == 0 and s["produced"] > 1000 and s["checked"] else 1)' \
  "$tmp/out.json" || fail "--no-publish: the summary claims publications: $(head -c 300 "$tmp/out.json")"
# (Windows: the fixture's first image is 1.26 s after its first event, since the listeners start before the camera.)
status=$(replay "$log" --to 1.8)
grep -q '"identical":null' "$tmp/out.json" && grep -q '"checked":false' "$tmp/out.json" ||
  fail "without --check the summary claims identical: $(head -c 200 "$tmp/out.json")"
# A --check whose window holds nothing to compare (it starts after the log's end) shows nothing identical: exit 1.
status=$(replay "$log" --check --from 100)
[[ $status -eq 1 ]] && grep -q "nothing was compared" "$tmp/err.log" && grep -q '"identical":false' "$tmp/out.json" ||
  fail "--check comparing nothing: exit $status, $(tail -1 "$tmp/err.log")"
# The files the log names are relative to the log: the replay works from any directory.
(cd / && "$visco" replay "$OLDPWD/$log" --camera "$OLDPWD/data/sim/slot_camera.xml" \
  --extrinsics "$OLDPWD/data/sim/slot_extrinsics.json" --objects "$OLDPWD/data/sim/slot_objects.json" --fast --check \
  --no-publish --to 2.3 >"$tmp/elsewhere.json" 2>"$tmp/elsewhere.log") ||
  fail "replay --check from / exited $?: $(tail -2 "$tmp/elsewhere.log")"
grep -q "controller: [0-9]* period(s) through the executor" "$tmp/elsewhere.log" ||
  fail "from /, the controller was not replayed: $(cat "$tmp/elsewhere.log")"

# A window (earlier frames go through vision silently): identical too, fewer messages compared.
status=$(replay "$log" --check --from 2.3 --to 3.3)
[[ $status -eq 0 ]] || { fail "windowed replay exited $status"; cat "$tmp/err.log"; }
grep -q '"warmup_frames":[1-9]' "$tmp/out.json" || fail "the window had no warm-up frames"

# At the log's pace (x4) and published on LCM (in-process provider): the same result.
"$visco" replay "$log" "${cam[@]}" --check --speed 4 --to 2.8 --lcm-url memq:// >"$tmp/paced.json" 2>"$tmp/err.log" ||
  fail "paced replay failed: $(tail -n 1 "$tmp/err.log")"

# Two replays write the same bytes.
"$visco" replay "$log" "${cam[@]}" --fast --no-publish --out "$tmp/a.lcmlog" >/dev/null 2>&1 || fail "replay --out"
"$visco" replay "$log" "${cam[@]}" --fast --no-publish --out "$tmp/b.lcmlog" >/dev/null 2>&1 || fail "replay --out"
cmp -s "$tmp/a.lcmlog" "$tmp/b.lcmlog" || fail "two replays wrote different logs"
grep -q "REPLAY_VISCO_ROBOT_ESTIMATE" "$tmp/a.lcmlog" || fail "the replay's log has no REPLAY_ channels"

# An image folder as the source (the fixture's frames as PNG files): vision as `visco track --images` takes them, on
# the folder's deterministic timestamps; two replays write the same bytes; nothing to --check against.
frames=$(python3 -S $here/logtool.py extract-images "$log" "$tmp/frames")
for k in 1 2; do
  "$visco" replay --images "$tmp/frames" --fps 15 "${cam[@]}" --fast --no-publish --out "$tmp/folder$k.lcmlog" \
    >"$tmp/folder.json" 2>"$tmp/err.log" || fail "replay --images exited $?: $(tail -n 1 "$tmp/err.log")"
done
grep -q "\"frames\":$frames," "$tmp/folder.json" || fail "replay --images did not process the $frames frames"
cmp -s "$tmp/folder1.lcmlog" "$tmp/folder2.lcmlog" || fail "two replays of an image folder wrote different logs"
status=$(replay --images "$tmp/frames" --check)
[[ $status -eq 2 ]] || fail "--check with --images: exit $status, expected 2"
status=$(replay "$log" --images "$tmp/frames")
[[ $status -eq 2 ]] || fail "a LOG and --images: exit $status, expected 2"

# Damaged logs: a report of what was skipped, exit 0 without --check, never a crash.
for kind in truncate flip-header bad-sync; do
  python3 -S $here/logtool.py damage "$log" "$tmp/$kind.lcmlog" $kind
  status=$(replay "$tmp/$kind.lcmlog")
  [[ $status -eq 0 ]] || fail "$kind: exit $status, expected 0"
  grep -q "replay: $tmp/$kind.lcmlog: .* skipped [0-9]* byte(s) in [0-9]* range(s)" "$tmp/err.log" ||
    fail "$kind: no report of the skipped bytes"
  # --check: never identical (exit 0): 1 at a difference, 3 when what could be compared is identical.
  status=$(replay "$tmp/$kind.lcmlog" --check)
  [[ $status -eq 1 || $status -eq 3 ]] || fail "$kind --check: exit $status, expected 1 or 3"
  [[ $status -eq 1 ]] || grep -q "^visco: replay --check: .* is incomplete (" "$tmp/err.log" ||
    fail "$kind --check: exit 3 without saying what is incomplete"
  echo "$kind: $(grep -m1 -A1 'skipped' "$tmp/err.log" | tail -n 1)"
done
grep -q "cut off by the end of the file" <("$visco" replay "$tmp/truncate.lcmlog" "${cam[@]}" --fast --no-publish 2>&1) ||
  fail "truncate: the report does not say the file ends in a cut-off event"
# Another process's channel: reported, the rest replays identically (exit 0). An undecodable image: the rest
# replays identically, but that frame was not checked (exit 3).
for kind in unknown-channel undecodable; do
  python3 -S $here/logtool.py damage "$log" "$tmp/$kind.lcmlog" $kind
  status=$(replay "$tmp/$kind.lcmlog" --check)
  expected=$([[ $kind == unknown-channel ]] && echo 0 || echo 3)
  [[ $status -eq $expected ]] || { fail "$kind: exit $status, expected $expected"; cat "$tmp/err.log"; }
done
grep -q '"SOMEONE_ELSES_CHANNEL":1' <("$visco" replay "$tmp/unknown-channel.lcmlog" "${cam[@]}" --fast --no-publish 2>/dev/null) ||
  fail "the unknown channel is not in the summary"
grep -q "does not decode as visco.image_t" "$tmp/err.log" || fail "the undecodable image is not reported"
# An image vision processed that the logger lost (no event number missing): the first difference comes with the
# missing image named and the --to that compares up to it, and that window replays identically.
python3 -S $here/logtool.py damage "$log" "$tmp/lose-image.lcmlog" lose-image
status=$(replay "$tmp/lose-image.lcmlog" --check)
[[ $status -eq 1 ]] || fail "lose-image: exit $status, expected 1"
grep -q "the log lacks the image of a frame live vision processed before it (capture utime [0-9]*, lost by the logger)" \
  "$tmp/err.log" || fail "lose-image: the missing image is not named with the difference"
to=$(sed -n 's/.*; --to \([0-9.]*\) compares up to the last image before it.*/\1/p' "$tmp/err.log")
[[ -n "$to" ]] || fail "lose-image: no --to given"
grep -q '"images_missing":\[{"frame_utime":[0-9]*,' "$tmp/out.json" || fail "lose-image: not in the summary's images_missing"
status=$(replay "$tmp/lose-image.lcmlog" --check --to "$to")
[[ $status -eq 0 ]] || fail "lose-image --to $to: exit $status, expected 0 (identical up to the lost image)"
grep -q '"images_missing":\[\]' <("$visco" replay "$log" "${cam[@]}" --fast --no-publish 2>/dev/null) ||
  fail "the whole fixture reports a missing image"

# Nothing usable: exit 2 with the reason.
for kind in garbage empty only-undecodable; do
  python3 -S $here/logtool.py damage "$log" "$tmp/$kind.lcmlog" $kind
  status=$(replay "$tmp/$kind.lcmlog")
  [[ $status -eq 2 ]] || fail "$kind: exit $status, expected 2"
  grep -q "^visco: $tmp/$kind.lcmlog: " "$tmp/err.log" || fail "$kind: no one-line error naming the file"
  echo "$kind: $(tail -c 300 "$tmp/err.log" | head -n 1)"
done
status=$(replay /nonexistent.lcmlog)
[[ $status -eq 2 ]] || fail "a missing log: exit $status"

# A process killed with SIGKILL leaves a readable log (flushed every 100 ms): the driver's statuses and heartbeats
# replay (republished) with at most a cut-off event reported at the end.
url="udpm://239.255.76.67:$((23000 + $$ % 20000))?ttl=0"
"$visco" driver --lcm-url "$url" --log "$tmp/driver.lcmlog" >/dev/null 2>&1 &
driver=$!
# Killed once its log holds about 100 events (statuses every 10 ms; 12 kB), or after 20 s: a fixed 1.5 s was too
# short under ThreadSanitizer, where the whole `visco` takes seconds to start.
sleep 1.5
for _ in $(seq 1 185); do
  (( $(stat -c %s "$tmp/driver.lcmlog" 2>/dev/null || echo 0) >= 12000 )) && break
  sleep 0.1
done
kill -9 $driver
wait $driver 2>/dev/null
# Published (in-process provider): the summary counts what went out, which --no-publish would not.
"$visco" replay "$tmp/driver.lcmlog" "${cam[@]}" --fast --lcm-url memq:// --channels 'VISCO_(STATUS|HEARTBEAT_DRIVER)' \
  >"$tmp/out.json" 2>"$tmp/err.log"
status=$?
[[ $status -eq 0 ]] || { fail "the SIGKILLed driver's log: exit $status"; cat "$tmp/err.log"; }
python3 -S -c '
import json, sys
s = json.load(open(sys.argv[1]))
print("driver log after SIGKILL: %d events, %d republished, %d bytes skipped" %
      (s["log"]["events"], s["republished"], s["log"]["skipped_bytes"]))
sys.exit(0 if s["republished"] >= 50 and s["log"]["skipped_ranges"] <= 1 else 1)' "$tmp/out.json" ||
  fail "the SIGKILLed driver's log holds too little or is damaged inside"
status=$("$visco_rt" driver --lcm-url "$url" --log "$tmp/rt.lcmlog" --duration 0.1 >/dev/null 2>"$tmp/err.log"; echo $?)
[[ $status -eq 2 ]] || fail "visco-rt driver --log: exit $status, expected 2"
grep -q "cannot write event logs" "$tmp/err.log" || fail "visco-rt does not say why it refuses --log"

# --step: Enter, Enter, "3" (three images on), then "q" at the sixth image: five frames, the controller not replayed.
printf '\n\n3\nq\n' | "$visco" replay "$log" "${cam[@]}" --fast --no-publish --step >"$tmp/step.json" 2>"$tmp/err.log"
python3 -S -c '
import json, sys
s = json.load(open(sys.argv[1]))
sys.exit(0 if s["frames"] == 5 and s["stopped_at_step"] else 1)' "$tmp/step.json" ||
  fail "--step with answers Enter Enter 3 q: $(cat "$tmp/step.json") $(tail -n 2 "$tmp/err.log")"
grep -q "not replayed: the replay was stopped at a --step prompt" "$tmp/err.log" ||
  fail "--step q: the controller note is missing"
# --loop 2 over a window: two summaries, the same but for the timing.
"$visco" replay "$log" "${cam[@]}" --fast --no-publish --from 1.6 --to 2.3 --loop 2 >"$tmp/loop.json" 2>"$tmp/err.log" ||
  fail "--loop 2 exited $?"
python3 -S -c '
import json, sys
runs = [json.loads(l) for l in open(sys.argv[1]) if l.startswith("{")]
for r in runs:
    r.pop("wall_s", None); r.pop("frames_per_s", None)
sys.exit(0 if len(runs) == 2 and runs[0] == runs[1] and runs[0]["frames"] > 0 else 1)' "$tmp/loop.json" ||
  fail "--loop 2 did not give two identical summaries: $(cat "$tmp/loop.json")"
status=$(replay "$log" --check --loop 2)
[[ $status -eq 2 ]] || fail "--check with --loop 2: exit $status, expected 2"

# --seek: straight to --from (no warm-up frames through vision); refused with --check.
status=$(replay "$log" --seek --from 2.3)
[[ $status -eq 0 ]] || fail "--seek --from 2.3: exit $status"
python3 -S -c '
import json, sys
s = json.load(open(sys.argv[1]))
sys.exit(0 if s["warmup_frames"] == 0 and s["seeked_events"] > 0 and s["frames"] > 0 else 1)' "$tmp/out.json" ||
  fail "--seek --from 2.3 did not skip the frames before 2.3 s: $(cat "$tmp/out.json")"
status=$(replay "$log" --seek --from 2.3 --check)
[[ $status -eq 2 ]] || fail "--seek with --check: exit $status, expected 2"

# Never hardware unless armed.
status=$(replay "$log" --can vcan0)
[[ $status -eq 2 ]] || fail "--can without --arm: exit $status"
grep -q -- "--arm" "$tmp/err.log" || fail "--can without --arm: the message does not name --arm"

echo "$((failures == 0 ? 1 : 0)) passed, $((failures == 0 ? 0 : 1)) failed"
exit $((failures == 0 ? 0 : 1))

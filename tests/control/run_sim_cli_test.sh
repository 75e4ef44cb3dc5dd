#!/usr/bin/env bash
# `visco sim` and `visco run` as two processes over LCM (UDP multicast on a private port, ttl=0): the hand-written
# strategy of tests/control/data reaches the goal (exit 0, JSON summary "done"); bad input exits 2 naming the file
# and object; a run whose driver never answers exits 1 with the reason.
set -uo pipefail
visco="$1"
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
data=tests/control/data
url="udpm://239.255.76.67:$((41000 + $$ % 20000))?ttl=0"
tmp=$(mktemp -d)
trap 'kill $sim_pid 2>/dev/null; rm -rf "$tmp"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
# Watchdog and silence limits are timing matters, not this test's: generous ones, so that a loaded machine or a
# sanitizer build does not stop the runs (the stops themselves are tested in tests/control/realtime_loop_test.cc and
# tests/drivers/driver_test.cc).
sim_patience=(--watchdog-ms 500)
run_patience=(--status-timeout-ms 500 --heartbeat-timeout-ms 1000)

"$visco" sim "$data/post_scene.json" --rays "$data/post_rays.json" --start 1.84 1.55 --seed 3 --lcm-url "$url" \
  --duration 30 "${sim_patience[@]}" >"$tmp/sim.json" 2>"$tmp/sim.log" &
sim_pid=$!
"$visco" run "$data/post_plan.json" --scene "$data/post_scene.json" --rays "$data/post_rays.json" --lcm-url "$url" \
  --max-speed 0.4 --max-accel 4 --no-realtime "${run_patience[@]}" >"$tmp/run.json" 2>"$tmp/run.log"
status=$?
kill -INT $sim_pid; wait $sim_pid
[[ $status -eq 0 ]] || fail "visco run exited $status"
grep -q '"result":"done"' "$tmp/run.json" || { fail "run summary is not done:"; cat "$tmp/run.json" "$tmp/run.log"; }
grep -q 'goal recognised' "$tmp/run.log" || fail "the log does not say why the run ended"
grep -q '"commands_applied"' "$tmp/sim.json" || { fail "sim printed no summary:"; cat "$tmp/sim.json" "$tmp/sim.log"; }

# The driver stops the robot at the workspace's bounds (the controller, given no scene, does not know them): the run
# stops with the driver's own reason (its EMCY), not only "the driver started a new session".
echo '{"steps": [{"theta_deg": 90, "active_rays": [], "terminate": {"kind": "contact"}, "timeout_s": 30}]}' \
  >"$tmp/up.json"
"$visco" sim "$data/post_scene.json" --start 1.84 1.55 --seed 3 --lcm-url "$url" --duration 30 \
  "${sim_patience[@]}" >"$tmp/sim2.json" 2>"$tmp/sim2.log" &
sim_pid=$!
"$visco" run "$tmp/up.json" --lcm-url "$url" --max-speed 0.4 --max-accel 4 --no-realtime "${run_patience[@]}" \
  >"$tmp/run2.json" 2>"$tmp/run2.log"
status=$?
kill -INT $sim_pid; wait $sim_pid
[[ $status -eq 1 ]] || fail "the run out of bounds exited $status, expected 1"
grep -q '"reason":"robot link: the driver stopped the robot: the robot left its workspace (EMCY 0x8612' \
  "$tmp/run2.json" || { fail "the stop reason is not the driver's:"; cat "$tmp/run2.json"; tail -5 "$tmp/run2.log"; }

# Bad input: exit 2, "visco: FILE: OBJECT: what".
echo '{"steps": [{"theta_deg": 0, "terminate": {"kind": "teleport"}}]}' >"$tmp/bad.json"
out=$("$visco" run "$tmp/bad.json" 2>&1); status=$?
[[ $status -eq 2 ]] || fail "bad strategy exited $status, expected 2"
grep -qE "^visco: .*bad.json: steps\[0\]\.terminate\.kind: unknown terminate kind" <<<"$out" || fail "message: $out"
out=$("$visco" run "$data/post_plan.json" --rays "$data/post_rays.json" 2>&1); status=$?
[[ $status -eq 2 ]] || fail "goal step without --scene exited $status, expected 2"
grep -q "give the scene file with --scene" <<<"$out" || fail "message: $out"
out=$("$visco" sim "$tmp/bad.json" 2>&1); status=$?
[[ $status -eq 2 ]] || fail "sim with a bad scene exited $status, expected 2"

# No driver: the run stops after the start-up time-out and says so (exit 1).
out=$("$visco" run "$data/post_plan.json" --scene "$data/post_scene.json" --rays "$data/post_rays.json" \
  --lcm-url "$url" --no-realtime 2>&1); status=$?
[[ $status -eq 1 ]] || fail "run without a driver exited $status, expected 1"
grep -q "no status or heartbeat from the driver" <<<"$out" || fail "message: $out"

echo "$(( failures == 0 ? 1 : 0 )) passed, $(( failures == 0 ? 0 : 1 )) failed"
exit $(( failures == 0 ? 0 : 1 ))

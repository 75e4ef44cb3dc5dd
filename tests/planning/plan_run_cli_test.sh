#!/usr/bin/env bash
# `visco plan` → `visco run` against `visco sim` (two processes over LCM, UDP multicast on a private port, ttl=0): the
# strategy the planner writes for the default scene is executed as it is and reaches the goal recognisably (that the
# plan is the same on every run: planning_strategy_test); a scene with no strategy exits 1 with the reason; bad input
# exits 2.
set -uo pipefail
visco="$1"
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
scene=data/scenes/slot.json
url="udpm://239.255.76.67:$((41000 + ($$ * 7) % 20000))?ttl=0"
tmp=$(mktemp -d)
sim_pid=
trap '[[ -n $sim_pid ]] && kill $sim_pid 2>/dev/null; rm -rf "$tmp"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

"$visco" plan "$scene" --speed 0.5 --threads 2 --out "$tmp/plan.json" --svg "$tmp/plan.svg" --check 10 2>"$tmp/plan.log" ||
  fail "visco plan exited $?: $(cat "$tmp/plan.log")"
grep -q '"feasible":true' "$tmp/plan.json" || fail "no feasible plan: $(head -c 400 "$tmp/plan.json")"
grep -q "10 of 10 start configurations reach the goal" "$tmp/plan.log" || fail "simulation check: $(cat "$tmp/plan.log")"
grep -q '<svg' "$tmp/plan.svg" && grep -q 'class="preimage' "$tmp/plan.svg" || fail "plan.svg has no preimage"
"$visco" vcrays "$scene" --out "$tmp/rays.json" || fail "visco vcrays failed"

# Execute it: the simulated robot starts in the start region.
"$visco" sim "$scene" --rays "$tmp/rays.json" --start 2 5.2 --seed 5 --lcm-url "$url" --duration 60 \
  >"$tmp/sim.json" 2>"$tmp/sim.log" &
sim_pid=$!
"$visco" run "$tmp/plan.json" --scene "$scene" --rays "$tmp/rays.json" --lcm-url "$url" --max-speed 0.5 \
  --max-accel 4 --no-realtime >"$tmp/run.json" 2>"$tmp/run.log"
status=$?
kill -INT $sim_pid; wait $sim_pid; sim_pid=
[[ $status -eq 0 ]] || fail "visco run exited $status: $(tail -5 "$tmp/run.log")"
grep -q '"result":"done"' "$tmp/run.json" || fail "run summary is not done: $(cat "$tmp/run.json")"
grep -q 'goal recognised' "$tmp/run.log" || fail "the run log does not say the goal was recognised"

# Two steps with contact termination (corner.json, no camera): the first motion sticks in the corner, the second
# goes from there to the goal; the executor ends the first step on contact and the second on the goal.
corner=data/scenes/corner.json
"$visco" plan "$corner" --speed 0.5 --threads 2 --out "$tmp/corner.json" --check 10 2>"$tmp/corner.log" ||
  fail "visco plan corner exited $?: $(cat "$tmp/corner.log")"
grep -q '"kind":"contact"' "$tmp/corner.json" || fail "the corner plan has no contact step: $(head -c 400 "$tmp/corner.json")"
grep -q "10 of 10 start configurations reach the goal" "$tmp/corner.log" || fail "corner check: $(cat "$tmp/corner.log")"
"$visco" sim "$corner" --start 7.5 4.5 --seed 3 --lcm-url "$url" --duration 90 >"$tmp/csim.json" 2>"$tmp/csim.log" &
sim_pid=$!
"$visco" run "$tmp/corner.json" --scene "$corner" --lcm-url "$url" --max-speed 0.5 --max-accel 4 --no-realtime \
  >"$tmp/crun.json" 2>"$tmp/crun.log"
status=$?
kill -INT $sim_pid; wait $sim_pid; sim_pid=
[[ $status -eq 0 ]] || fail "visco run corner exited $status: $(tail -5 "$tmp/crun.log")"
grep -q 'stopped in contact' "$tmp/crun.log" || fail "the corner run did not end its first step in contact"
grep -q 'goal recognised' "$tmp/crun.log" || fail "the corner run did not recognise the goal: $(tail -5 "$tmp/crun.log")"

# No strategy within one step without the camera: exit 1, the reason on stderr.
out=$("$visco" plan "$scene" --no-camera --max-steps 1 --out "$tmp/none.json" 2>&1); status=$?
[[ $status -eq 1 ]] || fail "infeasible plan exited $status, expected 1"
grep -q "no strategy within 1 step" <<<"$out" || fail "message: $out"
grep -q '"feasible":false' "$tmp/none.json" || fail "infeasible JSON: $(cat "$tmp/none.json")"

# Bad input: exit 2 naming the file and object.
echo '{"name": "x"}' >"$tmp/bad.json"
out=$("$visco" plan "$tmp/bad.json" 2>&1); status=$?
[[ $status -eq 2 ]] || fail "bad scene exited $status, expected 2"
out=$("$visco" plan "$scene" --max-steps 0 2>&1); status=$?
[[ $status -eq 2 ]] || fail "--max-steps 0 exited $status, expected 2: $out"

echo "$(( failures == 0 ? 1 : 0 )) passed, $(( failures == 0 ? 0 : 1 )) failed"
exit $(( failures == 0 ? 0 : 1 ))

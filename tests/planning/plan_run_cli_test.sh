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
# The picture draws the camera and the ray each step uses, numbers steps from 0 as the JSON does, and says in a legend
# what each colour means.
python3 - "$tmp/plan.svg" "$tmp/plan.json" <<'PY' || fail "plan.svg lacks the camera, the rays, step 0 or the legend"
import json, re, sys, xml.etree.ElementTree as ET
svg = open(sys.argv[1]).read()
ET.fromstring(svg.split("?>", 1)[-1])
plan = json.load(open(sys.argv[2]))
assert 'class="camera"' in svg and 'class="camera-fov"' in svg
for k, step in enumerate(plan["steps"]):
    assert ">step %d: θ = " % k in svg, k
    for ray in step["active_rays"]:
        assert re.search(r'class="active-ray step%d"' % k, svg) and ">%s: step %d complies to it<" % (ray, k) in svg
assert ">step %d: θ" % len(plan["steps"]) not in svg
legend = re.findall(r'class="legend" fill="black">([^<]*)<', svg)
for words in ("start region", "goal: where the robot's reference point", "preimage of step 0", "obstacle",
              "C-obstacle", "camera", "CVC ray a step complies to"):
    assert any(w.startswith(words) for w in legend), (words, legend)
PY
"$visco" vcrays "$scene" --out "$tmp/rays.json" || fail "visco vcrays failed"

# Execute it: the simulated robot starts in the start region. The driver's silence limits are a timing matter, not
# this test's: generous ones, so that a loaded machine or a sanitizer build does not stop the run (the default 100 ms
# status limit and the stop on silence are tested in tests/control/realtime_loop_test.cc).
patience=(--status-timeout-ms 500 --heartbeat-timeout-ms 1000)
"$visco" sim "$scene" --rays "$tmp/rays.json" --start 2 5.2 --seed 5 --lcm-url "$url" --duration 60 \
  >"$tmp/sim.json" 2>"$tmp/sim.log" &
sim_pid=$!
"$visco" run "$tmp/plan.json" --scene "$scene" --rays "$tmp/rays.json" --lcm-url "$url" --max-speed 0.5 \
  --max-accel 4 --no-realtime "${patience[@]}" >"$tmp/run.json" 2>"$tmp/run.log"
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
  "${patience[@]}" >"$tmp/crun.json" 2>"$tmp/crun.log"
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

# Files made for another scene are refused before anything moves (exit 2, naming the files and the scenes): the
# slot's plan with the corner scene, the slot's plan with the corner's rays (which has none: no camera), the plan
# with a slot whose goal was moved but whose name was kept. Plans and rays record the scene's digest.
python3 - "$tmp/plan.json" "$tmp/rays.json" <<'PY' || fail "plan and rays do not record the same scene_digest"
import json, sys
plan, rays = (json.load(open(p)) for p in sys.argv[1:])
assert plan["scene"] == rays["scene"] == "slot", (plan["scene"], rays["scene"])
assert len(plan["scene_digest"]) == 16 and plan["scene_digest"] == rays["scene_digest"], (plan, rays["scene_digest"])
PY
"$visco" vcrays "$corner" --out "$tmp/corner_rays.json" || fail "visco vcrays corner failed"
out=$("$visco" run "$tmp/plan.json" --scene "$corner" --rays "$tmp/rays.json" --lcm-url "$url" --no-realtime 2>&1)
status=$?
[[ $status -eq 2 ]] || fail "the slot plan with the corner scene exited $status, expected 2: $out"
grep -q "visco: $tmp/rays.json: scene: the rays were computed for scene \"slot\".*not for $corner, which is scene \"corner\"" <<<"$out" ||
  fail "message for the rays of another scene: $out"
out=$("$visco" run "$tmp/plan.json" --scene "$corner" --rays "$tmp/corner_rays.json" --lcm-url "$url" \
  --no-realtime 2>&1)
status=$?
[[ $status -eq 2 ]] || fail "the slot plan with the corner scene and rays exited $status, expected 2: $out"
grep -q "visco: $tmp/plan.json: scene: the strategy was planned for scene \"slot\".*not for $corner" <<<"$out" ||
  fail "message for the strategy of another scene: $out"
out=$("$visco" run "$tmp/plan.json" --scene "$scene" --rays "$tmp/corner_rays.json" --lcm-url "$url" \
  --no-realtime 2>&1)
status=$?
[[ $status -eq 2 ]] || fail "the slot plan with the corner's rays exited $status, expected 2: $out"
grep -q "visco: $tmp/corner_rays.json: scene: the rays were computed for scene \"corner\"" <<<"$out" ||
  fail "message for the rays of another scene: $out"
[[ $out != *"give the \`visco vcrays\` output with --rays"* ]] || fail "asks for --rays, which was given: $out"
python3 - "$scene" "$tmp/edited.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
s["goal"]["polygon"] = [[x + 0.05, y] for x, y in s["goal"]["polygon"]]
json.dump(s, open(sys.argv[2], "w"), indent=2)
PY
out=$("$visco" run "$tmp/plan.json" --scene "$tmp/edited.json" --lcm-url "$url" --no-realtime 2>&1); status=$?
[[ $status -eq 2 ]] || fail "the plan with an edited scene of the same name exited $status, expected 2: $out"
grep -q "the scene file was edited" <<<"$out" || fail "message for an edited scene: $out"
# A plan from before the digest: the names decide.
python3 -c 'import json,sys; p=json.load(open(sys.argv[1])); del p["scene_digest"]; json.dump(p, open(sys.argv[2], "w"))' \
  "$tmp/plan.json" "$tmp/old_plan.json"
out=$("$visco" run "$tmp/old_plan.json" --scene "$corner" --lcm-url "$url" --no-realtime 2>&1); status=$?
[[ $status -eq 2 ]] || fail "an old plan with another scene exited $status, expected 2: $out"
grep -q "planned for scene \"slot\", not for $corner" <<<"$out" || fail "message for an old plan: $out"
# visco sim refuses the rays of another scene too.
out=$("$visco" sim "$scene" --rays "$tmp/corner_rays.json" --lcm-url "$url" --duration 1 2>&1); status=$?
[[ $status -eq 2 ]] || fail "visco sim with the corner's rays exited $status, expected 2: $out"

# A goal narrower than twice the position uncertainty: one behaviour. `visco vcrays` warns and writes its
# output; `visco plan` writes its --out file with "feasible": false and the reason, and exits 1, as when no strategy
# exists within --max-steps.
python3 - "$corner" "$tmp/narrow.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
s["uncertainty"]["position"] = 0.35  # the goal is 0.6 m wide
json.dump(s, open(sys.argv[2], "w"))
PY
out=$("$visco" vcrays "$tmp/narrow.json" --out "$tmp/narrow_rays.json" 2>&1); status=$?
[[ $status -eq 0 ]] || fail "vcrays of a scene with an empty goal kernel exited $status, expected 0: $out"
grep -q "^visco: warning: $tmp/narrow.json: goal: the goal kernel is empty" <<<"$out" || fail "no vcrays warning: $out"
grep -q '"cvc_rays"' "$tmp/narrow_rays.json" || fail "vcrays wrote no output for a valid scene"
out=$("$visco" plan "$tmp/narrow.json" --out "$tmp/narrow_plan.json" 2>&1); status=$?
[[ $status -eq 1 ]] || fail "plan of a scene with an empty goal kernel exited $status, expected 1: $out"
grep -q "visco: $tmp/narrow.json: goal: the goal kernel is empty" <<<"$out" || fail "plan message: $out"
python3 - "$tmp/narrow_plan.json" <<'PY' || fail "plan wrote no infeasible --out file: $(cat "$tmp/narrow_plan.json")"
import json, sys
p = json.load(open(sys.argv[1]))
assert p["feasible"] is False and p["steps"] == [] and "goal kernel is empty" in p["reason"], p
PY

# Bad input: exit 2 naming the file and object.
echo '{"name": "x"}' >"$tmp/bad.json"
out=$("$visco" plan "$tmp/bad.json" 2>&1); status=$?
[[ $status -eq 2 ]] || fail "bad scene exited $status, expected 2"
out=$("$visco" plan "$scene" --max-steps 0 2>&1); status=$?
[[ $status -eq 2 ]] || fail "--max-steps 0 exited $status, expected 2: $out"

echo "$(( failures == 0 ? 1 : 0 )) passed, $(( failures == 0 ? 0 : 1 )) failed"
exit $(( failures == 0 ? 0 : 1 ))

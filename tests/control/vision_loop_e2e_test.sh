#!/usr/bin/env bash
# The closed loop with the real components, as three processes over real LCM (UDP multicast, private port, ttl=0):
#   visco sim   -- the motion-model robot behind the driver, and the rendered camera: the AprilTags of robot and
#                  obstacles drawn from the true poses (data/sim), published as image_t on VISCO_CAMERA_IMAGE;
#   visco track -- the vision pipeline: AprilTag detection and tracking, poses, robot estimate, visual events;
#   visco run   -- the executor: a visual guarded step that stops when vision sees the CM vertex cross the VC line,
#                  then visual compliance along that ray into the slot until vision recognises the goal.
# Scene: the default slot scene with the goal widened to the slot's width (tests/control/data/slot_e2e_scene.json);
# CVC rays: `visco vcrays` of that scene; strategy: tests/control/data/slot_e2e_plan.json, whose compliant step is
# the one `visco backproject SCENE --theta -125 --kernel` proves (its active rays; the guarded step stops on one of
# them, at the border of that VC backprojection). Checked against ground truth: the simulated robot ends in the goal.
# The scene plans with exact compliance (uncertainty.vc_tracking 0): vc9.cm1 ends on the right block's corner with its
# continuation free (it grazes the corner), which the planner refuses under a tracking error (docs/semantics.md,
# "Compliance ends beside the end"); the executor complies on past the corner until contact, into the slot.
# Faults: stale frames (hold, then resume and finish) and the robot's tag lost (occluded: hold, then stop with the
# fault reported).
# usage: vision_loop_e2e_test.sh VISCO [--sanitized]   (slower settings for sanitizer builds; CTest registers the
# test in the normal build only: under ASan vision loses most frames on LCM and the run stops, docs/control.md)
set -uo pipefail
visco="$1"
sanitized="${2:-}"
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
data=tests/control/data
scene=$data/slot_e2e_scene.json
plan=$data/slot_e2e_plan.json
cam=(--camera data/sim/slot_camera.xml --extrinsics data/sim/slot_extrinsics.json --objects data/sim/slot_objects.json)
url="udpm://239.255.76.67:$((22000 + $$ % 20000))?ttl=0"
tmp=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null; done
  [[ -n "${KEEP_TMP:-}" ]] || rm -rf "$tmp"
}
trap cleanup EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

# The camera renders a 640x480 frame in ~35 ms here (several times longer under ASan): the camera rate and the
# vision age limit follow (age = frame period + render + detection + transport, with margin for a loaded machine:
# the three processes share two cores with whatever else runs); so do the driver's watchdog and the controller's
# driver time-outs (the loop runs without SCHED_FIFO here).
if [[ "$sanitized" == "--sanitized" ]]; then
  camera_hz=6 age_ms=800 max_speed=0.4 supersample=1
else
  camera_hz=15 age_ms=400 max_speed=1.0 supersample=2
fi
"$visco" vcrays "$scene" >"$tmp/rays.json" || { echo "FAIL: visco vcrays"; exit 1; }
# The strategy's compliant step is the planner's: its active rays are those of the VC backprojection of the goal
# kernel at its direction, and the guarded step stops on one of them.
theta=$(python3 -S -c 'import json, sys; print(json.load(open(sys.argv[1]))["steps"][1]["theta_deg"])' "$plan")
"$visco" backproject "$scene" --theta "$theta" --kernel >"$tmp/backprojection.json" ||
  { echo "FAIL: visco backproject"; exit 1; }
python3 -S -c '
import json, sys
plan = json.load(open(sys.argv[1]))
planner = sorted(json.load(open(sys.argv[2]))["vc"]["active_rays"])
steps = plan["steps"]
ok = sorted(steps[1]["active_rays"]) == planner and steps[0]["terminate"]["ref"] in planner
print("planner: active rays at %s deg %s; strategy step 1 %s, step 0 stops on %s" %
      (steps[1]["theta_deg"], planner, steps[1]["active_rays"], steps[0]["terminate"]["ref"]))
sys.exit(0 if ok else 1)' "$plan" "$tmp/backprojection.json" || fail "the strategy does not match the planner's backprojection"

# Runs one closed loop; $1 = name, then extra `visco sim` options. Leaves $tmp/$1.{run.json,run.log,sim.json,...}.
loop() {
  local name="$1"
  shift
  "$visco" sim "$scene" "${cam[@]}" --camera-hz $camera_hz --latency-ms 5 --supersample $supersample \
    --image-noise 2 --blur-px 0.5 --seed 7 --lcm-url "$url" --duration 90 --watchdog-ms 500 "$@" \
    >"$tmp/$name.sim.json" 2>"$tmp/$name.sim.log" &
  local sim=$!
  # recv_buf_size: a 640x480 frame (307 kB) is larger than the kernel's default UDP receive buffer (212 kB).
  "$visco" track --lcm --lcm-url "$url&recv_buf_size=4194304" "${cam[@]}" >"$tmp/$name.track.jsonl" 2>"$tmp/$name.track.log" &
  local track=$!
  pids=($sim $track)
  local t0=$SECONDS
  "$visco" run "$plan" --scene "$scene" --rays "$tmp/rays.json" --lcm-url "$url" --max-speed $max_speed \
    --max-accel 4 "${cam[@]}" --max-vision-age-ms $age_ms --max-hold 4 --startup-timeout 30 --status-timeout-ms 500 \
    --heartbeat-timeout-ms 1000 --no-realtime \
    >"$tmp/$name.run.json" 2>"$tmp/$name.run.log"
  run_status=$?
  echo "$name: visco run exited $run_status after $((SECONDS - t0)) s"
  kill -INT $sim $track
  wait $sim $track
  pids=()
}
show() {
  for f in "$tmp/$1".*; do
    echo "--- $(basename "$f")"
    tail -n 25 "$f" | cut -c1-300
  done
}
# Ground truth: the simulated robot's final position (visco sim's summary) is in the goal polygon.
in_goal() {
  python3 -S -c '
import json, sys
p = json.load(open(sys.argv[1]))["position"]
sys.exit(0 if 3.9 <= p[0] <= 4.3 and 0.0 <= p[1] <= 0.8 else 1)' "$1"
}

# 1. Nominal, with stale frames for one second on the way (capture times 1 s old): a hold, then the run resumes.
loop nominal --stale 3 1 --stale-ms 1000
[[ $run_status -eq 0 ]] || fail "nominal run exited $run_status"
grep -q '"result":"done"' "$tmp/nominal.run.json" || fail "nominal run summary is not done"
grep -q 'goal recognised' "$tmp/nominal.run.log" || fail "the log does not say the goal was recognised"
grep -q 'step 0: reached CVC ray "vc9.cm1"' "$tmp/nominal.run.log" || fail "the guarded step did not end on vc9.cm1"
grep -q 'step 1 mode visual-compliant' "$tmp/nominal.run.log" || fail "no visual compliance in step 1"
grep -q '"cvc_ray":"vc9.cm1"[^}]*"state":"negative"' "$tmp/nominal.track.jsonl" ||
  fail "vision never saw the CM vertex on the other side of vc9.cm1"
grep -q '"crossed":1,"cvc_ray":"vc9.cm1"' "$tmp/nominal.track.jsonl" || fail "vision reported no vc9.cm1 crossing"
grep -q 'old (limit' "$tmp/nominal.run.log" || fail "the stale frames caused no hold"
grep -q 'cleared (code 3): vision restored' "$tmp/nominal.run.log" || fail "no resume after the stale frames"
in_goal "$tmp/nominal.sim.json" || fail "the simulated robot did not end in the goal"
grep -q '"bounds_stops":0' "$tmp/nominal.sim.json" || fail "the robot left the workspace"
grep -q '"camera":"rendered"' "$tmp/nominal.sim.json" || fail "the simulated camera did not render"
[[ $failures -eq 0 ]] || show nominal

# 2. The robot's tag is lost (something hides the robot from 3 s on): vision reports it lost, the controller holds,
#    commands zero and stops after --max-hold with the fault reported; the run fails (exit 1).
before=$failures
loop occluded --occlude 3 30
[[ $run_status -eq 1 ]] || fail "occluded run exited $run_status, expected 1"
grep -q '"result":"stopped"' "$tmp/occluded.run.json" || fail "occluded run summary is not stopped"
grep -qE '"stop_code":(2|3)' "$tmp/occluded.run.json" || fail "the stop is not a vision fault"
grep -qE 'robot stopped \(code 2\): .*not observed' "$tmp/occluded.run.log" ||
  fail "the log does not report the robot lost"
grep -q '"valid":0' "$tmp/occluded.track.jsonl" || fail "vision never reported the robot lost"
grep -q '"driver":{[^}]*"state":"stopped"' "$tmp/occluded.sim.json" ||
  grep -q '"driver":{[^}]*"state":"ready"' "$tmp/occluded.sim.json" || fail "the driver did not end stopped"
python3 -S -c '
import json, sys
s = json.load(open(sys.argv[1]))
sys.exit(0 if s["position"][1] > 2.5 else 1)' "$tmp/occluded.sim.json" || fail "the robot went on while unseen"
[[ $failures -eq $before ]] || show occluded

echo "$((failures == 0 ? 1 : 0)) passed, $((failures == 0 ? 0 : 1)) failed"
exit $((failures == 0 ? 0 : 1))

#!/bin/sh
# All V4L2 checks in one VM boot (started by scripts/hil-vm --vivid from CTest, label `hil`), against the vivid driver
# whose output is looped back to its capture:
#  1. the capture source itself (gtest): rendered frames byte for byte, sequence numbers, timestamps, vivid's error
#     injection (dropped buffers, the buffer error flag, no frames, a disconnect and the device's return), bad input;
#  2. `visco capture` as a process publishing over LCM, and `visco track --lcm` taking the calibration from the bus
#     (no --camera, no --extrinsics) and detecting the tags of the frames written to vivid's output;
#  3. `visco track --v4l2` reading the camera in-process;
#  4. `visco capture` refusing a calibration whose image size is not the stream's (exit 2);
#  5. capture-to-publish latency and CPU per frame at 640x480 (vivid's webcam input at 25 Hz, its fastest at that
#     size; step 2 gives the HDMI loop's at 59.94 Hz), figures printed; and the per-frame work benchmark, whose
#     host run tells the emulated CPU's slow-down; the simulated camera's renderer, full against cached (one frame
#     each, a few seconds);
#  6. the closed loop through V4L2 (`visco demo --v4l2-output`): the simulated world renders the camera image at the
#     robot's true pose and writes it to vivid's output; `visco capture` reads it back from the HDMI input, `visco
#     track` and `visco run` close the loop to the driver of the simulated robot, which reaches the goal. The plan is
#     made on the host (PLAN_FILE, `visco plan`: planning on the emulated CPU takes ~40 s) and the run starts half a
#     metre above the goal, in the slot. The log's checks and figures (tests/vision/hil/loop_check.py) and its replay
#     run on the host afterwards (tests/vision/hil/vm_test.sh).
# usage: run_in_vm.sh BUILD_DIR FRAMES_FILE [PLAN_FILE]   (working directory: the repository top)
set -u
build="$1"
frames="$2"
plan="${3:-}"
out="$build/hil-out-v4l2"
mkdir -p "$out"
visco="$build/bin/visco"
test="$build/bin/vision_v4l2_hil_test"
status=0
current=""
step() { current="$*"; echo "== $*"; }
: >/tmp/hil_failures
failed() { status=1; echo "-- FAILED: $current${1:+: $1}" >>/tmp/hil_failures; }
# LCM over UDP multicast on the loopback interface only.
ip link set lo multicast on 2>/dev/null
ip route add 224.0.0.0/4 dev lo 2>/dev/null
# A 640x480 frame is larger than the default socket receive buffer: let LCM have the one it asks for.
sysctl -qw net.core.rmem_max=8388608 2>/dev/null
url="udpm://239.255.76.67:7671?ttl=0&recv_buf_size=4194304"
objects="--objects data/vision/demo_objects.json --quad-sigma 0.8"
calibration="--camera data/vision/synthetic_camera.xml --extrinsics data/vision/demo_extrinsics.json"

step "the V4L2 capture source against vivid (gtest)"
HIL_FRAMES="$frames" "$test" --gtest_brief=1 >/tmp/gtest.log 2>&1 || failed
cat /tmp/gtest.log
grep -E -A4 'Failure$|\[  FAILED  \]' /tmp/gtest.log | head -n 40 >>/tmp/hil_failures

step "visco capture over LCM, visco track --lcm with the calibration from the bus"
"$test" --write-frames "$frames" >/tmp/writer.log 2>&1 &
writer=$!
sleep 1
"$visco" track --lcm --lcm-url "$url" $objects --max-frames 8 --calibration-timeout 120 --no-publish \
  --out "$out/track_lcm.jsonl" 2>"$out/track_lcm.err" &
track=$!
"$visco" capture --device /dev/video0 --input 1 --width 640 --height 480 --pixel-format GREY \
  --camera data/vision/synthetic_camera.xml --extrinsics data/vision/demo_extrinsics.json --lcm-url "$url" \
  --duration 240 >"$out/capture.jsonl" 2>"$out/capture.err" &
capture=$!
wait $track
track_status=$?
kill -TERM $capture 2>/dev/null
wait $capture
capture_status=$?
cat "$out/capture.err" "$out/track_lcm.err"
tail -n 1 "$out/capture.jsonl"
tail -n 1 "$out/track_lcm.jsonl"
[ $track_status -eq 0 ] || failed "track exited $track_status"
[ $capture_status -eq 0 ] || failed "capture exited $capture_status"
python3 -S - "$out/capture.jsonl" "$out/track_lcm.jsonl" "$out/track_lcm.err" <<'PY' || failed "outputs"
import json, sys
cap = [json.loads(l) for l in open(sys.argv[1])]
track = [json.loads(l) for l in open(sys.argv[2])]
summary = cap[-1]["summary"]
assert summary["frames"] > 0 and summary["format"] == "GREY" and summary["width"] == 640, summary
frames = [l for l in track if "seq" in l]
assert len(frames) >= 8, track[-1]
assert all(l["robot"]["valid"] for l in frames), frames
assert all(0 in l["tags"] and 1 in l["tags"] for l in frames), [l["tags"] for l in frames]
err = open(sys.argv[3]).read()
assert "track: calibration from VISCO_CAMERA_INFO" in err and "mismatch" not in err, err
print("capture + track --lcm: ok (%d frames published, %d tracked, robot seen in all)" % (summary["frames"], len(frames)))
PY

step "visco track --v4l2 (the camera in-process)"
"$visco" track --v4l2 /dev/video0 --input 1 --pixel-format GREY $calibration $objects --max-frames 8 --no-publish \
  --out "$out/track_v4l2.jsonl" 2>"$out/track_v4l2.err" || failed "track --v4l2 exited $?"
kill -TERM $writer 2>/dev/null
wait $writer
cat /tmp/writer.log
python3 -S - "$out/track_v4l2.jsonl" <<'PY' || failed "track --v4l2 output"
import json, sys
track = [json.loads(l) for l in open(sys.argv[1])]
frames = [l for l in track if "seq" in l]
assert len(frames) >= 8 and all(l["robot"]["valid"] and 0 in l["tags"] and 1 in l["tags"] for l in frames), track
print("track --v4l2: ok (%d frames, robot seen in all)" % len(frames))
PY

step "visco capture: a calibration for another image size is refused (exit 2)"
"$visco" capture --device /dev/video0 --input 0 --width 320 --height 180 --pixel-format GREY \
  --camera data/vision/synthetic_camera.xml --duration 1 >/dev/null 2>/tmp/mismatch.err
code=$?
cat /tmp/mismatch.err
[ $code -eq 2 ] && grep -q "calibration is for 640x480 but /dev/video0 streams 320x180" /tmp/mismatch.err ||
  failed "exit $code"

step "capture-to-publish latency and CPU per frame: visco capture, 640x480 GREY 25 Hz (webcam input), 10 s"
"$visco" capture --device /dev/video0 --input 0 --width 640 --height 480 --pixel-format GREY --fps 25 \
  --lcm-url "$url" --duration 10 >"$out/bench.jsonl" 2>/tmp/bench.err
code=$?
[ $code -eq 0 ] || { cat /tmp/bench.err; failed "exit $code"; }
tail -n 1 "$out/bench.jsonl"

if [ -x "$build/bin/vision_capture_benchmark" ]; then
  step "the per-frame work of visco capture on the emulated CPU (run it on the host for the slow-down)"
  "$build/bin/vision_capture_benchmark" --benchmark_min_time=0.1 2>&1 | grep -E "^BM_|^-|^Benchmark" ||
    failed "benchmark"
fi

if [ -x "$build/bin/vision_render_benchmark" ]; then
  step "the simulated camera's renderer on the emulated CPU: a full render against the cached one, 640x480"
  "$build/bin/vision_render_benchmark" --benchmark_filter='BM_CachedToReference/1/0' --benchmark_min_time=0.01 2>&1 |
    grep -E "^BM_" || failed "benchmark"
fi

if [ -n "$plan" ]; then
  step "the closed loop through V4L2: world -> vivid output -> visco capture -> track -> run -> driver -> robot"
  # The run's files straight on the host (the guest's memory is small for two loggers' images).
  loop="$out/loop"
  rm -rf "$loop"
  "$test" --setup-loop || failed "setting up vivid's loop"
  started=$(date +%s)
  # --slow-machine 16: the time limits and rates of the emulated CPU (docs/demo.md), the plan's speed 0.6/16 m/s;
  # without image noise and blur, which the emulated CPU renders slowest (docs/camera.md).
  "$visco" demo --plan "$plan" --start 4.1 1.3 --slow-machine 16 --timeout 15 --image-noise 0 --blur-px 0 \
    --v4l2-output /dev/video1 --v4l2-capture /dev/video0 --v4l2-input 1 --out "$loop" >"$out/loop.out" \
    2>"$out/loop.err"
  code=$?
  cat "$out/loop.out"
  tail -n 3 "$out/loop.err"
  echo "the loop's step took $(($(date +%s) - started)) s in the VM"
  [ $code -eq 0 ] || failed "visco demo exited $code"
fi

if [ -s /tmp/hil_failures ]; then
  echo "== summary of the failures"
  cat /tmp/hil_failures
fi
echo "run_in_vm: status $status"
exit $status

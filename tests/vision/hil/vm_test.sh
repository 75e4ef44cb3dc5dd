#!/bin/sh
# vision.hil_v4l2 (CTest, label hil): every V4L2 check in one boot of the VM of scripts/hil-vm --vivid
# (tests/vision/hil/run_in_vm.sh). What the emulated CPU does slowly is done on the host: before the boot, the
# frames the rig writes to vivid's output are rendered and the closed loop's strategy planned; after it, the loop's
# log is checked (tests/vision/hil/loop_check.py: goal, byte-exact frames, figures) and replayed with
# `visco replay --check` and no other file.
# usage: vm_test.sh BUILD_DIR   (working directory: the repository top)
set -u
build="$1"
frames="$build/hil-v4l2-frames.gray"
plan="$build/hil-v4l2-plan.json"
out="$build/hil-out-v4l2"
"$build/bin/vision_v4l2_hil_test" --render-frames "$frames" || exit 1
# The demo's strategy at the speed of --slow-machine 16 (0.6 m/s / 16).
"$build/bin/visco" plan data/scenes/slot.json --speed 0.0375 --out "$plan" || exit 1
rm -rf "$out/loop"
scripts/hil-vm --vivid --workdir "$build" --cwd "$PWD" --timeout 600 -- tests/vision/hil/run_in_vm.sh "$build" \
  "$frames" "$plan"
status=$?
if [ -f "$out/loop/run.lcmlog" ]; then
  echo "== on the host: the closed loop's log (tests/vision/hil/loop_check.py)"
  python3 tests/vision/hil/loop_check.py "$out/loop" || status=1
  echo "== on the host: visco replay run.lcmlog --check, no other file"
  to=$(cat "$out/loop/replay_to" 2>/dev/null)
  [ -z "$to" ] || echo "(up to ${to} s into the log: the logger lost an image vision processed after it)"
  "$build/bin/visco" replay "$out/loop/run.lcmlog" --check --fast --no-publish --no-progress ${to:+--to "$to"} \
    >"$out/loop_replay.txt" 2>&1
  code=$?
  tail -n 3 "$out/loop_replay.txt"
  [ $code -eq 0 ] || { echo "-- FAILED: visco replay --check exited $code"; status=1; }
else
  echo "-- FAILED: the closed loop left no log in $out/loop"
  status=1
fi
echo "vm_test: status $status"
exit $status

#!/bin/sh
# All CAN hardware-in-the-loop checks in one VM boot (started by scripts/hil-vm from CTest, label `hil`):
#  1. candump records the whole bus;
#  2. the controller's SocketCAN link against the `visco driver` process, with injected faults (gtest);
#  3. python-can as an independent peer of a second driver (node 3);
#  4. the candump log decoded with the DBC semantics and a model of the driver's acceptance rule;
#  5. the controller frames of that log (this boot's earlier sessions) replayed with canplayer into a fresh driver:
#     nothing may be applied;
#  6. the controller's loop over the SocketCAN link under the real-time guard, every stop path;
#  7. the CiA 402 backend (`visco-rt driver --robot cia402`) against simulated CiA 402 drives (python-can) on vcan1
#     and vcan0, the drives' traffic recorded and decoded;
#  8. the CiA 402 backend's loop under the real-time guard (no allocation, lock or throw) against the simulator;
#  9. the whole loop through the kernel's interfaces: the simulated world's camera through vivid's video output and
#     V4L2 capture -> `visco track` -> `visco run` -> vcan0 -> `visco-rt driver --robot cia402` -> vcan1 -> simulated
#     drives -> the physics of the simulated world (`visco sim --plant`); the controller, a drive and the driver killed
#     in turn, then the goal and `visco replay --check` of the run's log; both buses decoded, the loop's latency;
# 10. (with --bench) command throughput against cangen and the command-to-feedback round trip.
# usage: run_in_vm.sh BUILD_DIR [--bench]   (working directory: the repository top; the VM of scripts/hil-vm --vivid)
set -u
build="$1"
bench="${2:-}"
out="$build/hil-out"
mkdir -p "$out"
# The real-time programs alone (`visco driver`, `visco run` without planner and vision): they start at once on the
# emulated CPU, where the whole `visco` takes 10-30 s.
export VISCO_BIN="$build/bin/visco-rt"
py=/usr/bin/python3
status=0
current=""
step() { current="$*"; echo "== $*"; }
# A failing check names its step, and the end of the output repeats the failures: CI and ctest show a long log's
# tail only.
: >/tmp/hil_failures
failed() {
  status=1
  echo "-- FAILED: $current" >>/tmp/hil_failures
  [ $# -gt 0 ] && grep -E -A4 'Failure$|\[  FAILED  \]|^FAIL |replay: FAIL|failure\(s\)' "$1" | grep -v '^ok ' | head -n 40 \
    >>/tmp/hil_failures
}
# Runs a command with its output both shown and kept (for the summary); its exit status is the command's.
kept() {
  log=/tmp/hil_step.log
  "$@" >"$log" 2>&1
  rc=$?
  cat "$log"
  return $rc
}

# The buffer holds the whole flood test (~35 000 frames in 0.65 s, ~1 KB each in the kernel): with 4 MB candump fell
# behind under emulation and its log had holes (-d reports them; the decoder fails on them by name).
step "candump -L -D -d vcan0,0:0,#FFFFFFFF (data and error frames, 64 MB socket buffer, drops reported, to tmpfs, kept through interface down)"
candump -L -D -d -r 67108864 "vcan0,0:0,#FFFFFFFF" >/tmp/candump.log 2>&1 &
dump=$!
sleep 0.3

step "controller link vs visco driver, faults injected"
kept "$build/bin/drivers_can_hil_test" --gtest_brief=1 || failed /tmp/hil_step.log

step "python-can peer vs visco driver --node 3"
taskset -c 1 "$VISCO_BIN" driver --can vcan0 --node 3 --watchdog-ms 500 --status-period-ms 20 >/tmp/driver3.log 2>&1 &
driver=$!
kept taskset -c 0 $py -S tests/drivers/hil/python_can_peer.py --node 3 --watchdog-ms 500 || failed /tmp/hil_step.log
kill -TERM $driver 2>/dev/null
wait $driver 2>/dev/null
tail -n 1 /tmp/driver3.log

sleep 0.2
kill -TERM $dump 2>/dev/null
wait $dump 2>/dev/null
cp /tmp/candump.log "$out/candump.log"
step "candump log decoded with drivers/visco.dbc"
kept $py -S tests/drivers/hil/decode_candump.py --self-test drivers/visco.dbc || failed /tmp/hil_step.log
kept $py -S tests/drivers/hil/decode_candump.py drivers/visco.dbc "$out/candump.log" --watchdog-ms 1=300 3=500 9=1000 \
  --slack-ms 250 --expect-faults || failed /tmp/hil_step.log

step "canplayer: this boot's recorded controller frames (commands and NMT of node 1) replayed into a fresh driver"
grep -E '^\([0-9.]+\) vcan0 (201|000)#' "$out/candump.log" | head -n 6000 >/tmp/replay.log
frames=$(wc -l </tmp/replay.log)
# (The driver logs and prints its JSON summary, the last line, on stdout.)
taskset -c 1 "$VISCO_BIN" driver --can vcan0 --node 1 --watchdog-ms 300 >/tmp/replay_driver.out 2>&1 &
rdriver=$!
for _ in $(seq 1 120); do grep -q "session 0x" /tmp/replay_driver.out 2>/dev/null && break; sleep 0.5; done
candump -L "vcan0,181:7FF" >/tmp/replay_status.log 2>&1 &
rdump=$!
sleep 0.3
# In the recorded timing (gaps longer than 1 s skipped): a burst would only overflow the driver's receive queue.
taskset -c 0 canplayer -s 1 -I /tmp/replay.log
sleep 0.5
kill -TERM $rdump 2>/dev/null
wait $rdump 2>/dev/null
kill -TERM $rdriver 2>/dev/null
wait $rdriver 2>/dev/null
cp /tmp/replay_driver.out "$out/replay_driver.out"
$py -S - "$frames" /tmp/replay_driver.out /tmp/replay_status.log <<'PYEOF' || failed
import json, re, sys
frames, statuses = int(sys.argv[1]), sys.argv[3]
summary = json.loads([l for l in open(sys.argv[2], errors="replace") if l.startswith("{")][-1])
moving = 0
count = 0
for line in open(statuses, errors="replace"):
    m = re.match(r"^\(\S+\) \S+ 181#([0-9A-Fa-f]{16})", line)
    if m:
        d = bytes.fromhex(m.group(1))
        count += 1
        moving += d[2:6] != bytes(4) or (d[6] & 0x0F) in (1, 2)
print("replay: %d recorded frames into a fresh driver: applied %d, resets %d, wrong session %d, bad %d, "
      "out of sequence %d, e-stops %d; %d statuses, %d of them moving or enabled; final state %s" %
      (frames, summary["commands_applied"], summary["resets"], summary["wrong_session"], summary["bad_commands"],
       summary["out_of_sequence"], summary["estops"], count, moving, summary["state"]))
ok = frames > 500 and summary["commands_applied"] == 0 and summary["resets"] == 0 and moving == 0 and count > 0 \
    and summary["wrong_session"] + summary["bad_commands"] > frames // 2
print("replay: " + ("ok" if ok else "FAIL"))
sys.exit(0 if ok else 1)
PYEOF
step "the control loop over the SocketCAN link under the real-time guard (SCHED_FIFO, mlockall, every stop path)"
kept "$build/bin/control_can_realtime_hil_test" --gtest_brief=1 || failed /tmp/hil_step.log

step "CiA 402 backend vs simulated CiA 402 drives (tests/drivers/hil/cia402_drive_sim.py) on vcan1 and vcan0"
candump -L -D -r 16777216 vcan0 vcan1 >/tmp/cia402_candump.log 2>&1 &
cdump=$!
sleep 0.3
kept taskset -c 0 $py -S tests/drivers/hil/cia402_hil_test.py "$VISCO_BIN" || failed /tmp/hil_step.log
sleep 0.2
kill -TERM $cdump 2>/dev/null
wait $cdump 2>/dev/null
cp /tmp/cia402_candump.log "$out/cia402_candump.log"
for f in /tmp/cia402_*.log; do [ -f "$f" ] && cp "$f" "$out/"; done
step "CiA 402 candump decoded (NMT, SYNC, SDO, EMCY, the mapped PDOs): checks and bus load"
kept $py -S tests/drivers/hil/decode_cia402.py --self-test || failed /tmp/hil_step.log
kept $py -S tests/drivers/hil/decode_cia402.py "$out/cia402_candump.log" --nodes 2 3 --visco-node 1 \
  || failed /tmp/hil_step.log

step "the CiA 402 backend's loop (SetVelocity, Step, Read, QuickStop, Reset) under the real-time guard, against the drive simulator on vcan1"
kept "$build/bin/drivers_cia402_realtime_hil_test" --gtest_brief=1 || failed /tmp/hil_step.log

step "the whole loop through the kernel's interfaces (tests/drivers/hil/whole_loop_test.py): kills, then the goal"
loop_start=$(date +%s)
if "$build/bin/vision_v4l2_hil_test" --setup-loop >/tmp/hil_step.log 2>&1; then
  kept $py -S tests/drivers/hil/whole_loop_test.py "$build" "$out/loop" || failed /tmp/hil_step.log
else
  cat /tmp/hil_step.log
  failed
fi
echo "whole loop: $(($(date +%s) - loop_start)) s in the VM"
step "whole loop: both buses decoded (traffic, bus load, command -> drive); camera frame -> drive target"
kept $py -S tests/drivers/hil/decode_cia402.py "$out/loop/candump.log" --nodes 2 3 --visco-node 1 \
  || failed /tmp/hil_step.log
kept $py -S tests/drivers/hil/loop_latency.py "$out/loop/controller.lcmlog" "$out/loop/candump.log" \
  || failed /tmp/hil_step.log

if [ "$bench" = "--bench" ]; then
  step "benchmarks on vcan0: command throughput vs cangen, round trip vs vcan loopback"
  kept "$build/bin/drivers_can_benchmark" --benchmark_min_time=0.2 --benchmark_counters_tabular=true || failed /tmp/hil_step.log
fi
if [ -s /tmp/hil_failures ]; then
  echo "== summary of the failures"
  cat /tmp/hil_failures
fi
echo "run_in_vm: status $status"
exit $status

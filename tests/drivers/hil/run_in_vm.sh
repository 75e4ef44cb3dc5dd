#!/bin/sh
# All CAN hardware-in-the-loop checks in one VM boot (started by scripts/hil-vm from CTest, label `hil`):
#  1. candump records the whole bus;
#  2. the controller's SocketCAN link against the `visco driver` process, with injected faults (gtest);
#  3. python-can as an independent peer of a second driver (node 3);
#  4. the candump log decoded with the DBC semantics;
#  5. (with --bench) command throughput against cangen and the command-to-feedback round trip.
# usage: run_in_vm.sh BUILD_DIR [--bench]   (working directory: the repository top)
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
step() { echo "== $*"; }

step "candump -L -D vcan0,0:0,#FFFFFFFF (data and error frames, 4 MB socket buffer, to tmpfs, kept through interface down)"
candump -L -D -r 4194304 "vcan0,0:0,#FFFFFFFF" >/tmp/candump.log 2>&1 &
dump=$!
sleep 0.3

step "controller link vs visco driver, faults injected"
"$build/bin/drivers_can_hil_test" --gtest_brief=1 || status=1

step "python-can peer vs visco driver --node 3"
taskset -c 1 "$VISCO_BIN" driver --can vcan0 --node 3 --watchdog-ms 500 --status-period-ms 20 >/tmp/driver3.log 2>&1 &
driver=$!
taskset -c 0 $py -S tests/drivers/hil/python_can_peer.py --node 3 --watchdog-ms 500 || status=1
kill -TERM $driver 2>/dev/null
wait $driver 2>/dev/null
tail -n 1 /tmp/driver3.log

sleep 0.2
kill -TERM $dump 2>/dev/null
wait $dump 2>/dev/null
cp /tmp/candump.log "$out/candump.log"
step "candump log decoded with drivers/visco.dbc"
$py -S tests/drivers/hil/decode_candump.py drivers/visco.dbc "$out/candump.log" --watchdog-ms 1=300 3=500 \
  --expect-faults || status=1
if [ "$bench" = "--bench" ]; then
  step "benchmarks on vcan0: command throughput vs cangen, round trip vs vcan loopback"
  "$build/bin/drivers_can_benchmark" --benchmark_min_time=0.2 --benchmark_counters_tabular=true || status=1
fi
echo "run_in_vm: status $status"
exit $status

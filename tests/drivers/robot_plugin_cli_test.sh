#!/bin/sh
# `visco-rt driver` with a robot plugin chosen by a parameter file (--config): the example plugin loads and the driver
# runs; a missing library and a bad CiA 402 configuration are clear errors (exit 2) naming the file and the key.
# usage: robot_plugin_cli_test.sh VISCO_RT PLUGIN
set -u
rt="$1"
plugin="$2"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
echo '{"time_constant_s": 0.05, "workspace": [-1, -1, 1, 1]}' >"$tmp/stage.json"
cat >"$tmp/params.json" <<JSON
{"driver": {"robot": "plugin", "robot-plugin": "$plugin", "robot-config": "$tmp/stage.json", "duration": 0.3,
            "lcm-url": "memq://"}}
JSON
"$rt" --config "$tmp/params.json" driver >"$tmp/out" 2>"$tmp/err" || { cat "$tmp/err"; fail "the plugin run failed"; }
grep -q "plugin robot at (0, 0)" "$tmp/err" || fail "the driver did not run the plugin robot"
grep -q '"state": "disabled"' "$tmp/out" || fail "no JSON summary"
"$rt" driver --robot plugin --robot-plugin "$tmp/none.so" --lcm-url memq:// 2>"$tmp/err"
[ $? -eq 2 ] || fail "a missing plugin must exit 2"
grep -q "none.so: cannot load the robot plugin" "$tmp/err" || fail "the error does not name the library"
echo '{"format": "visco-cia402-1", "interface": "can1", "axes": [{"node": 2, "counts_per_metre": 1e5},
      {"node": 2, "counts_per_metre": 1e5}]}' >"$tmp/drives.json"
"$rt" driver --robot cia402 --robot-config "$tmp/drives.json" --lcm-url memq:// 2>"$tmp/err"
[ $? -eq 2 ] || fail "a bad drive configuration must exit 2"
grep -q "drives.json: axes\[1\].node: node 2 twice" "$tmp/err" || { cat "$tmp/err"; fail "the error does not name the key"; }
echo "robot plugin CLI: ok"

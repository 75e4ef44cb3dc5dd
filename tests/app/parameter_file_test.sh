#!/usr/bin/env bash
# Parameter files (`--config FILE`, docs/formats.md): a command's options from JSON, the command line winning over
# the file, values checked as on the command line, and an unknown key refused with exit 2 naming the file and key;
# in all three programs (visco, visco-full through it, visco-rt).
set -uo pipefail
visco="$1"
rt="$2"
scene="$3"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

# visco-rt driver from a file: the world, start and seed from it; its summary shows the start was taken.
"$visco" sim "$scene" --write-world "$tmp/world.json" --start 2 6 || fail "visco sim --write-world exited $?"
python3 -c 'import json,sys; w = json.load(open(sys.argv[1])); assert w["start"] == [2, 6] and w["obstacles"], w' \
  "$tmp/world.json" || fail "world.json: $(head -c 300 "$tmp/world.json")"
cat >"$tmp/driver.json" <<JSON
{"driver": {"world": "$tmp/world.json", "start": [2.5, 6.5], "duration": 0.3, "lcm-url": "udpm://239.255.76.67:$((30000 + $$ % 20000))?ttl=0"}}
JSON
out=$("$rt" driver --config "$tmp/driver.json" 2>"$tmp/driver.err") || fail "driver --config exited $?: $(cat "$tmp/driver.err")"
python3 -c 'import json,sys; d = json.loads(sys.argv[1]); assert d["position"] == [2.5, 6.5], d' "$out" ||
  fail "the driver did not start where the file says: $out"
grep -q "among [1-9][0-9]* C-obstacle" "$tmp/driver.err" || fail "the driver did not load the world: $(cat "$tmp/driver.err")"
# The command line wins over the file (and --config may come first).
out=$("$rt" --config "$tmp/driver.json" driver --start 3 6.5 2>/dev/null) || fail "command-line override exited $?"
python3 -c 'import json,sys; d = json.loads(sys.argv[1]); assert d["position"] == [3, 6.5], d' "$out" ||
  fail "the command line did not win: $out"

# A relative path in the file is relative to the file's folder (the demo's driver.json named a world relative
# to where the demo ran), from any working directory.
mkdir -p "$tmp/conf"
cat >"$tmp/conf/driver.json" <<JSON
{"driver": {"world": "../world.json", "duration": 0.3, "lcm-url": "udpm://239.255.76.67:$((30000 + $$ % 20000))?ttl=0"}}
JSON
out=$(cd / && "$rt" driver --config "$tmp/conf/driver.json" 2>"$tmp/driver.err") ||
  fail "driver --config with a relative world, from /, exited $?: $(cat "$tmp/driver.err")"
grep -q "among [1-9][0-9]* C-obstacle" "$tmp/driver.err" || fail "the relative world was not loaded: $(cat "$tmp/driver.err")"
python3 -c 'import json,sys; d = json.loads(sys.argv[1]); assert d["position"] == [2, 6], d' "$out" ||
  fail "the driver did not start where the relative world says: $out"

# Unknown key, unknown command, bad value, bad JSON, missing file: exit 2 naming the file and what is wrong.
expect2() {
  local what="$1" pattern="$2"
  shift 2
  "$@" >"$tmp/o" 2>"$tmp/e"
  local status=$?
  [[ $status -eq 2 ]] || fail "$what: exit $status (expected 2): $(cat "$tmp/e")"
  grep -q -- "$pattern" "$tmp/e" || fail "$what: the message lacks '$pattern': $(cat "$tmp/e")"
}
echo '{"driver": {"speed": 3}}' >"$tmp/k.json"
expect2 "unknown key" "k.json: driver.speed: unknown command or option" "$rt" driver --config "$tmp/k.json"
echo '{"drivr": {"duration": 1}}' >"$tmp/c.json"
expect2 "unknown command" "c.json: drivr.duration" "$rt" driver --config "$tmp/c.json"
echo '{"driver": {"node": 300, "duration": 0.1}}' >"$tmp/v.json"
expect2 "value out of range" "node" "$rt" driver --config "$tmp/v.json"
echo '{"driver": ' >"$tmp/j.json"
expect2 "bad JSON" "not valid JSON" "$rt" driver --config "$tmp/j.json"
expect2 "missing file" "$tmp/none.json" "$rt" driver --config "$tmp/none.json"

# The planner's program and visco-full (through it) read them too.
echo "{\"vcrays\": {\"SCENE\": \"$scene\"}}" >"$tmp/vcrays.json"
a=$("$visco" vcrays --config "$tmp/vcrays.json" 2>&1) || fail "visco vcrays --config exited $?: $a"
b=$("$visco" vcrays "$scene" 2>&1)
[[ "$a" == "$b" ]] || fail "vcrays from the file differs from the command line"
echo '{"sim": {"bogus": 1}}' >"$tmp/s.json"
expect2 "visco-full unknown key" "s.json: sim.bogus" "$visco" sim "$scene" --config "$tmp/s.json"

[[ $failures -eq 0 ]] && echo "parameter files: all checks passed"
exit $((failures > 0))

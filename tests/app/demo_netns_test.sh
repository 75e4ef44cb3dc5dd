#!/usr/bin/env bash
# `visco demo --netns`: the demo's processes on hosts of their own (a network namespace each, veth to a bridge, LCM
# multicast with ttl=1 across it), as on several machines; the run reaches the goal, summary.json says where each
# process ran (and each was seen in its own namespace, none in the demo's), and no namespace is left afterwards.
# Needs root and iproute2: skipped (77) otherwise.
set -uo pipefail
visco="$1"
# The probe makes what the demo makes, on a small scale: a namespace with a bridge and a veth pair into another.
probe() {
  local a="visco-probe-$$-a" b="visco-probe-$$-b" ok=0
  ip netns add "$a" 2>/dev/null || return 1
  if ip netns add "$b" 2>/dev/null; then
    ip -n "$a" link add br0 type bridge mcast_snooping 0 2>/dev/null &&
      ip -n "$a" link add p0 type veth peer name eth0 netns "$b" 2>/dev/null &&
      ip -n "$a" link set p0 master br0 up 2>/dev/null && ok=1
    ip netns del "$b"
  fi
  ip netns del "$a"
  [[ $ok -eq 1 ]]
}
if [[ $(id -u) -ne 0 ]] || ! command -v ip >/dev/null || ! probe; then
  echo "SKIP: needs root, network namespaces, bridges and veth pairs"
  exit 77
fi
tmp=$(mktemp -d)
trap 'pkill -f "$tmp" 2>/dev/null; rm -rf "$tmp"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

"$visco" demo --netns --out "$tmp/d" >"$tmp/out.txt" 2>"$tmp/err.txt"
status=$?
[[ $status -eq 0 ]] || { fail "visco demo --netns exited $status"; cat "$tmp/out.txt" "$tmp/err.txt"; tail -20 "$tmp"/d/*.log; }
grep -q "a host of its own" "$tmp/err.txt" || fail "no word about the hosts on stderr: $(cat "$tmp/err.txt")"
grep -q "ttl=1" "$tmp/err.txt" || fail "the bus is not ttl=1: $(cat "$tmp/err.txt")"
python3 - "$tmp/d/summary.json" <<'PY' || fail "summary.json: $(head -c 2000 "$tmp/d/summary.json")"
import json, sys
s = json.load(open(sys.argv[1]))
assert s["netns"] is True, s
run = s["runs"][0]
assert run["success"] and run["result"] == "done", run
n = run["netns"]
assert set(n) == {"lcm-logger", "driver", "camera", "track", "run"}, n
inodes = [p["namespace_inode"] for p in n.values()]
assert all(inodes) and len(set(inodes)) == 5, n
for name, p in n.items():
    assert p["seen_in_inode"] == p["namespace_inode"], (name, p)
    assert p["seen_in_inode"] != run["demo_netns_inode"], (name, p)
assert len({p["address"] for p in n.values()}) == 5, n
assert run["logged_messages"] > 100 and run["commands_sent"] > 100, run
print(" ".join(p["namespace"] for p in n.values()))
PY
prefix=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["runs"][0]["netns"]["driver"]["namespace"].rsplit("-", 1)[0])' "$tmp/d/summary.json" 2>/dev/null)
if [[ -n "$prefix" ]]; then
  left=$(ip netns list | grep -c "^$prefix-")
  [[ $left -eq 0 ]] || fail "$left namespace(s) left: $(ip netns list | grep "^$prefix-")"
fi
# Without root the flag is refused with exit 2 (as a user would run it).
if id nobody >/dev/null 2>&1 && command -v setpriv >/dev/null &&
  setpriv --reuid=nobody --regid=nogroup --clear-groups "$visco" --version >/dev/null 2>&1; then
  setpriv --reuid=nobody --regid=nogroup --clear-groups "$visco" demo --netns --out "$tmp/nr" >/dev/null 2>"$tmp/nr.err"
  status=$?
  [[ $status -eq 2 ]] && grep -q -- "--netns: needs root" "$tmp/nr.err" ||
    fail "--netns without root: exit $status: $(cat "$tmp/nr.err")"
fi

[[ $failures -eq 0 ]] && echo "demo --netns: all checks passed"
exit $((failures > 0))

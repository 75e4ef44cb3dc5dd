#!/usr/bin/env bash
# The README's first command as written, `scripts/demo --out DIR`, on the built tree: it runs scripts/setup, configures
# and builds target visco in build/ (seconds when the tree is built), then `visco demo` (not `visco --help`, as it did
# when a SIGPIPE'd probe fell through). The goal is reached (summary.json); a relative DIR is the caller's;
# the parameter files of the run name files that resolve from their own folder.
# usage: scripts_demo_test.sh SOURCE_DIR VISCO   (skipped, exit 77, unless VISCO is SOURCE_DIR/build/bin/visco: the
# script builds build/, and building another tree there would cost minutes)
set -uo pipefail
src="$1"
visco="$2"
if [[ "$(realpath "$visco")" != "$(realpath -m "$src/build/bin/visco")" ]]; then
  echo "skipped: this build tree is not $src/build, which scripts/demo builds"
  exit 77
fi
if ! "$src/scripts/setup" --check >/dev/null; then
  echo "skipped: packages missing, which scripts/demo would install: $("$src/scripts/setup" --check)"
  exit 77
fi
tmp=$(mktemp -d)
trap 'pkill -f "$tmp" 2>/dev/null; rm -rf "$tmp"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

# From another directory, a relative --out: the outputs land there.
start=$(date +%s%N)
(cd "$tmp" && "$src/scripts/demo" --out d) >"$tmp/out.txt" 2>"$tmp/err.txt" &
demo=$!
# The set-up and build part ends when `visco demo` speaks.
until grep -q "^visco demo: " "$tmp/err.txt" 2>/dev/null || ! kill -0 $demo 2>/dev/null; do sleep 0.1; done
setup_ms=$(( ($(date +%s%N) - start) / 1000000 ))
wait $demo
status=$?
echo "scripts/demo: set-up, configure and build of the built tree took $((setup_ms / 1000)).$(printf %03d $((setup_ms % 1000))) s; exit $status"
[[ $status -eq 0 ]] || { fail "scripts/demo --out d exited $status"; tail -20 "$tmp/out.txt" "$tmp/err.txt"; }
grep -q "1 of 1 run(s) reached the goal recognisably" "$tmp/out.txt" || fail "no demo summary: $(tail -5 "$tmp/out.txt")"
! grep -q "^Subcommands:" "$tmp/out.txt" || fail "scripts/demo printed visco's --help"
(( setup_ms < 60000 )) || fail "set-up and build of a built tree took ${setup_ms} ms (seconds expected)"
python3 - "$tmp/d" <<'PY' || fail "summary.json does not say the goal was reached"
import json, os, sys
d = sys.argv[1]
s = json.load(open(os.path.join(d, "summary.json")))
run = s["runs"][0]
assert run["success"] and run["result"] == "done" and run["goal_error_m"] == 0.0, run
# The parameter files name what resolves from their own folder (here absolute), from any working directory.
for name in ("driver", "camera", "run"):
    p = json.load(open(os.path.join(d, "params", name + ".json")))
    for command, options in p.items():
        for key in ("world", "rays", "scene", "camera", "extrinsics", "objects", "log"):
            if key in options:
                path = os.path.join(d, "params", options[key])
                assert os.path.exists(path), (name, key, options[key])
PY

# docs/getting_started.md's table of the demo's outputs names what the demo writes, and every file it writes.
python3 - "$tmp/d" "$src/docs/getting_started.md" <<'PY' || fail "docs/getting_started.md's table of outputs is out of date"
import fnmatch, glob, os, re, sys
d, page = sys.argv[1], open(sys.argv[2], encoding="utf-8").read()
table = page[page.index("| file in `/tmp/demo` |"):].split("\n\n")[0]
patterns = [p for row in table.splitlines()[2:] for p in re.findall(r"`([^`]+)`", row.split("|")[1])]
assert patterns, "no table"
for p in patterns:
    assert glob.glob(os.path.join(d, p)), "the page lists %s, the demo wrote none" % p
for root, _, files in os.walk(d):
    for f in files:
        rel = os.path.relpath(os.path.join(root, f), d)
        assert any(fnmatch.fnmatch(rel, p) for p in patterns), "the demo wrote %s, the page does not list it" % rel
PY

echo "$(( failures == 0 ? 1 : 0 )) passed, $(( failures == 0 ? 0 : 1 )) failed"
exit $(( failures == 0 ? 0 : 1 ))

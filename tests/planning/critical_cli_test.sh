#!/usr/bin/env bash
# `visco critical` (docs/formats.md): the JSON's shape, the kinetic walk and the critical-slice baseline agreeing on
# the orientations, the slices (one per orientation and one per open interval, each interval inside its neighbours'
# orientations), the start region's intervals, the sweeps by purpose adding up, --svg, --out, and exit 2 on bad input.
set -uo pipefail
visco="$1"
scene="$2"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

"$visco" critical "$scene" --slices --svg "$tmp/c.svg" --out "$tmp/k.json" || fail "critical exited $?"
"$visco" critical "$scene" --method baseline --threads 1 > "$tmp/b.json" || fail "critical --method baseline exited $?"
python3 - "$tmp/k.json" "$tmp/b.json" <<'PY' || failures=$((failures + 1))
import json, sys
k = json.load(open(sys.argv[1]))
b = json.load(open(sys.argv[2]))
kinds = {"vgraph", "sliding", "vertex", "R", "free-edge", "vc", "selection"}
for d in (k, b):
    o = d["orientations"]
    assert o, "no orientation"
    thetas = [x["theta_deg"] for x in o]
    assert thetas == sorted(thetas) and -180 <= thetas[0] and thetas[-1] < 180, thetas
    for x in o:
        assert x["kind"] in kinds, x
        assert x["refs"] and all(isinstance(r, str) and r for r in x["refs"]), x
        assert ("cause" in x) == (x["kind"] == "sliding"), x
        assert x.get("cause", "sticking") in ("sticking", "contact", "vertex-rule"), x
    st = d["stats"]
    assert st["unexplained"] == 0 and st["found_by_probes"] == 0, st
    assert st["rule_missed"] - st["rule_missed_sliding"] == 0, st
    assert 0 <= st["explained"] <= st["changes"], st
    assert 0 <= st["updated"] <= st["events"], st
    assert st["changes"] == sum(1 for x in o if x["kind"] != "R"), st
    assert st["r_critical"] == sum(1 for x in o if x["kind"] == "R"), st
    assert sum(st["sweeps"].values()) == st["backprojections"], st
    assert set(st["sweeps"]) == {"walk", "locate", "checks", "bisect", "slices"}, st["sweeps"]
    assert st["candidates"] == sum(st["candidates_by_kind"].values()), st
# The same orientations by both methods (the baseline sweeps every interval between candidates), the kinetic walk
# with fewer sweeps.
key = lambda d: [(round(x["theta_deg"], 9), x["kind"]) for x in d["orientations"]]
assert key(k) == key(b), (key(k), key(b))
assert k["stats"]["method"] == "kinetic" and b["stats"]["method"] == "baseline"
assert b["stats"]["explained"] == 0 and b["stats"]["updated"] == 0, b["stats"]
assert b["stats"]["sweeps"]["walk"] == b["stats"]["events"], b["stats"]
assert k["stats"]["sweeps"]["walk"] < b["stats"]["sweeps"]["walk"], (k["stats"], b["stats"])
assert "slices" not in b
# Slices: a critical one at each structural orientation, then the open interval up to the next one (wrapping).
s = k["slices"]
structural = [x["theta_deg"] for x in k["orientations"] if x["kind"] != "R"]
assert len(s) == 2 * len(structural), (len(s), len(structural))
for i, t in enumerate(structural):
    crit, open_ = s[2 * i], s[2 * i + 1]
    assert crit["critical"] and abs(crit["lo_deg"] - t) < 1e-9 and crit["lo_deg"] == crit["hi_deg"], crit
    assert not open_["critical"] and abs(open_["lo_deg"] - t) < 1e-9, open_
    nxt = structural[(i + 1) % len(structural)] + (360 if i + 1 == len(structural) else 0)
    assert abs(open_["hi_deg"] - nxt) < 1e-9, open_
    mid = open_["theta_deg"] + (360 if open_["theta_deg"] < open_["lo_deg"] else 0)  # the last interval wraps
    assert open_["lo_deg"] < mid < open_["hi_deg"], open_
    for sl in (crit, open_):
        assert sl["classic"]["area"] <= sl["vc"]["area"] * (1 + 1e-12) + 1e-12, sl["theta_deg"]
# The start region's intervals: inside [-180, 180 + 360), each with its best orientation inside it.
for key_ in ("classic", "vc"):
    for iv in k["start_intervals"][key_]:
        assert iv["lo_deg"] <= iv["best_theta_deg"] <= iv["hi_deg"] or iv["lo_deg"] <= iv["best_theta_deg"] + 360 <= iv["hi_deg"], iv
        assert iv["margin"] >= 0, iv
PY
# The picture: well-formed, two area curves and a line per orientation.
python3 - "$tmp/c.svg" "$tmp/k.json" <<'PY' || fail "the SVG is not a well-formed document with both curves"
import json, sys, xml.etree.ElementTree as ET
ns = "{http://www.w3.org/2000/svg}"
root = ET.parse(sys.argv[1]).getroot()
assert root.tag == ns + "svg", root.tag
assert len(list(root.iter(ns + "polyline"))) + len(list(root.iter(ns + "path"))) >= 2
n = len(json.load(open(sys.argv[2]))["orientations"])
assert len(list(root.iter(ns + "line"))) >= n, (len(list(root.iter(ns + "line"))), n)
PY
# Bad input: exit 2 and a message naming what is wrong.
"$visco" critical "$tmp/missing.json" > /dev/null 2> "$tmp/err"
[ $? -eq 2 ] || fail "a missing scene did not exit 2"
grep -q "missing.json" "$tmp/err" || fail "the error does not name the missing file: $(cat "$tmp/err")"
echo '{"obstacles": [' > "$tmp/broken.json"
"$visco" critical "$tmp/broken.json" > /dev/null 2> "$tmp/err"
[ $? -eq 2 ] || fail "a broken scene did not exit 2"
"$visco" critical "$scene" --resweep-period -1 > /dev/null 2>&1
[ $? -eq 2 ] || fail "--resweep-period -1 did not exit 2"
"$visco" critical --help | grep -q -- "--method" || fail "--help does not list --method"

[ "$failures" -eq 0 ] && echo "critical CLI: all checks passed"
exit "$failures"

#!/usr/bin/env bash
# `visco backproject` (CONTRACT.md): JSON shape, provenance kinds, B_θ ⊆ B_vcθ by area, --kernel, --svg, exit 2 on
# bad input.
set -uo pipefail
visco="$1"
scene="$2"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

"$visco" backproject "$scene" --theta -90 --out "$tmp/b.json" --svg "$tmp/b.svg" || fail "backproject exited $?"
python3 - "$tmp/b.json" <<'PY' || failures=$((failures + 1))
import json, sys
d = json.load(open(sys.argv[1]))
assert d["theta_deg"] == -90, d["theta_deg"]
for key in ("classic", "vc"):
    r = d[key]
    assert r["area"] > 0, (key, r["area"])
    for poly in r["regions"]:
        for ring in [poly["outer"]] + poly["holes"]:
            assert len(ring["vertices"]) == len(ring["edges"]) >= 3
            for e in ring["edges"]:
                assert e["kind"] in ("obstacle", "goal", "free", "vc", "bounds"), e
                assert isinstance(e["ref"], str) and e["ref"], e
assert isinstance(d["vc"]["active_rays"], list)
assert d["vc"]["area"] >= d["classic"]["area"] * (1 - 1e-12)
sel = d["vc"]["ray_selection"]
assert sel["method"] in ("exact", "greedy", "none"), sel
assert sel["candidates"] >= 0 and sel["sweeps"] >= 1, sel
if sel["method"] == "exact":
    assert sel["sweeps"] == 2 ** sel["candidates"], sel
PY
# Forcing the greedy choice: never a larger region than the default (exact up to the limit) choice.
"$visco" backproject "$scene" --theta -90 --exact-limit -1 > "$tmp/g.json" || fail "--exact-limit -1 exited $?"
python3 -c "import json; g=json.load(open('$tmp/g.json'))['vc']; d=json.load(open('$tmp/b.json'))['vc']; \
assert g['ray_selection']['method'] in ('greedy', 'none'); assert g['area'] <= d['area'] * (1 + 1e-12)" \
  || fail "the greedy choice is not reported or is larger than the exact one"
grep -q "<svg" "$tmp/b.svg" || fail "no SVG written"
"$visco" backproject "$scene" --theta -90 --kernel > "$tmp/k.json" || fail "--kernel exited $?"
python3 -c "import json,sys; a=json.load(open('$tmp/k.json')); b=json.load(open('$tmp/b.json')); assert 0 < a['classic']['area'] < b['classic']['area']" \
  || fail "the kernel's backprojection is not smaller"
out=$("$visco" backproject /no/such/scene.json --theta 0 2>&1); status=$?
[[ $status -eq 2 && "$out" == visco:\ /no/such/scene.json* ]] || fail "missing scene: status $status, '$out'"
out=$("$visco" backproject "$scene" 2>&1); status=$?
[[ $status -eq 2 ]] || fail "missing --theta: status $status"
out=$("$visco" backproject "$scene" --theta abc 2>&1); status=$?
[[ $status -eq 2 ]] || fail "bad --theta: status $status"
echo "$(( failures == 0 ? 1 : 0 )) passed, $failures failed"
exit $(( failures == 0 ? 0 : 1 ))

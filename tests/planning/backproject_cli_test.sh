#!/usr/bin/env bash
# `visco backproject` (docs/formats.md): JSON shape, provenance kinds, B_θ ⊆ B_vcθ by area, --kernel, --svg, exit 2 on
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
assert sel["method"] in ("track", "none"), sel
assert sel["candidates"] >= 0 and sel["sweeps"] >= 1, sel
assert sel["sweeps"] <= 3 * sel["candidates"] + 1, sel
PY
# The exact search (every subset) as a reference: never a smaller region than the default choice, 2^k sweeps.
"$visco" backproject "$scene" --theta -90 --ray-selection exact --exact-limit 12 > "$tmp/x.json" || fail "--ray-selection exact exited $?"
python3 -c "import json; x=json.load(open('$tmp/x.json'))['vc']; d=json.load(open('$tmp/b.json'))['vc']; \
s=x['ray_selection']; assert s['method'] in ('exact', 'none'); assert s['sweeps'] == 2 ** s['candidates']; \
assert x['area'] >= d['area'] * (1 - 1e-12)" \
  || fail "the exact choice is not reported, or is smaller than the default one"
"$visco" backproject "$scene" --theta -90 --ray-selection nonsense > /dev/null 2>&1 && fail "a bad --ray-selection was accepted"
[ $? -eq 2 ] || fail "a bad --ray-selection did not exit 2"
# The picture: well-formed XML, one document with both panels side by side, each with its own drawing and title.
python3 - "$tmp/b.svg" <<'PY' || fail "the SVG is not one well-formed document with both panels"
import re, sys, xml.etree.ElementTree as ET
ns = "{http://www.w3.org/2000/svg}"
root = ET.parse(sys.argv[1]).getroot()
assert root.tag == ns + "svg", root.tag
groups = {g.get("id"): g for g in root.iter(ns + "g")}
assert set(groups) == {"classic", "vc"}, sorted(groups)
shift = {k: float(re.fullmatch(r"translate\(([-0-9.]+),0\)", g.get("transform")).group(1)) for k, g in groups.items()}
assert shift["classic"] == 0 and shift["vc"] > 0, shift
assert float(root.get("width")) >= 2 * shift["vc"] * 0.9, (root.get("width"), shift)
titles = {"classic": "classic B_θ(G)", "vc": "VC-enlarged B_vcθ(G)"}
for key, g in groups.items():
    assert len(list(g.iter(ns + "path"))) >= 4, key  # bounds, region, obstacles, C-obstacles, goal
    assert len(list(g.iter(ns + "line"))) >= 4, key  # region edges, velocity arrow
    assert any(t.text and t.text.startswith(titles[key]) for t in g.iter(ns + "text")), key
    # A legend in words for what each colour means.
    legend = [t.text for t in g.iter(ns + "text") if t.get("class") == "legend"]
    for words in ("the backprojection", "its edges on an active ray", "obstacle", "C-obstacle", "goal",
                  "active CVC ray", "commanded direction θ", "camera"):
        assert any(w == words or w.startswith(words + " ") for w in legend), (key, words, legend)
PY
# Refs name file positions (docs/formats.md): the same scene with every polygon written clockwise from another vertex
# gives the same regions; goal refs name the same file edges (renumbered by the rewrite), and every obstacle ref
# names, in each file, a Minkowski segment (obstacle edge - robot vertex, or obstacle vertex - robot edge) that
# contains its edge. (Where several coincident segments contain an edge, the first by file position wins, so which
# one is named may change with the numbering.)
python3 - "$scene" "$tmp/cw.json" <<'PY' || fail "could not write the rewritten scene"
import json, sys
d = json.load(open(sys.argv[1]))
def rewrite(p):  # file vertex k moves to position (n - k) % n; file edge k (k -> k+1) becomes edge (n - 1 - k) % n
    return [p[0]] + p[1:][::-1]
d["robot"]["polygon"] = rewrite(d["robot"]["polygon"])
d["goal"]["polygon"] = rewrite(d["goal"]["polygon"])
for o in d["obstacles"]:
    o["polygon"] = rewrite(o["polygon"])
json.dump(d, open(sys.argv[2], "w"))
PY
"$visco" backproject "$tmp/cw.json" --theta -90 --out "$tmp/cw_b.json" || fail "backproject of the rewritten scene exited $?"
python3 - "$scene" "$tmp/b.json" "$tmp/cw.json" "$tmp/cw_b.json" <<'PY' || fail "refs do not follow the file positions"
import json, re, sys
def check(scene_path, result_path):
    scene = json.load(open(scene_path))
    robot = scene["robot"]["polygon"]
    obstacles = {o["id"]: o["polygon"] for o in scene["obstacles"]}
    goal = scene["goal"]
    out, checked = {}, 0
    for key in ("classic", "vc"):
        for poly in json.load(open(result_path))[key]["regions"]:
            for ring in [poly["outer"]] + poly["holes"]:
                v = ring["vertices"]
                for i, e in enumerate(ring["edges"]):
                    a, b = v[i], v[(i + 1) % len(v)]
                    if e["kind"] == "goal":
                        out[(key, round(a[0], 9), round(a[1], 9), round(b[0], 9), round(b[1], 9))] = e["ref"]
                    if e["kind"] != "obstacle":
                        continue
                    m = re.fullmatch(r"obstacle\[(.*)\]\.([ev])\[(\d+)\]-robot\.([ve])\[(\d+)\]", e["ref"])
                    assert m, e["ref"]
                    o, k, j = obstacles[m.group(1)], int(m.group(3)), int(m.group(5))
                    sub = lambda p, q: (p[0] - q[0], p[1] - q[1])
                    if m.group(2) == "e":
                        s, t = sub(o[k], robot[j]), sub(o[(k + 1) % len(o)], robot[j])
                    else:
                        s, t = sub(o[k], robot[j]), sub(o[k], robot[(j + 1) % len(robot)])
                    for p in (a, b):
                        d = (t[0] - s[0], t[1] - s[1])
                        u = max(0.0, min(1.0, ((p[0] - s[0]) * d[0] + (p[1] - s[1]) * d[1]) / (d[0] ** 2 + d[1] ** 2)))
                        dist = ((p[0] - s[0] - u * d[0]) ** 2 + (p[1] - s[1] - u * d[1]) ** 2) ** 0.5
                        assert dist < 1e-7, (e["ref"], a, b, s, t)
                    checked += 1
    assert checked > 0
    return out, len(goal["polygon"])
original, n = check(sys.argv[1], sys.argv[2])
rewritten, _ = check(sys.argv[3], sys.argv[4])
renumber = lambda ref: re.sub(r"goal\.e\[(\d+)\]", lambda m: "goal.e[%d]" % ((n - 1 - int(m.group(1))) % n), ref)
assert original and set(original) == set(rewritten), (sorted(original), sorted(rewritten))
for k, ref in original.items():
    assert renumber(ref) == rewritten[k], (k, ref, renumber(ref), rewritten[k])
PY
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

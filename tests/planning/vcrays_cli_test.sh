#!/usr/bin/env bash
# `visco vcrays` on every example scene: exit 0, the contract's JSON keys, an SVG when asked; bad scenes exit 2 with
# one line naming the file and the object.
set -uo pipefail
visco="$1"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
for scene in data/scenes/*.json; do
  if ! "$visco" vcrays "$scene" --out "$tmp/out.json" --svg "$tmp/out.svg" 2>"$tmp/err"; then
    fail "visco vcrays $scene: $(cat "$tmp/err")"
    continue
  fi
  python3 - "$tmp/out.json" "$scene" <<'PY' || fail "JSON of $1"
import json, sys
j = json.load(open(sys.argv[1]))
scene = json.load(open(sys.argv[2]))
assert set(["vc_rays", "cvc_rays"]) <= set(j), j.keys()
for r in j["vc_rays"]:
    assert set(["id", "obstacle", "vertex", "from", "to"]) <= set(r), r
def at_image_border(p, offset):
    pin = scene.get("camera", {}).get("pinhole")
    if pin is None:
        return False
    m = pin["wMc"]
    w = [p[0] - offset[0] - m[0][3], p[1] - offset[1] - m[1][3], -m[2][3]]
    x, y, z = (sum(m[r][k] * w[r] for r in range(3)) for k in range(3))  # R^T (point - centre)
    if z <= 0:
        return False
    u, v = pin["px"] * x / z + pin["u0"], pin["py"] * y / z + pin["v0"]
    return abs(min(u, pin["width"] - u, v, pin["height"] - v) - 1.0) < 1e-6
for c in j["cvc_rays"]:
    assert set(["id", "vc_ray", "cm_vertex", "segments", "open_ends"]) <= set(c), c
    assert c["id"].startswith(c["vc_ray"] + ".cm"), c
    assert len(c["open_ends"]) == len(c["segments"]), c
    # An open end is where the bounds clip the ray, the camera end (P + offset), or, for a pinhole camera, where the
    # CM vertex leaves the image (it projects one pixel inside the border there); every other end is on CB.
    (x0, y0), (x1, y1) = scene["bounds"]["min"], scene["bounds"]["max"]
    cam = next(r["to"] for r in j["vc_rays"] if r["id"] == c["vc_ray"])  # the projection centre P
    for seg, ends in zip(c["segments"], c["open_ends"]):
        assert all(isinstance(e, bool) for e in ends), c
        for p, is_open in zip(seg, ends):
            on_bounds = min(abs(p[0] - x0), abs(p[0] - x1), abs(p[1] - y0), abs(p[1] - y1)) < 1e-9
            at_camera = abs(p[0] - cam[0] - c["offset"][0]) + abs(p[1] - cam[1] - c["offset"][1]) < 1e-9
            assert not is_open or on_bounds or at_camera or at_image_border(p, c["offset"]), (c["id"], p)
# Every example scene with a camera has rays (corner.json has no camera: none).
assert len(j["vc_rays"]) > 0 or "camera" not in scene, "no VC rays in " + sys.argv[2]
PY
  grep -q "</svg>" "$tmp/out.svg" || fail "no SVG for $scene"
done
# Same output twice (ids and order are deterministic).
"$visco" vcrays data/scenes/slot.json > "$tmp/a.json" && "$visco" vcrays data/scenes/slot.json > "$tmp/b.json"
cmp -s "$tmp/a.json" "$tmp/b.json" || fail "two runs differ"
# Bad input: exit 2, "visco: FILE: OBJECT: what".
sed 's/"friction_cone_deg"/"friction_deg"/' data/scenes/slot.json > "$tmp/bad.json"
out=$("$visco" vcrays "$tmp/bad.json" 2>&1); status=$?
[[ $status -eq 2 ]] || fail "bad scene exited $status"
grep -qE "^visco: .*bad.json: friction_deg: unknown field" <<<"$out" || fail "bad scene message: $out"
out=$("$visco" vcrays /nonexistent.json 2>&1); status=$?
[[ $status -eq 2 ]] || fail "missing scene exited $status"
grep -qE "^visco: /nonexistent.json: cannot open" <<<"$out" || fail "missing scene message: $out"
"$visco" vcrays --help | grep -q "SCENE" || fail "no --help"
echo "$(( failures == 0 ? 1 : 0 )) passed, $(( failures == 0 ? 0 : 1 )) failed"
exit $(( failures == 0 ? 0 : 1 ))

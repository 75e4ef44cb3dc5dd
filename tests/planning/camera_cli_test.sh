#!/usr/bin/env bash
# `visco camera`: ranks candidate cameras on an example scene (viewing cells, a grid, a file), writes the heat map,
# and rejects bad input with exit 2 naming the file and the object.
set -uo pipefail
visco="$1"
# --sanitized (ASan/UBSan build): fewer candidates, the same checks.
cells=6
[[ "${2:-}" == "--sanitized" ]] && cells=3
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

# fig13 (§VIII-A): no strategy without a camera, one step with the scene's camera.
"$visco" camera data/scenes/fig13.json --max-candidates $cells --threads 2 --out "$tmp/cells.json" --svg "$tmp/cells.svg" \
  2>"$tmp/cells.log" || fail "visco camera (cells) exited $?: $(cat "$tmp/cells.log")"
python3 - "$tmp/cells.json" "$cells" <<'PY' || fail "cells JSON: $(head -c 600 "$tmp/cells.json")"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["mode"] == "cells", j["mode"]
assert j["cells"]["views"] > 1 and j["cells"]["faces"] >= j["cells"]["cells"] > 0, j["cells"]
assert j["no_camera"]["feasible"] is False, j["no_camera"]
assert j["scene_camera"]["feasible"] is True and j["scene_camera"]["steps"] == 1, j["scene_camera"]
c = j["candidates"]
n = int(sys.argv[2])
assert len(c) == n and [x["rank"] for x in c] == list(range(1, n + 1)), [x.get("rank") for x in c]
key = lambda x: (not x["feasible"], x["steps"] if x["feasible"] else 0, -x["min_interval_deg"], -x["preimage_area"])
assert [key(x) for x in c] == sorted(key(x) for x in c), "not ranked"
assert j["best"] is not None and j["best"]["center"] == c[0]["center"], j["best"]
assert all("cell" in x and len(x["fov_deg"]) == 2 for x in c)
PY
grep -q '<svg' "$tmp/cells.svg" && grep -q 'class="cell view' "$tmp/cells.svg" && grep -q '>best<' "$tmp/cells.svg" ||
  fail "cells.svg lacks cells or the best camera"
# A legend in words for every colour and mark, and no grey but the obstacles' (a candidate without a strategy is
# purple, not the obstacles' grey).
python3 - "$tmp/cells.svg" <<'PY' || fail "cells.svg: legend or colours"
import re, sys
svg = open(sys.argv[1]).read()
for words in ("1 step", "no strategy", "view not evaluated", "obstacle", "goal", "start region", "the best candidate"):
    assert re.search(r'class="legend"[^>]*>' + re.escape(words), svg), words
fills = set(re.findall(r'class="(?:cell view\d+|candidate)" fill="(#[0-9a-f]{6})"', svg))
greys = {f for f in fills if f[1:3] == f[3:5] == f[5:7] and f != "#ffffff"}
assert fills and not greys, (fills, greys)
PY
grep -q '^best: centre' "$tmp/cells.log" || fail "no summary line: $(cat "$tmp/cells.log")"

# A file of candidates: the scene's own centre and one inside the post (infeasible, with the reason).
echo '{"centers": [[9, 7.5], [2.5, 2]]}' >"$tmp/candidates.json"
"$visco" camera data/scenes/fig13.json --candidates "$tmp/candidates.json" --fov 100 --aim 5 4 --threads 1 \
  --out "$tmp/file.json" 2>"$tmp/file.log" || fail "visco camera (file) exited $?: $(cat "$tmp/file.log")"
python3 - "$tmp/file.json" <<'PY' || fail "file JSON: $(head -c 600 "$tmp/file.json")"
import json, sys
j = json.load(open(sys.argv[1]))
c = j["candidates"]
assert j["mode"] == "candidates" and len(c) == 2, j
assert c[1]["center"] == [2.5, 2] and c[1]["feasible"] is False and "inside obstacle post" in c[1]["reason"], c[1]
assert j["aim"] == [5, 4] and j["fov_deg"] == 100
PY

# A coarse grid.
grid=4
[[ "${2:-}" == "--sanitized" ]] && grid=6
"$visco" camera data/scenes/fig13.json --grid $grid --max-steps 1 --threads 2 --out "$tmp/grid.json" \
  --svg "$tmp/grid.svg" 2>"$tmp/grid.log"
status=$?
[[ $status -eq 0 || $status -eq 1 ]] || fail "visco camera (grid) exited $status: $(cat "$tmp/grid.log")"
grep -q '"mode": "grid"' "$tmp/grid.json" && grep -q 'class="candidate"' "$tmp/grid.svg" || fail "grid output"

# Bad input: exit 2 with the file and object named.
"$visco" camera data/scenes/fig13.json --fov 200 >/dev/null 2>"$tmp/bad1.log"
[[ $? -eq 2 ]] && grep -q -- "--fov" "$tmp/bad1.log" || fail "--fov 200: $(cat "$tmp/bad1.log")"
echo '{"centers": [[1, 2], [3]]}' >"$tmp/bad.json"
"$visco" camera data/scenes/fig13.json --candidates "$tmp/bad.json" >/dev/null 2>"$tmp/bad2.log"
[[ $? -eq 2 ]] && grep -q "bad.json: centers\[1\]" "$tmp/bad2.log" || fail "bad candidates: $(cat "$tmp/bad2.log")"
"$visco" camera data/scenes/fig13.json --grid 1 --candidates "$tmp/bad.json" >/dev/null 2>"$tmp/bad3.log"
[[ $? -eq 2 ]] || fail "--grid with --candidates: $(cat "$tmp/bad3.log")"

[[ $failures -eq 0 ]] && echo "camera CLI: all checks passed"
exit $((failures > 0))

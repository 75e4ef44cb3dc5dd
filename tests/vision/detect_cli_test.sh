#!/usr/bin/env bash
# `visco detect` against docs/formats.md: JSON shape on visp-images-data's AprilTag.pgm, and exit 2 with a message naming
# the file and what is wrong for bad input.
set -uo pipefail
visco="$1"
data=/usr/share/visp-images-data/ViSP-images/AprilTag
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

out=$("$visco" detect "$data/AprilTag.pgm" --camera tests/vision/data/apriltag_pgm_camera.xml --tag-size 0.053) \
  || fail "detect exited $?"
python3 - "$out" <<'PY' || fail "JSON does not follow the contract"
import json, sys
d = json.loads(sys.argv[1])
assert d["image"] == {"width": 640, "height": 480}, d["image"]
dets = d["detections"]
assert sorted(x["id"] for x in dets) == list(range(8, 20)), [x["id"] for x in dets]
for x in dets:
    assert x["family"] == "tag36h11"
    assert len(x["corners"]) == 4 and all(len(c) == 2 for c in x["corners"])
    assert len(x["pose"]["t"]) == 3 and len(x["pose"]["R"]) == 3 and all(len(r) == 3 for r in x["pose"]["R"])
    assert x["decision_margin"] > 15
    assert 0.3 < x["pose"]["t"][2] < 0.6
tag8 = [x for x in dets if x["id"] == 8][0]
# Ground truth (v u) 51.611 245.347 for corner 0 of tag 8.
assert abs(tag8["corners"][0][0] - 245.347) < 0.1 and abs(tag8["corners"][0][1] - 51.611) < 0.1, tag8["corners"][0]
PY

expect2() {  # expect2 PATTERN -- ARGS...
  local pattern="$1"; shift 2
  local msg status
  msg=$("$visco" "$@" 2>&1 >/dev/null); status=$?
  [[ $status -eq 2 ]] || fail "visco $* exited $status, expected 2"
  grep -qE -- "$pattern" <<<"$msg" || fail "visco $*: message '$msg' does not match '$pattern'"
}
expect2 '^visco: /nonexistent.xml: calibration file does not exist' -- \
  detect "$data/AprilTag.pgm" --camera /nonexistent.xml --tag-size 0.05
expect2 '^visco: /nonexistent.pgm: image file does not exist' -- \
  detect /nonexistent.pgm --camera tests/vision/data/apriltag_pgm_camera.xml --tag-size 0.05
expect2 '^visco: command line: --tag-size: must be a positive' -- \
  detect "$data/AprilTag.pgm" --camera tests/vision/data/apriltag_pgm_camera.xml --tag-size -1
expect2 '^visco: command line: --family: unknown tag family' -- \
  detect "$data/AprilTag.pgm" --camera tests/vision/data/apriltag_pgm_camera.xml --tag-size 0.05 --family tag99
expect2 'cube/image.0000.pgm: image is 384x288 but calibration' -- \
  detect /usr/share/visp-images-data/ViSP-images/cube/image.0000.pgm --camera tests/vision/data/apriltag_pgm_camera.xml \
  --tag-size 0.05
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
head -c 200 "$data/AprilTag.pgm" > "$tmp/truncated.pgm"
expect2 'truncated.pgm: cannot decode image' -- \
  detect "$tmp/truncated.pgm" --camera tests/vision/data/apriltag_pgm_camera.xml --tag-size 0.05
echo "<root><camera>" > "$tmp/bad.xml"
expect2 'bad.xml' -- detect "$data/AprilTag.pgm" --camera "$tmp/bad.xml" --tag-size 0.05
expect2 '^visco: command line: ' -- detect "$data/AprilTag.pgm" --tag-size 0.05
echo "$(( failures == 0 ? 1 : 0 )) passed, $(( failures == 0 ? 0 : 1 )) failed"
exit $(( failures == 0 ? 0 : 1 ))

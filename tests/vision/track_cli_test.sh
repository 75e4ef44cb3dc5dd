#!/usr/bin/env bash
# `visco track` over a folder of real frames (visp-images-data AprilTag.pgm copies, the "robot" carrying tag 8 and an
# "obstacle" tag 9), with a corrupt file among them; bad input exits 2 naming the file or option.
set -uo pipefail
visco="$1"
data=/usr/share/visp-images-data/ViSP-images/AprilTag
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
mkdir "$tmp/frames"
for i in 0 1 2 3; do cp "$data/AprilTag.pgm" "$tmp/frames/f$i.pgm"; done
echo "garbage" > "$tmp/frames/f1b.pgm"
cat > "$tmp/objects.json" <<'JSON'
{"robot": {"polygon": [[-0.03, -0.03], [0.03, -0.03], [0.03, 0.03], [-0.03, 0.03]], "height": 0.01,
           "tags": [{"id": 8, "size": 0.053, "t": [0, 0, 0.01]}]},
 "obstacles": [{"id": "o", "polygon": [[-0.03, -0.03], [0.03, -0.03], [0.03, 0.03], [-0.03, 0.03]], "height": 0.01,
                "tags": [{"id": 9, "size": 0.053, "t": [0, 0, 0.01]}]}]}
JSON
echo '{"wMc": {"t": [0, 0, 0.5], "rpy_deg": [180, 0, 0]}}' > "$tmp/ext.json"
out=$("$visco" track --camera tests/vision/data/apriltag_pgm_camera.xml --extrinsics "$tmp/ext.json" \
  --objects "$tmp/objects.json" --images "$tmp/frames" --no-publish) || fail "track exited $?"
python3 - "$out" <<'PY' || fail "track output is not as expected"
import json, sys
lines = [json.loads(l) for l in sys.argv[1].splitlines()]
faults = [l["fault"] for l in lines if "fault" in l]
frames = [l for l in lines if "seq" in l]
summary = lines[-1]["summary"]
assert len(frames) == 4 and summary["frames"] == 4 and summary["bad_frames"] == 1, summary
assert len(faults) == 1 and "f1b.pgm" in faults[0]["message"], faults
assert all(f["robot"]["valid"] for f in frames), frames
assert frames[0]["full_detection"] and not frames[1]["full_detection"], frames
assert len(frames[0]["events"]) == 16, len(frames[0]["events"])  # 4 robot vertices x 4 obstacle vertices
assert all(8 in f["tags"] and 9 in f["tags"] for f in frames)
PY
# --mode mbt: every line says what the robot's model-based tracker did (this real image has no robot prism to track,
# so it runs from the tags' pose and its pose is not used, with the reason).
out=$("$visco" track --camera tests/vision/data/apriltag_pgm_camera.xml --extrinsics "$tmp/ext.json" \
  --objects "$tmp/objects.json" --images "$tmp/frames" --no-publish --mode mbt) || fail "track --mode mbt exited $?"
python3 - "$out" <<'PY' || fail "track --mode mbt output is not as expected"
import json, sys
frames = [json.loads(l) for l in sys.argv[1].splitlines() if '"seq"' in l]
assert len(frames) == 4, len(frames)
for f in frames:
    m = f["model_tracker"]
    assert m["ran"] and m["from_tags"], m
    assert m["used"] == (m["failure"] == ""), m  # used, or a reason why not
PY
expect2() {  # expect2 PATTERN -- ARGS...
  local pattern="$1"; shift 2
  local msg status
  msg=$("$visco" "$@" 2>&1 >/dev/null); status=$?
  [[ $status -eq 2 ]] || fail "visco $* exited $status, expected 2"
  grep -qE -- "$pattern" <<<"$msg" || fail "visco $*: message '$msg' does not match '$pattern'"
}
common=(--camera tests/vision/data/apriltag_pgm_camera.xml --extrinsics "$tmp/ext.json" --objects "$tmp/objects.json" --no-publish)
expect2 'give exactly one frame source' -- track "${common[@]}"
expect2 '/nonexistent: image folder does not exist' -- track "${common[@]}" --images /nonexistent
expect2 '--mode: must be roi, mbt, klt or detect' -- track "${common[@]}" --images "$tmp/frames" --mode fast
expect2 ': robot: missing' -- track --camera tests/vision/data/apriltag_pgm_camera.xml \
  --extrinsics "$tmp/ext.json" --objects <(echo '{}') --images "$tmp/frames" --no-publish
echo '{"wMc": {"t": [0, 0]}}' > "$tmp/bad_ext.json"
expect2 'bad_ext.json: wMc.t' -- track --camera tests/vision/data/apriltag_pgm_camera.xml \
  --extrinsics "$tmp/bad_ext.json" --objects "$tmp/objects.json" --images "$tmp/frames" --no-publish
echo "$(( failures == 0 ? 1 : 0 )) passed, $(( failures == 0 ? 0 : 1 )) failed"
exit $(( failures == 0 ? 0 : 1 ))

#!/usr/bin/env bash
# `visco detect --overlay` and `visco track --overlay` as commands: the flags are described in --help, pictures are
# written where asked (a PNG, an image folder with one picture per input frame, a video), and bad paths (unknown
# extension, missing or unwritable folder, a file where a folder is wanted) exit 2 naming the file. The pictures'
# content is checked against ground truth in tests/vision/overlay_test.cc.
set -uo pipefail
visco="$1"
data=/usr/share/visp-images-data/ViSP-images/AprilTag
camera=tests/vision/data/apriltag_pgm_camera.xml
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT

"$visco" detect --help | grep -q -- '--overlay' || fail "detect --help does not describe --overlay"
"$visco" track --help | grep -q -- '--overlay' || fail "track --help does not describe --overlay"

# detect: the JSON as before, and a PNG of the image's size.
out=$("$visco" detect "$data/AprilTag.pgm" --camera "$camera" --tag-size 0.053 --overlay "$tmp/tags.png") \
  || fail "detect --overlay exited $?"
python3 - "$out" "$tmp/tags.png" <<'PY' || fail "detect --overlay: JSON or picture not as expected"
import json, struct, sys
d = json.loads(sys.argv[1])
assert len(d["detections"]) == 12, len(d["detections"])
png = open(sys.argv[2], "rb").read()
assert png[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
w, h, depth, colour = struct.unpack(">IIBB", png[16:26])
assert (w, h) == (640, 480) and colour == 2, (w, h, colour)  # colour type 2: RGB
PY

# track: one picture per input frame (4 frames and a corrupt file) into a folder, or a video.
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
common=(--camera "$camera" --extrinsics "$tmp/ext.json" --objects "$tmp/objects.json" --no-publish)
summary() { tail -n 1 <<<"$1" | python3 -c 'import json, sys; print(json.load(sys.stdin)["summary"]["overlay_frames"])'; }
out=$("$visco" track "${common[@]}" --images "$tmp/frames" --overlay "$tmp/pictures") || fail "track --overlay DIR exited $?"
[[ $(summary "$out") == 5 ]] || fail "track --overlay DIR: summary says $(summary "$out") pictures, expected 5"
[[ $(ls "$tmp/pictures" | tr '\n' ' ') == "000000.png 000001.png 000002.png 000003.png 000004.png " ]] \
  || fail "track --overlay DIR wrote: $(ls "$tmp/pictures" | tr '\n' ' ')"
for ext in avi mp4; do
  out=$("$visco" track "${common[@]}" --images "$tmp/frames" --overlay "$tmp/run.$ext") || fail "track --overlay .$ext exited $?"
  [[ $(summary "$out") == 5 ]] || fail "track --overlay .$ext: $(summary "$out") pictures, expected 5"
  [[ -s "$tmp/run.$ext" ]] || fail "track --overlay .$ext wrote nothing"
done
# --overlay from a parameter file, like every option.
echo "{\"track\": {\"overlay\": \"$tmp/from_config\"}}" > "$tmp/track.json"
"$visco" track --config "$tmp/track.json" "${common[@]}" --images "$tmp/frames" >/dev/null \
  || fail "track --config with overlay exited $?"
[[ $(ls "$tmp/from_config" | wc -l) == 5 ]] || fail "track --config overlay: $(ls "$tmp/from_config" | wc -l) pictures"

expect2() {  # expect2 PATTERN -- ARGS...
  local pattern="$1"; shift 2
  local msg status
  msg=$("$visco" "$@" 2>&1 >/dev/null); status=$?
  [[ $status -eq 2 ]] || fail "visco $* exited $status, expected 2"
  grep -qE -- "$pattern" <<<"$msg" || fail "visco $*: message '$msg' does not match '$pattern'"
}
detect=(detect "$data/AprilTag.pgm" --camera "$camera" --tag-size 0.053)
expect2 "^visco: $tmp/tags.xyz: unknown picture extension '.xyz'" -- "${detect[@]}" --overlay "$tmp/tags.xyz"
expect2 "^visco: /nonexistent/tags.png: cannot write: folder '/nonexistent' does not exist" -- \
  "${detect[@]}" --overlay /nonexistent/tags.png
expect2 "^visco: $tmp: cannot write: is a folder" -- "${detect[@]}" --overlay "$tmp"
expect2 "^visco: $tmp/run.xyz: unknown overlay extension '.xyz'" -- \
  track "${common[@]}" --images "$tmp/frames" --overlay "$tmp/run.xyz"
expect2 "^visco: /nonexistent/run.avi: cannot write: folder '/nonexistent' does not exist" -- \
  track "${common[@]}" --images "$tmp/frames" --overlay /nonexistent/run.avi
touch "$tmp/plainfile"
expect2 "^visco: $tmp/plainfile: cannot write overlay pictures: exists and is not a folder" -- \
  track "${common[@]}" --images "$tmp/frames" --overlay "$tmp/plainfile"
expect2 "^visco: $tmp/plainfile/sub: cannot create overlay folder" -- \
  track "${common[@]}" --images "$tmp/frames" --overlay "$tmp/plainfile/sub"
# Bad paths are refused before any frame is read: nothing written.
[[ ! -e "$tmp/run.xyz" && ! -e "$tmp/tags.xyz" ]] || fail "a refused overlay path was written"
echo "$(( failures == 0 ? 1 : 0 )) passed, $(( failures == 0 ? 0 : 1 )) failed"
exit $(( failures == 0 ? 0 : 1 ))

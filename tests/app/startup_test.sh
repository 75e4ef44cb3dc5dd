#!/usr/bin/env bash
# Start-up cost: `visco` runs the planner's commands without loading vision (OpenCV, ViSP, AprilTag), so scripts that
# call the planner in a loop pay milliseconds, not the hundreds of shared libraries visco-full loads; every other
# command still works through it (handed to visco-full by exec: the command's own exit status and output).
# `visco-rt` links neither the planner nor vision.
set -uo pipefail
visco="$1"
rt="$2"
full="$(dirname "$visco")/visco-full"
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

for prog in "$visco" "$rt"; do
  needed=$(readelf -d "$prog" | grep NEEDED)
  if grep -qiE 'opencv|visp|apriltag|gdal|avcodec|gst' <<<"$needed"; then
    fail "$(basename "$prog") links vision: $(grep -iE 'opencv|visp|apriltag' <<<"$needed" | head -3)"
  fi
done
grep -qiE 'gmp|mpfr' <<<"$(readelf -d "$rt" | grep NEEDED)" && fail "visco-rt links the planner (GMP/MPFR)"
# Statically linked code too: no planner (visco::planning, CGAL), no vision (visco::vision, cv::, vp*) in visco-rt's
# symbols. Its simulated robot runs the motion model (visco::MotionModel, common/), which is not the planner.
symbols=$(nm -C "$rt" 2>/dev/null)
[[ -n "$symbols" ]] || fail "nm printed no symbols of visco-rt"
for pattern in 'visco::planning::' 'CGAL::' 'visco::vision::' 'cv::' 'vpImage' 'SyntheticCamera' 'RenderedCamera'; do
  count=$(grep -c -- "$pattern" <<<"$symbols")
  [[ $count -eq 0 ]] || fail "visco-rt holds $count symbol(s) matching $pattern: $(grep -m2 -- "$pattern" <<<"$symbols")"
done
grep -q 'visco::MotionModel::Advance' <<<"$symbols" || fail "visco-rt lacks the simulated robot's motion model"
libs=$(ldd "$visco" | wc -l)
full_libs=$(ldd "$full" | wc -l)
[[ $libs -lt 40 ]] || fail "visco loads $libs shared libraries"
echo "shared libraries: visco $libs, visco-full $full_libs"

"$visco" --version | grep -q '^visco ' || fail "--version"
# (Captured first: `grep -q` closing the pipe early would fail the writer with SIGPIPE under pipefail.)
help=$("$visco" --help)
grep -qE '^\s+track\s' <<<"$help" || fail "--help does not list the vision commands"
grep -qE '^\s+plan\s' <<<"$help" || fail "--help does not list plan"
help=$("$visco" plan --help)
grep -q -- '--max-steps' <<<"$help" || fail "plan --help"
help=$("$visco" track --help)
grep -q -- '--camera' <<<"$help" || fail "track --help (through visco-full)"
"$visco" nonsense >/dev/null 2>&1
[[ $? -eq 2 ]] || fail "an unknown command does not exit 2"
"$visco" vcrays /nonexistent.json >/dev/null 2>&1
[[ $? -eq 2 ]] || fail "a planner command's bad input does not exit 2"
"$visco" detect /nonexistent.png >/dev/null 2>&1
[[ $? -eq 2 ]] || fail "a vision command's bad input (through visco-full) does not exit 2"

# Whole-process time, the median of 21 starts, against `true` (the machine's own cost of a process): printed for
# the log, not asserted (the structure above is what keeps it low; the README's figures are medians of repeated whole-process timings).
median() { sort -n | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
time_of() {
  for _ in $(seq 21); do
    s=$(date +%s%N); "$@" >/dev/null 2>&1; e=$(date +%s%N); echo $(((e - s) / 1000))
  done | median
}
t_true=$(time_of true)
t_visco=$(time_of "$visco" --version)
t_full=$(time_of "$full" --version)
echo "start-up, median of 21 (us): true $t_true, visco --version $t_visco, visco-full --version $t_full"

[[ $failures -eq 0 ]] && echo "start-up: all checks passed"
exit $((failures > 0))

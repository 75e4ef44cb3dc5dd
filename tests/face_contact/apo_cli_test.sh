#!/usr/bin/env bash
# `visco apo`: the example files succeed with the paper's trials; bad input exits 2 with a precise message.
set -uo pipefail
visco="$1"
failures=0
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
expect() {  # expect STATUS PATTERN -- ARGS...
  local want="$1" pattern="$2"; shift 3
  local out status
  out=$("$visco" "$@" 2>&1); status=$?
  if [[ $status -ne $want ]]; then echo "FAIL: visco $* exited $status, expected $want"; failures=$((failures + 1)); fi
  if ! grep -qE -- "$pattern" <<<"$out"; then
    echo "FAIL: visco $* printed no line matching '$pattern':"; echo "$out" | head -20; failures=$((failures + 1))
  fi
}
expect 0 'Usage|usage' -- apo --help
expect 0 'try \{T3, T2\}: succeeds' -- apo data/apo/castles_stick.json --text
expect 0 'try \{T5, T4, T3, T2\}: succeeds' -- apo data/apo/sub_assembly.json --text
expect 0 'undo step 4: put cube back' -- apo data/apo/disappeared_relation.json --text
expect 0 '"corrected_operations"' -- apo data/apo/disappeared_relation.json
expect 0 'T1, T2, T3' -- apo data/apo/castles_stick.json --mode all-at-once --text
expect 0 'Assembly plan' -- apo data/apo/castles_stick.json --out "$tmp/out.json"
if ! grep -q '"final_poses"' "$tmp/out.json"; then echo "FAIL: --out wrote no JSON"; failures=$((failures + 1)); fi
expect 2 '^visco: no/such.json: cannot be read' -- apo no/such.json
echo '{"objects": [], "operations": []}' > "$tmp/empty.json"
expect 2 "^visco: $tmp/empty.json: objects: must be a non-empty array" -- apo "$tmp/empty.json"
sed 's/"object": "stick"/"object": "stik"/' data/apo/castles_stick.json > "$tmp/unknown.json"
expect 2 "unknown object id 'stik'" -- apo "$tmp/unknown.json"
expect 2 '^visco: command line: .*--mode' -- apo data/apo/castles_stick.json --mode sometimes
echo "$(( failures == 0 ? 1 : 0 )) passed, $(( failures == 0 ? 0 : 1 )) failed"
exit $(( failures == 0 ? 0 : 1 ))

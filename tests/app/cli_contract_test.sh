#!/usr/bin/env bash
# `visco` answers --help and --version with status 0, and usage errors with status 2 and one line naming them.
set -uo pipefail
visco="$1"
failures=0
expect() {  # expect STATUS PATTERN -- ARGS...
  local want="$1" pattern="$2"; shift 3
  local out status
  out=$("$visco" "$@" 2>&1); status=$?
  if [[ $status -ne $want ]]; then echo "FAIL: visco $* exited $status, expected $want"; failures=$((failures + 1)); fi
  if ! grep -qE -- "$pattern" <<<"$out"; then
    echo "FAIL: visco $* printed no line matching '$pattern':"; echo "$out"; failures=$((failures + 1))
  fi
}
expect 0 'visco: plans uncertainty-tolerant' -- --help
expect 0 '^visco [0-9]+\.[0-9]+\.[0-9]+' -- --version
expect 2 '^visco: command line: .*' -- no-such-command
expect 2 '^visco: command line: .*' --
expect 2 '^visco: command line: .*--no-such-flag' -- spy --no-such-flag
expect 0 'lcm-spy' -- spy --help
expect 0 'lcm\.spy\.Spy' -- spy --print
# Every subcommand has --help.
for sub in $("$visco" --help | awk '/^Subcommands:/{on=1; next} on && NF {print $1}'); do
  expect 0 "Usage|usage" -- "$sub" --help
done
echo "$(( failures == 0 ? 1 : 0 )) passed, $(( failures == 0 ? 0 : 1 )) failed"
exit $(( failures == 0 ? 0 : 1 ))

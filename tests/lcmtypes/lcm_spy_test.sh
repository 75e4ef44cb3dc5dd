#!/usr/bin/env bash
# lcm-spy (started by `visco spy` under Xvfb) must find all visco types, and lcm-spy's type database must decode
# one published message of every type. Usage: lcm_spy_test.sh VISCO PUBLISH_ALL CHECK_CLASSES_DIR
set -euo pipefail
visco="$1"
publish_all="$2"
check_dir="$3"
# A private multicast port and TTL 0, so that the test neither hears nor disturbs other LCM users.
url="udpm://239.255.76.67:$((20000 + RANDOM % 20000))?ttl=0"
work=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$work"' EXIT

expected=$("$publish_all" "$url" 0)
echo "visco defines $expected LCM types; LCM URL $url"

timeout 60 xvfb-run -a "$visco" spy --lcm-url "$url" >"$work/spy.out" 2>&1 &
classpath=$("$visco" spy --print | sed -e 's/.* -cp \([^ ]*\) .*/\1/')
timeout 60 java -Djava.net.preferIPv4Stack=true -cp "$classpath:$check_dir" SpyDecodeCheck "$url" 12 \
  >"$work/decode.out" 2>&1 &
checker=$!
# Wait for lcm-spy to scan the class path, then publish every type for a few seconds.
for _ in $(seq 1 100); do grep -q "LCM types" "$work/spy.out" 2>/dev/null && break; sleep 0.2; done
"$publish_all" "$url" 40 >/dev/null
wait "$checker" || true

echo "--- lcm-spy:"; cat "$work/spy.out"
echo "--- decoded with lcm-spy's type database:"; sort "$work/decode.out"
found=$(sed -n 's/^Found \([0-9]*\) LCM types.*/\1/p' "$work/spy.out" | head -n 1)
status=0
if [[ -z "$found" ]]; then echo "FAIL: lcm-spy did not report its types"; status=1
elif (( found < expected )); then echo "FAIL: lcm-spy found $found LCM types, expected at least $expected"; status=1; fi
decoded=$(grep -c '^decoded SPYTEST_' "$work/decode.out" || true)
if (( decoded != expected )); then echo "FAIL: decoded $decoded of $expected types"; status=1; fi
if grep -qE '^(undecodable|error)' "$work/decode.out"; then echo "FAIL: some messages were not decodable"; status=1; fi
while read -r line; do
  channel=$(echo "$line" | awk '{print $2}'); type=$(echo "$line" | awk '{print $3}')
  [[ "visco.${channel#SPYTEST_}" == "$type" ]] || { echo "FAIL: $channel decoded as $type"; status=1; }
done < <(grep '^decoded' "$work/decode.out")
(( status == 0 )) && echo "lcm-spy found $found types; all $expected decoded"
exit $status

#!/usr/bin/env bash
# Joins while others stream, over udpm:// inside a private network namespace
# this script creates (never the host network): 8 configured clients publish
# the bundled walk at 90 Hz (as e2e_multi_client.sh) while live clients (the
# client library's example program) join, stream and leave, a new one every
# 100 ms. Every answer of the 8 must still come in order without gaps and
# equal `sweptccd query` (service_e2e_tool collect); every live client must
# have been accepted and have left.
#   e2e_live_under_load.sh SWEPTCCD SERVICE E2E_TOOL SOURCE_DIR WORK_DIR CLIENT_EXAMPLE
set -euo pipefail
source "$(dirname "$0")/../../tools/netns.sh"
enter_private_netns "$@"
sweptccd=$1 service=$2 tool=$3 src=$4 work=$5 example=$6
rm -rf "$work"; mkdir -p "$work"
setup_loopback_multicast
url=$SWEPTCCD_URL
env_ply="$src/data/env/morse_apartment.ply.gz"
import_walk "$sweptccd" "$src" 90 "$work"
query_walk "$sweptccd" "$env_ply" "$work"
ids=(c0 c1 c2 c3 c4 c5 c6 c7)
client_flags=()
for id in "${ids[@]}"; do client_flags+=(--client "$id=$work/skeleton.json"); done
"$service" --lcm-url "$url" --env "$env_ply" "${client_flags[@]}" --security-mode unsigned \
  --max-live-clients 32 --log-level info 2> "$work/daemon.log" &
daemon=$!
collector= churn=
trap 'kill -KILL $daemon $collector $churn 2>/dev/null || true' EXIT
wait_for "$work/daemon.log" ready
timeout 60 "$tool" collect "$url" "$work/poses.jsonl" "$work/expected.jsonl" "$sweptccd" \
  "$work/skeleton.json" "$env_ply" "$work/collect.ready" 30 "${ids[@]}" > "$work/collect.out" 2>&1 &
collector=$!
for _ in $(seq 100); do [ -e "$work/collect.ready" ] && break; sleep 0.1; done
[ -e "$work/collect.ready" ]
(
  k=0
  while [ $k -lt 25 ]; do
    "$example" "$url" "joiner$k" "$work/skeleton.json" > "$work/joiner$k.out" 2>&1 &
    k=$((k + 1))
    sleep 0.1
  done
  wait
) &
churn=$!
"$tool" publish "$url" "$work/poses.jsonl" 90 "${ids[@]}"
wait "$collector" || { cat "$work/collect.out" >&2; exit 1; }
wait "$churn"
cat "$work/collect.out"
joined=$(cat "$work"/joiner*.out | grep -c "^joined: session" || true)
left=$(cat "$work"/joiner*.out | grep -c "^left" || true)
[ "$joined" = 25 ] && [ "$left" = 25 ] || {
  echo "live clients: $joined joined, $left left of 25" >&2; exit 1; }
# Every live client's state is gone: the daemon logged each leave.
for _ in $(seq 50); do
  [ "$(grep -c "live client 'joiner[0-9]*' left" "$work/daemon.log")" = 25 ] && break
  sleep 0.1
done
[ "$(grep -c "live client 'joiner[0-9]*' left" "$work/daemon.log")" = 25 ]
kill -TERM $daemon
wait $daemon
grep -q stopped "$work/daemon.log"
echo "e2e_live_under_load: 25 live clients joined and left while 8 streamed; passed"

#!/usr/bin/env bash
# End-to-end load over udpm:// inside a private network namespace this script
# creates (never the host network): 8 clients (same skeleton, own ids) each
# publish the bundled walk imported at 90 Hz, at 90 Hz, all at once (about
# 3 s); every client's events come in order without gaps, poses - 1 =
# answered + skipped, and every event equals `sweptccd query` for its pair.
#   e2e_multi_client.sh SWEPTCCD SERVICE E2E_TOOL SOURCE_DIR WORK_DIR
set -euo pipefail
source "$(dirname "$0")/../../tools/netns.sh"
enter_private_netns "$@"
sweptccd=$1 service=$2 tool=$3 src=$4 work=$5
rm -rf "$work"; mkdir -p "$work"
setup_loopback_multicast
url=$SWEPTCCD_URL
env_ply="$src/data/env/morse_apartment.ply.gz"
import_walk "$sweptccd" "$src" 90 "$work"
query_walk "$sweptccd" "$env_ply" "$work"
ids=(c0 c1 c2 c3 c4 c5 c6 c7)
client_flags=()
for id in "${ids[@]}"; do client_flags+=(--client "$id=$work/skeleton.json"); done
# The one end-to-end run in unsigned mode (a lab bench): it must say so.
"$service" --lcm-url "$url" --env "$env_ply" "${client_flags[@]}" --security-mode unsigned \
  --log-level info 2> "$work/daemon.log" &
daemon=$!
collector=
trap 'kill -KILL $daemon $collector 2>/dev/null || true' EXIT
wait_for "$work/daemon.log" ready
grep -q "UNSIGNED MODE" "$work/daemon.log"
timeout 60 "$tool" collect "$url" "$work/poses.jsonl" "$work/expected.jsonl" "$sweptccd" \
  "$work/skeleton.json" "$env_ply" "$work/collect.ready" 30 "${ids[@]}" > "$work/collect.out" 2>&1 &
collector=$!
for _ in $(seq 100); do [ -e "$work/collect.ready" ] && break; sleep 0.1; done
[ -e "$work/collect.ready" ]
"$tool" publish "$url" "$work/poses.jsonl" 90 "${ids[@]}"
wait "$collector" || { cat "$work/collect.out" >&2; exit 1; }
cat "$work/collect.out"
kill -TERM $daemon
wait $daemon
grep -q stopped "$work/daemon.log"
echo "e2e_multi_client: passed"

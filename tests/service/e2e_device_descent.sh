#!/usr/bin/env bash
# End-to-end, the daemon with the device descent (issue 30; docs/SERVICE.md
# "The device descent") over udpm:// inside a private network namespace
# this script creates (never the host network): 4 clients (same skeleton,
# own ids) publish the bundled walk imported at 90 Hz, at 90 Hz, all at once;
# the daemon runs `--backend gpu --device-descent` (llvmpipe in CI) with a
# gather window, so its workers answer the ready pairs of several clients in
# one device batch. Every client's events come in order without gaps, poses
# - 1 = answered + skipped, and every event equals `sweptccd query --backend
# cpu` for its pair; the daemon's log must show batches that gathered more
# than one pair (pairs > batches) and intervals the device cleared.
#   e2e_device_descent.sh SWEPTCCD SERVICE E2E_TOOL SOURCE_DIR WORK_DIR
set -euo pipefail
source "$(dirname "$0")/../../tools/netns.sh"
enter_private_netns "$@"
sweptccd=$1 service=$2 tool=$3 src=$4 work=$5
rm -rf "$work"; mkdir -p "$work"
setup_loopback_multicast
url=$SWEPTCCD_URL
env_ply="$src/data/env/morse_apartment.ply.gz"
import_walk "$sweptccd" "$src" 90 "$work"
"$sweptccd" query --skeleton "$work/skeleton.json" --poses "$work/poses.jsonl" --env "$env_ply" \
  --backend cpu --output "$work/expected.jsonl"
ids=(c0 c1 c2 c3)
client_flags=()
for id in "${ids[@]}"; do client_flags+=(--client "$id=$work/skeleton.json"); done
"$service" --lcm-url "$url" --env "$env_ply" "${client_flags[@]}" --security-mode unsigned \
  --backend gpu --device-descent --descent-max-batch 8 --descent-gather-us 4000 --workers 2 \
  --log-level info 2> "$work/daemon.log" &
daemon=$!
collector=
trap 'kill -KILL $daemon $collector 2>/dev/null || true' EXIT
wait_for "$work/daemon.log" ready
grep -q "device descent on: batches of up to 8 pairs, gather window 4000 us" "$work/daemon.log" ||
  { cat "$work/daemon.log" >&2; echo "the device descent is not on" >&2; exit 1; }
timeout 90 "$tool" collect "$url" "$work/poses.jsonl" "$work/expected.jsonl" "$sweptccd" \
  "$work/skeleton.json" "$env_ply" "$work/collect.ready" 60 "${ids[@]}" > "$work/collect.out" 2>&1 &
collector=$!
for _ in $(seq 100); do [ -e "$work/collect.ready" ] && break; sleep 0.1; done
[ -e "$work/collect.ready" ]
"$tool" publish "$url" "$work/poses.jsonl" 90 "${ids[@]}"
wait "$collector" || { cat "$work/collect.out" >&2; exit 1; }
cat "$work/collect.out"
kill -TERM $daemon
wait $daemon
grep -q stopped "$work/daemon.log"
line=$(grep -o 'GPU device descent: .*' "$work/daemon.log") ||
  { cat "$work/daemon.log" >&2; echo "no device descent summary" >&2; exit 1; }
echo "$line"
read -r batches pairs cleared < <(sed -E \
  's/.* ([0-9]+) batches, ([0-9]+) pairs, [0-9]+ dispatches, [0-9]+ intervals tested, ([0-9]+) cleared.*/\1 \2 \3/' \
  <<< "$line")
[ "$batches" -gt 0 ] || { echo "no device batch" >&2; exit 1; }
[ "$pairs" -gt "$batches" ] || { echo "no batch gathered several pairs" >&2; exit 1; }
[ "$cleared" -gt 0 ] || { echo "the device cleared nothing" >&2; exit 1; }
echo "e2e_device_descent: passed"

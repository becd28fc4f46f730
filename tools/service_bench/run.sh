#!/usr/bin/env bash
# Service latency benchmark inside a private network namespace (never the host
# network): for 1, 8 and 32 clients at 90 Hz, publication -> contact event.
#   bash tools/service_bench/run.sh [BUILD_DIR]   (default build)
set -euo pipefail
source "$(dirname "$0")/../netns.sh"
enter_private_netns "$@"
cd "$(dirname "$0")/../.."
build=${1:-build}
work=$build/service_bench
mkdir -p "$work"
setup_loopback_multicast
url=$SWEPTCCD_URL
import_walk "$build/bin/sweptccd" . 90 "$work"
rm -f "$work/room.key"
"$build/bin/sweptccd" keygen --out "$work/room.key"
echo "| clients | Hz | poses sent | events | median us | p99 us | max us |"
echo "|---:|---:|---:|---:|---:|---:|---:|"
for n in 1 8 32; do
  args=()
  for c in $(seq 0 $((n - 1))); do args+=(--client "client$c=$work/skeleton.json"); done
  "$build/bin/sweptccd-service" --lcm-url "$url" --env data/env/morse_apartment.ply.gz --workers 2 \
    --room-key "$work/room.key" --log-level warn "${args[@]}" 2> "$work/daemon_$n.log" &
  daemon=$!
  sleep 1
  "$build/bin/sweptccd_latency_bench" "$url" "$work/poses.jsonl" "$n" 90 10 "$work/room.key"
  kill -TERM $daemon
  wait $daemon
done

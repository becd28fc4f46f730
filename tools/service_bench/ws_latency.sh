#!/usr/bin/env bash
# Pose-to-event latency through the WebSocket door against the LCM door,
# inside a private network namespace (never the host network): 1 and 16
# live clients at 90 Hz on the bundled walk through the bundled apartment,
# one daemon with both doors (signed, the door on 127.0.0.1).
#   bash tools/service_bench/ws_latency.sh [BUILD_DIR]   (default build)
# RUNS="CLIENTS ..." changes the client counts (default "1 16");
# SECONDS_PER_RUN the length of each run (default 10).
set -euo pipefail
source "$(dirname "$0")/../netns.sh"
enter_private_netns "$@"
cd "$(dirname "$0")/../.."
build=${1:-build}
work=$build/ws_latency_bench
mkdir -p "$work"
setup_loopback_multicast
url=$SWEPTCCD_URL
port=18767
rm -f "$work/room.key"
"$build/bin/sweptccd" keygen --out "$work/room.key"
import_walk "$build/bin/sweptccd" . 90 "$work" >/dev/null
"$build/bin/sweptccd-service" --lcm-url "$url" --env data/env/morse_apartment.ply.gz --workers 2 \
  --room-key "$work/room.key" --log-level warn --max-live-clients 64 \
  --ws-listen 127.0.0.1:$port --ws-max-connections-per-address 64 2> "$work/daemon.log" &
daemon=$!
trap 'kill -KILL $daemon 2>/dev/null || true' EXIT
sleep 2
echo "| door | clients | Hz | poses sent | events | p50 us | p99 us | max us | intervals |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|"
for n in ${RUNS:-1 16}; do
  for door in lcm ws; do
    if [ $door = ws ]; then where=$port; else where=$url; fi
    "$build/bin/sweptccd_ws_latency" $door "$where" "$work/skeleton.json" "$work/poses.jsonl" \
      "$n" 90 "${SECONDS_PER_RUN:-10}" "$work/room.key"
    sleep 1
  done
done
kill -TERM $daemon
wait $daemon

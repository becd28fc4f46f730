#!/usr/bin/env bash
# Pose-to-event latency through the unicast WebSocket door from another
# host against LCM multicast on the room's own host (docs/BENCHMARKS.md),
# never on the host network: this script's private network namespace is a
# router between two network namespaces, A (the room: the daemon, LCM on
# its loopback, the door on 10.0.1.2) and B (remote clients, 10.0.2.2);
# unicast is forwarded, multicast is not (as in a cloud network). 1 and 16
# live clients at 90 Hz on the bundled walk through the bundled apartment:
# LCM clients on A, WebSocket clients on B (wss://, a self-signed
# certificate), the same signed daemon.
#   bash tools/service_bench/fleet_latency.sh [BUILD_DIR]   (default build)
# RUNS="CLIENTS ..." (default "1 16"), SECONDS_PER_RUN (default 10),
# DELAY_MS: netem delay added on the router's link to B, each way (default 0).
set -euo pipefail
source "$(dirname "$0")/../netns.sh"
enter_private_hosts_ns "$@"
cd "$(dirname "$0")/../.."
build=$(cd "${1:-build}" && pwd)
work=$build/fleet_latency_bench
rm -rf "$work" && mkdir -p "$work"
tag=sccdbench$$
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -KILL "$p" 2> /dev/null || true; done
  del_hosts "$tag" a b
}
trap cleanup EXIT
add_routed_hosts "$tag" a b
if [ "${DELAY_MS:-0}" != 0 ]; then tc qdisc add dev rb root netem delay "${DELAY_MS}ms"; fi
url=$SWEPTCCD_URL
"$build/bin/sweptccd" keygen --out "$work/room.key"
openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=bench -keyout "$work/door.key" \
  -out "$work/door.crt" 2> /dev/null
import_walk "$build/bin/sweptccd" . 90 "$work" > /dev/null
ip netns exec "${tag}a" "$build/bin/sweptccd-service" --lcm-url "$url" \
  --env data/env/morse_apartment.ply.gz --workers 2 --room-key "$work/room.key" --log-level warn \
  --ws-cert "$work/door.crt" --ws-key "$work/door.key" \
  --max-live-clients 64 --ws-listen 0.0.0.0:8765 --ws-max-connections-per-address 64 \
  2> "$work/daemon.log" &
pids+=($!)
sleep 2
echo "| door | clients | Hz | poses sent | events | p50 us | p99 us | max us | intervals |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|"
for c in ${RUNS:-1 16}; do
  ip netns exec "${tag}a" "$build/bin/sweptccd_ws_latency" lcm "$url" "$work/skeleton.json" \
    "$work/poses.jsonl" "$c" 90 "${SECONDS_PER_RUN:-10}" "$work/room.key" | sed 's/^| LCM/| LCM multicast, same host/'
  sleep 1
  ip netns exec "${tag}b" "$build/bin/sweptccd_ws_latency" ws tls:10.0.1.2:8765 "$work/skeleton.json" \
    "$work/poses.jsonl" "$c" 90 "${SECONDS_PER_RUN:-10}" "$work/room.key" | sed 's/^| WebSocket/| WebSocket via router/'
  sleep 1
done

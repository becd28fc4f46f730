#!/usr/bin/env bash
# A cold room's time from its start to Agones Ready (docs/BENCHMARKS.md):
# what a fleet's buffer hides from an allocation. The daemon with --agones
# and the 1.1 M-triangle scene (the Bitterli breakfast room and the
# Stanford dragon: 1 140 952 triangles, bench's breakfast+dragon_1.1M) in a
# private network namespace, the SDK sidecar stand-in
# (tests/service/ops/agones_sdk_standin.py) recording its calls; per run:
# exec -> POST /ready (the stand-in's clock), resident memory once Ready,
# then an allocation through the allocator stand-in
# (tests/service/fleet/agones_allocator_standin.py) and its round trip.
#   bash tools/service_bench/allocation_ready.sh [BUILD_DIR] [RUNS]   (build, 3)
set -euo pipefail
source "$(dirname "$0")/../netns.sh"
enter_private_netns "$@"
cd "$(dirname "$0")/../.."
src=$PWD
build=$(cd "${1:-build}" && pwd)
runs=${2:-3}
work=$build/allocation_ready_bench
rm -rf "$work" && mkdir -p "$work/gameservers"
setup_loopback_multicast
py=/usr/bin/python3
cat > "$work/room.yaml" <<YAML
lcm_url: "udpm://239.255.76.67:7667?ttl=0"
environment: [$src/data/env/bitterli_breakfast_room.ply.gz, $src/data/env/stanford_dragon_vrip.ply.gz]
backend: cpu
security: {mode: unsigned}
log_level: info
agones: {enabled: true, health_period_s: 0.5, empty_shutdown_s: 0}
YAML
"$py" tests/service/fleet/agones_allocator_standin.py 127.0.0.1 18080 "$work/gameservers" \
  "$work/allocator.log" &
alloc=$!
trap 'kill -KILL $alloc 2> /dev/null || true' EXIT
echo "| run | door | triangles | exec to Ready s | RSS at Ready MiB | allocation round trip ms |"
echo "|---:|---|---:|---:|---:|---:|"
# Each run with the WebSocket door (what a fleet's room runs: its display
# scene is built before Ready) and without it (LCM only).
for i in $(seq "$runs"); do
 for door in websocket none; do
  flags=()
  if [ $door = websocket ]; then flags=(--ws-listen 127.0.0.1:8765); fi
  rm -f "$work/gameservers/"*.json
  "$py" tests/service/ops/agones_sdk_standin.py 127.0.0.1 9358 "$work/sdk_$i-$door.log" \
    "$work/gameservers/room.json" room-$i 127.0.0.1 8765 sweptccd.dev/scene=dragon &
  sdk=$!
  for _ in $(seq 100); do curl -s -o /dev/null http://127.0.0.1:9358/none && break; sleep 0.05; done
  t0=$(date +%s.%N)
  AGONES_SDK_HTTP_PORT=9358 "$build/bin/sweptccd-service" --config "$work/room.yaml" "${flags[@]}" \
    2> "$work/daemon_$i-$door.log" &
  daemon=$!
  for _ in $(seq 1200); do grep -q '"/ready"' "$work/sdk_$i-$door.log" && break; sleep 0.05; done
  ready=$(grep '"/ready"' "$work/sdk_$i-$door.log" | head -1 | sed 's/.*"wall": \([0-9.]*\).*/\1/')
  rss=$(awk '/VmRSS/ {print $2}' /proc/$daemon/status)
  ms=$(curl -s -o /dev/null -w '%{time_total}' -X POST -H 'Content-Type: application/json' \
    http://127.0.0.1:18080/gameserverallocation \
    -d '{"namespace":"default","gameServerSelectors":[{"matchLabels":{"sweptccd.dev/scene":"dragon"}}],"metadata":{"labels":{"sweptccd.dev/room":"bench"}}}')
  tris=$(sed -n 's/.*environment: [0-9]* objects, \([0-9]*\) triangles, loaded in \([0-9.]*\) s.*/\1 (loaded in \2 s)/p' \
    "$work/daemon_$i-$door.log")
  awk -v i="$i" -v d="$door" -v tris="$tris" -v t0="$t0" -v r="$ready" -v rss="$rss" -v ms="$ms" 'BEGIN {
    printf "| %d | %s | %s | %.2f | %.0f | %.1f |\n", i, d, tris, r - t0, rss / 1024, ms * 1000 }'
  grep 'websocket scene' "$work/daemon_$i-$door.log" | sed 's/^.*\] /  /' >&2 || true
  kill -TERM $daemon
  wait $daemon || true
  kill -KILL $sdk
  wait $sdk 2> /dev/null || true
 done
done

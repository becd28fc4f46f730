#!/usr/bin/env bash
# Service latency benchmark inside a private network namespace (never the host
# network): for 1, 8 and 32 clients at 90 Hz, publication -> contact event.
#   bash tools/service_bench/run.sh [BUILD_DIR]   (default build)
set -euo pipefail
if [ "${SWEPTCCD_IN_NETNS:-}" != 1 ]; then
  if [ "$(id -u)" = 0 ]; then flags=-n; else flags=-rn; fi
  exec env SWEPTCCD_IN_NETNS=1 unshare $flags bash "$0" "$@"
fi
cd "$(dirname "$0")/../.."
build=${1:-build}
work=$build/service_bench
mkdir -p "$work"
# Refuse to run on a real network: a fresh namespace has only "lo".
[ "$(ip -o link show | wc -l)" = 1 ] || { echo "$0: not in a private network namespace" >&2; exit 1; }
ip link set lo up
ip route add 224.0.0.0/4 dev lo
url='udpm://239.255.76.67:7667?ttl=0'
"$build/bin/sweptccd" import-bvh --bvh data/demo/cmu_02_01_walk.bvh --up z --rate 90 \
  --offset 0 -1 0 --skeleton-out "$work/skeleton.json" --poses-out "$work/poses.jsonl"
echo "| clients | Hz | poses sent | events | median us | p99 us | max us |"
echo "|---:|---:|---:|---:|---:|---:|---:|"
for n in 1 8 32; do
  args=()
  for c in $(seq 0 $((n - 1))); do args+=(--client "client$c=$work/skeleton.json"); done
  "$build/bin/sweptccd-service" --lcm-url "$url" --env data/morse_apartment.ply --workers 2 \
    --log-level warn "${args[@]}" 2> "$work/daemon_$n.log" &
  daemon=$!
  sleep 1
  "$build/bin/sweptccd_latency_bench" "$url" "$work/poses.jsonl" "$n" 90 10
  kill -TERM $daemon
  wait $daemon
done

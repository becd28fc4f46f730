#!/usr/bin/env bash
# End-to-end load over udpm:// inside a private network namespace this script
# creates (never the host network): 8 clients (same skeleton, own ids) each
# publish the bundled walk imported at 90 Hz, at 90 Hz, all at once (about
# 3 s); every client's events come in order without gaps, poses - 1 =
# answered + skipped, and every event equals `sweptccd query` for its pair.
#   e2e_multi_client.sh SWEPTCCD SERVICE E2E_TOOL SOURCE_DIR WORK_DIR
set -euo pipefail
if [ "${SWEPTCCD_IN_NETNS:-}" != 1 ]; then
  if [ "$(id -u)" = 0 ]; then flags=-n; else flags=-rn; fi
  exec env SWEPTCCD_IN_NETNS=1 unshare $flags bash "$0" "$@"
fi
sweptccd=$1 service=$2 tool=$3 src=$4 work=$5
rm -rf "$work"; mkdir -p "$work"
# Refuse to run on a real network: a fresh namespace has only "lo".
[ "$(ip -o link show | wc -l)" = 1 ] || { echo "$0: not in a private network namespace" >&2; exit 1; }
ip link set lo up
ip route add 224.0.0.0/4 dev lo
url='udpm://239.255.76.67:7667?ttl=0'
env_ply="$src/data/morse_apartment.ply"
"$sweptccd" import-bvh --bvh "$src/data/demo/cmu_02_01_walk.bvh" --up z --rate 90 \
  --offset 0 -1 0 --utime-start 1000000 \
  --skeleton-out "$work/skeleton.json" --poses-out "$work/poses.jsonl"
"$sweptccd" query --skeleton "$work/skeleton.json" --poses "$work/poses.jsonl" \
  --env "$env_ply" --output "$work/expected.jsonl"
ids=(c0 c1 c2 c3 c4 c5 c6 c7)
client_flags=()
for id in "${ids[@]}"; do client_flags+=(--client "$id=$work/skeleton.json"); done
"$service" --lcm-url "$url" --env "$env_ply" "${client_flags[@]}" --log-level info \
  2> "$work/daemon.log" &
daemon=$!
collector=
trap 'kill -KILL $daemon $collector 2>/dev/null || true' EXIT
for _ in $(seq 100); do grep -q ready "$work/daemon.log" && break; sleep 0.1; done
grep -q ready "$work/daemon.log"
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

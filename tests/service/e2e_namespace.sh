#!/usr/bin/env bash
# End-to-end test of the daemon over udpm:// inside a private network
# namespace this script creates (never the host network): the bundled walk
# through the bundled apartment, every event compared with `sweptccd query`.
#   e2e_namespace.sh SWEPTCCD SERVICE E2E_CLIENT SOURCE_DIR WORK_DIR
set -euo pipefail
if [ "${SWEPTCCD_IN_NETNS:-}" != 1 ]; then
  # Re-run inside a new user + network namespace (as root: unshare -n).
  if [ "$(id -u)" = 0 ]; then flags=-n; else flags=-rn; fi
  exec env SWEPTCCD_IN_NETNS=1 unshare $flags bash "$0" "$@"
fi
sweptccd=$1 service=$2 client=$3 src=$4 work=$5
mkdir -p "$work"
# Refuse to run on a real network: a fresh namespace has only "lo".
[ "$(ip -o link show | wc -l)" = 1 ] || { echo "$0: not in a private network namespace" >&2; exit 1; }
ip link set lo up
ip route add 224.0.0.0/4 dev lo
url='udpm://239.255.76.67:7667?ttl=0'
# A bad configuration is refused with one line naming the file, status 2.
status=0
"$service" --lcm-url "$url" --env "$work/missing.ply" --client a=x.json 2> "$work/bad.log" || status=$?
[ "$status" = 2 ] && [ "$(wc -l < "$work/bad.log")" = 1 ] && grep -q missing.ply "$work/bad.log"
"$sweptccd" import-bvh --bvh "$src/data/demo/cmu_02_01_walk.bvh" --up z --rate 30 \
  --offset 0 -1 0 --utime-start 1000000 \
  --skeleton-out "$work/skeleton.json" --poses-out "$work/poses.jsonl"
"$sweptccd" query --skeleton "$work/skeleton.json" --poses "$work/poses.jsonl" \
  --env "$src/data/morse_apartment.ply" --output "$work/expected.jsonl"
"$service" --lcm-url "$url" --env "$src/data/morse_apartment.ply" \
  --client "alice=$work/skeleton.json" --log-level info 2> "$work/daemon.log" &
daemon=$!
trap 'kill -KILL $daemon 2>/dev/null || true' EXIT
for _ in $(seq 100); do grep -q ready "$work/daemon.log" && break; sleep 0.1; done
grep -q ready "$work/daemon.log"
"$client" "$url" alice "$work/poses.jsonl" "$work/expected.jsonl"
kill -TERM $daemon
wait $daemon
grep -q stopped "$work/daemon.log"
echo "e2e_namespace: passed"

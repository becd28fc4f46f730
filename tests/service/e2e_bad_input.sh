#!/usr/bin/env bash
# End-to-end bad input over udpm:// inside a private network namespace this
# script creates (never the host network): while a good client streams the
# bundled walk lock-step, a bad client and an unknown client send a wrong link
# count, non-finite numbers, a zero quaternion, an out-of-range position, a
# duplicate seq, a decreasing utime, and raw garbage / truncated bytes go on
# the pose channel; each gets a rejection_t with the right reason and the
# good client's every event equals `sweptccd query`.
#   e2e_bad_input.sh SWEPTCCD SERVICE E2E_TOOL SOURCE_DIR WORK_DIR
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
"$sweptccd" import-bvh --bvh "$src/data/demo/cmu_02_01_walk.bvh" --up z --rate 30 \
  --offset 0 -1 0 --utime-start 1000000 \
  --skeleton-out "$work/skeleton.json" --poses-out "$work/poses.jsonl"
"$sweptccd" query --skeleton "$work/skeleton.json" --poses "$work/poses.jsonl" \
  --env "$env_ply" --output "$work/expected.jsonl"
"$service" --lcm-url "$url" --env "$env_ply" --client "alice=$work/skeleton.json" \
  --client "bob=$work/skeleton.json" --log-level info 2> "$work/daemon.log" &
daemon=$!
trap 'kill -KILL $daemon 2>/dev/null || true' EXIT
for _ in $(seq 100); do grep -q ready "$work/daemon.log" && break; sleep 0.1; done
grep -q ready "$work/daemon.log"
"$tool" badinput "$url" alice bob "$work/poses.jsonl" "$work/expected.jsonl"
kill -TERM $daemon
wait $daemon
grep -q stopped "$work/daemon.log"
echo "e2e_bad_input: passed"

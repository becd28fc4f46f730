#!/usr/bin/env bash
# End-to-end test of the daemon over udpm:// inside a private network
# namespace this script creates (never the host network): the bundled walk
# through the bundled apartment, every event compared with `sweptccd query`.
#   e2e_namespace.sh SWEPTCCD SERVICE E2E_TOOL SOURCE_DIR WORK_DIR
set -euo pipefail
source "$(dirname "$0")/../../tools/netns.sh"
enter_private_netns "$@"
sweptccd=$1 service=$2 tool=$3 src=$4 work=$5
mkdir -p "$work"
setup_loopback_multicast
url=$SWEPTCCD_URL
# A bad configuration is refused with one line naming the file, status 2.
rm -f "$work/room.key" "$work/open.key"
"$sweptccd" keygen --out "$work/room.key"
status=0
"$service" --lcm-url "$url" --env "$work/missing.ply" --client a=x.json --room-key "$work/room.key" \
  2> "$work/bad.log" || status=$?
[ "$status" = 2 ] && [ "$(wc -l < "$work/bad.log")" = 1 ] && grep -q missing.ply "$work/bad.log"
# Flag values out of range are refused, not silently replaced by defaults.
for flag in "--workers 0" "--status-period -1"; do
  status=0
  # shellcheck disable=SC2086
  "$service" --lcm-url "$url" $flag --env "$src/data/env/morse_apartment.ply.gz" --client a=x.json \
    --room-key "$work/room.key" 2> "$work/bad.log" || status=$?
  [ "$status" = 2 ] && [ "$(wc -l < "$work/bad.log")" = 1 ] && grep -q -- "${flag% *}" "$work/bad.log"
done
import_walk "$sweptccd" "$src" 30 "$work"
query_walk "$sweptccd" "$src/data/env/morse_apartment.ply.gz" "$work"
# The CPU backend, then the GPU backend (llvmpipe in CI): the same answers.
# A key file others can read is refused with one line naming the fix.
"$sweptccd" keygen --out "$work/open.key"
chmod 644 "$work/open.key"
status=0
"$service" --lcm-url "$url" --env "$src/data/env/morse_apartment.ply.gz" --client "alice=$work/skeleton.json" \
  --room-key "$work/open.key" 2> "$work/bad.log" || status=$?
[ "$status" = 2 ] && [ "$(wc -l < "$work/bad.log")" = 1 ] && grep -q "chmod 600" "$work/bad.log"
for backend in cpu gpu; do
  "$service" --lcm-url "$url" --env "$src/data/env/morse_apartment.ply.gz" --backend $backend \
    --client "alice=$work/skeleton.json" --room-key "$work/room.key" --log-level info \
    --max-pose-rate 100000 2> "$work/daemon_$backend.log" &  # Lock-step outruns any tracker.
  daemon=$!
  trap 'kill -KILL $daemon 2>/dev/null || true' EXIT
  wait_for "$work/daemon_$backend.log" ready
  "$tool" --key "$work/room.key" lockstep "$url" alice "$work/poses.jsonl" "$work/expected.jsonl"
  kill -TERM $daemon
  wait $daemon
  grep -q stopped "$work/daemon_$backend.log"
done
grep -q "backend gpu (requested; " "$work/daemon_gpu.log"
echo "e2e_namespace: passed"

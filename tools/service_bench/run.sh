#!/usr/bin/env bash
# Service latency benchmark inside a private network namespace (never the host
# network): for 1, 8 and 32 clients at 90 Hz, publication -> contact event.
#   bash tools/service_bench/run.sh [BUILD_DIR]   (default build)
# RUNS="CLIENTS:HZ ..." changes the runs (default "1:90 8:90 32:90"; issue 11's
# throughput targets: RUNS="1:90 32:90 64:120"). The walk is imported at each
# rate. "merged" = consecutive pairs (poses - clients) not answered, the
# pairs latest-wins merged (or lost).
set -euo pipefail
source "$(dirname "$0")/../netns.sh"
enter_private_netns "$@"
cd "$(dirname "$0")/../.."
build=${1:-build}
work=$build/service_bench
mkdir -p "$work"
setup_loopback_multicast
url=$SWEPTCCD_URL
rm -f "$work/room.key"
"$build/bin/sweptccd" keygen --out "$work/room.key"
echo "| clients | Hz | poses sent | events | median us | p99 us | max us | merged |"
echo "|---:|---:|---:|---:|---:|---:|---:|---:|"
for run in ${RUNS:-1:90 8:90 32:90}; do
  n=${run%%:*} hz=${run#*:}
  import_walk "$build/bin/sweptccd" . "$hz" "$work" >/dev/null
  args=()
  for c in $(seq 0 $((n - 1))); do args+=(--client "client$c=$work/skeleton.json"); done
  "$build/bin/sweptccd-service" --lcm-url "$url" --env data/env/morse_apartment.ply.gz --workers 2 \
    --room-key "$work/room.key" --log-level warn "${args[@]}" 2> "$work/daemon_$n.log" &
  daemon=$!
  sleep 1
  line=$("$build/bin/sweptccd_latency_bench" "$url" "$work/poses.jsonl" "$n" "$hz" 10 "$work/room.key")
  read -r sent events < <(awk -F'|' '{ gsub(/ /, ""); print $4, $5 }' <<< "$line")
  echo "$line $(awk -v s="$sent" -v e="$events" -v n="$n" 'BEGIN { printf "%.2f%% |", 100 * (s - n - e) / (s - n) }')"
  kill -TERM $daemon
  wait $daemon
done

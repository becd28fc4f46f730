#!/usr/bin/env bash
# Joins under load, inside a private network namespace (never the host
# network): 8 configured clients stream the bundled walk at 90 Hz for 10 s
# (sweptccd_latency_bench: publication -> contact event), four times:
#   alone     nothing else;
#   listen    the control: the churn process opens and closes the same LCM
#             receivers at the same times (10 a second, each open 0.8 s)
#             but never joins: its own cost to the shared machine;
#   churn     live clients join and leave at 10 per second, each live 0.8 s
#             and streaming a pose at 90 Hz meanwhile (about 8 more clients
#             streaming at any time, so more pairs to answer);
#   joinonly  live clients join and leave at 10 per second without a pose:
#             the join and leave work alone.
# The live clients are LiveClients of the client library in one process
# (sweptccd_join_churn), which also prints the join round trip.
# Prints the latency table of the 8 streaming clients for each run and the
# joins and leaves the daemon logged. Figures are printed, never asserted.
#   bash tools/service_bench/join_churn.sh [BUILD_DIR]   (default build)
set -euo pipefail
source "$(dirname "$0")/../netns.sh"
enter_private_netns "$@"
cd "$(dirname "$0")/../.."
build=${1:-build}
work=$build/service_bench_churn
mkdir -p "$work"
setup_loopback_multicast
url=$SWEPTCCD_URL
import_walk "$build/bin/sweptccd" . 90 "$work"
rm -f "$work/room.key"
"$build/bin/sweptccd" keygen --out "$work/room.key"
args=()
for c in $(seq 0 7); do args+=(--client "client$c=$work/skeleton.json"); done
echo "| run | clients | Hz | poses sent | events | median us | p99 us | max us |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
for run in alone listen churn joinonly; do
  "$build/bin/sweptccd-service" --lcm-url "$url" --env data/env/morse_apartment.ply.gz \
    --workers 2 --room-key "$work/room.key" --log-level info --max-live-clients 32 \
    --silence-timeout-ms 2000 "${args[@]}" 2> "$work/daemon_$run.log" &
  daemon=$!
  sleep 1
  churn=
  if [ "$run" != alone ]; then
    mode=join
    if [ "$run" = churn ]; then mode=stream; fi
    if [ "$run" = listen ]; then mode=listen; fi
    "$build/bin/sweptccd_join_churn" "$url" "$work/skeleton.json" "$work/poses.jsonl" \
      "$work/room.key" 10 0.8 11 $mode > "$work/churn_$run.out" 2>&1 &
    churn=$!
  fi
  line=$("$build/bin/sweptccd_latency_bench" "$url" "$work/poses.jsonl" 8 90 10 "$work/room.key")
  echo "| $run ${line#| }"
  if [ -n "$churn" ]; then wait $churn || true; fi
  kill -TERM $daemon
  wait $daemon
done
echo
for run in churn joinonly; do
  echo "$run run: $(cat "$work/churn_$run.out")"
  echo "  daemon log: $(grep -c "joined: session" "$work/daemon_$run.log") joins," \
    "$(grep -c "' left (session" "$work/daemon_$run.log") leaves," \
    "$(grep -c "join of client .* refused" "$work/daemon_$run.log" || true) refused"
done

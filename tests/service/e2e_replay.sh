#!/usr/bin/env bash
# End-to-end record and replay over udpm:// inside a private network
# namespace this script creates (never the host network): the daemon runs
# while a publisher sends the bundled walk at 30 Hz and lcm-logger records the
# pose channel; then, for lcm-logplayer speeds 1, 2 and 4, a fresh daemon
# answers the replayed log and every contact event must equal `sweptccd query`
# for the same pair (consecutive pairs from the whole-file query, pairs joined
# by latest-wins from a query on the two poses).
#   e2e_replay.sh SWEPTCCD SERVICE E2E_TOOL SOURCE_DIR WORK_DIR
set -euo pipefail
source "$(dirname "$0")/../../tools/netns.sh"
enter_private_netns "$@"
sweptccd=$1 service=$2 tool=$3 src=$4 work=$5
rm -rf "$work"; mkdir -p "$work"
setup_loopback_multicast
url=$SWEPTCCD_URL
env_ply="$src/data/env/morse_apartment.ply.gz"
import_walk "$sweptccd" "$src" 30 "$work"
query_walk "$sweptccd" "$env_ply" "$work"
pids=()
trap 'for p in "${pids[@]}"; do kill -KILL "$p" 2>/dev/null || true; done' EXIT
"$sweptccd" keygen --out "$work/room.key"
start_daemon() {  # LOG
  "$service" --lcm-url "$url" --env "$env_ply" --client "alice=$work/skeleton.json" \
    --room-key "$work/room.key" --log-level info 2> "$1" &
  daemon=$!; pids+=("$daemon")
  wait_for "$1" ready
}
stop_daemon() {  # LOG
  kill -TERM "$daemon"; wait "$daemon"; grep -q stopped "$1"
}
collect() {  # NAME: collector in the background, waits until it is subscribed
  timeout 60 "$tool" --key "$work/room.key" collect "$url" "$work/poses.jsonl" "$work/expected.jsonl" "$sweptccd" \
    "$work/skeleton.json" "$env_ply" "$work/$1.ready" 30 alice > "$work/$1.out" 2>&1 &
  collector=$!; pids+=("$collector")
  wait_for "$work/$1.ready" ready
}
# Record: daemon live, logger on the pose channel, publisher at 30 Hz.
start_daemon "$work/daemon-record.log"
lcm-logger -q -f -c 'SWEPTCCD_POSE|E2E_PROBE' --flush-interval=10 --lcm-url="$url" \
  "$work/poses.lcmlog" &
logger=$!; pids+=("$logger")
# lcm-logger prints nothing once subscribed: probe on a side channel until a
# probe is in the log (bounded), so the first pose cannot be missed.
for _ in $(seq 100); do
  "$tool" probe "$url" E2E_PROBE
  grep -q E2E_PROBE "$work/poses.lcmlog" 2>/dev/null && break
  sleep 0.1
done
grep -q E2E_PROBE "$work/poses.lcmlog" || { echo "e2e_replay: lcm-logger records nothing" >&2; exit 1; }
collect live
"$tool" --key "$work/room.key" publish "$url" "$work/poses.jsonl" 30 alice
wait "$collector" || { cat "$work/live.out" >&2; exit 1; }
cat "$work/live.out"
kill -INT "$logger"; wait "$logger" || true
stop_daemon "$work/daemon-record.log"
# Replay at 1x, 2x and 4x into a fresh daemon each time. The collector
# requires events up to the last pose with answered + skipped = poses - 1, so
# a log missing a pose fails.
for speed in 1 2 4; do
  start_daemon "$work/daemon-$speed.log"
  collect "replay-$speed"
  lcm-logplayer -s "$speed" -e '^SWEPTCCD_POSE$' -l "$url" "$work/poses.lcmlog"
  wait "$collector" || { echo "speed $speed:" >&2; cat "$work/replay-$speed.out" >&2; exit 1; }
  echo "speed $speed:"; cat "$work/replay-$speed.out"
  stop_daemon "$work/daemon-$speed.log"
done
pids=()  # all reaped: nothing for the EXIT trap to kill
echo "e2e_replay: passed"

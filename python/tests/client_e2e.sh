#!/usr/bin/env bash
# The Python client (python/sweptccd/client.py) against the real daemon's
# WebSocket door, inside a private network namespace this script creates
# (never the host network): client_e2e.py (see its header).
#   client_e2e.sh SWEPTCCD SERVICE PYTHON SOURCE_DIR WORK_DIR PYTHONPATH
set -euo pipefail
src_dir=$4
source "$src_dir/tools/netns.sh"
enter_private_netns "$@"
sweptccd=$1 service=$2 python=$3 src=$4 work=$5 pypath=$6
rm -rf "$work"; mkdir -p "$work"
setup_loopback_multicast
fail() { echo "client_e2e: FAILED: $*" >&2; exit 1; }
import_walk "$sweptccd" "$src" 30 "$work"
query_walk "$sweptccd" "$src/data/env/morse_apartment.ply.gz" "$work"
"$sweptccd" keygen --out "$work/room.key"
"$sweptccd" keygen --out "$work/walker.key"
port=7702
"$service" --lcm-url "$SWEPTCCD_URL" --env "$src/data/env/morse_apartment.ply.gz" \
  --room-key "$work/room.key" --max-live-clients 8 --status-period 0.2 --room py-room \
  --client "pywalker=$work/skeleton.json" --client-key "pywalker=$work/walker.key" \
  --ws-listen "127.0.0.1:$port" --log-level info 2> "$work/daemon.log" &
daemon=$!
trap 'kill -KILL $daemon 2>/dev/null || true' EXIT
wait_for "$work/daemon.log" ready || { cat "$work/daemon.log" >&2; fail "no daemon"; }
PYTHONPATH=$pypath PYTHONDONTWRITEBYTECODE=1 "$python" "$(dirname "$0")/client_e2e.py" \
  "ws://127.0.0.1:$port/ws" "$work/room.key" "$work/skeleton.json" "$work/poses.jsonl" \
  "$work/expected.jsonl" "$work/walker.key" || { tail -20 "$work/daemon.log" >&2; fail "client_e2e.py"; }
# The example: joins, streams 40 poses at 60 Hz, prints contacts, leaves.
PYTHONPATH=$pypath PYTHONDONTWRITEBYTECODE=1 "$python" "$src/python/examples/live_walk.py" \
  --url "ws://127.0.0.1:$port/ws" --key "$work/room.key" --id example \
  --skeleton "$work/skeleton.json" --poses "$work/poses.jsonl" --rate 60 --count 40 \
  > "$work/example.out" || { cat "$work/example.out" >&2; fail "live_walk.py"; }
cat "$work/example.out"
grep -q "^joined as example: session" "$work/example.out" || fail "the example did not join"
grep -q "^left: 40 poses sent, 39 events" "$work/example.out" || fail "the example lost events"
kill -TERM $daemon
wait $daemon || true
echo "client_e2e: passed"

#!/usr/bin/env bash
# The JavaScript client (client/js) under Node against the real daemon's
# WebSocket door, inside a private network namespace this script creates
# (never the host network): js_client_e2e.mjs (see its header), then the
# Node example streams the walk and must print its contacts and leave.
#   js_client_e2e.sh SWEPTCCD SERVICE NODE SOURCE_DIR WORK_DIR JS_DIR
set -euo pipefail
source "$(dirname "$0")/../../tools/netns.sh"
enter_private_netns "$@"
sweptccd=$1 service=$2 node=$3 src=$4 work=$5 js=$6
rm -rf "$work"; mkdir -p "$work"
setup_loopback_multicast
fail() { echo "js_client_e2e: FAILED: $*" >&2; exit 1; }
import_walk "$sweptccd" "$src" 30 "$work"
query_walk "$sweptccd" "$src/data/env/morse_apartment.ply.gz" "$work"
"$sweptccd" keygen --out "$work/room.key"
"$sweptccd" keygen --out "$work/walker.key"
port=7701
"$service" --lcm-url "$SWEPTCCD_URL" --env "$src/data/env/morse_apartment.ply.gz" \
  --room-key "$work/room.key" --max-live-clients 8 --status-period 0.2 --room js-room \
  --client "jswalker=$work/skeleton.json" --client-key "jswalker=$work/walker.key" \
  --ws-listen "127.0.0.1:$port" --log-level info 2> "$work/daemon.log" &
daemon=$!
trap 'kill -KILL $daemon 2>/dev/null || true' EXIT
wait_for "$work/daemon.log" ready || { cat "$work/daemon.log" >&2; fail "no daemon"; }
export SWEPTCCD_JS_DIR=$js
url="ws://127.0.0.1:$port/ws"
"$node" "$(dirname "$0")/js_client_e2e.mjs" "$url" "$work/room.key" "$work/skeleton.json" \
  "$work/poses.jsonl" "$work/expected.jsonl" "$work/walker.key" || { tail -n 20 "$work/daemon.log" >&2; fail "js_client_e2e.mjs"; }
# The Node example: joins, streams 40 poses at 60 Hz, prints contacts, leaves.
"$node" "$js/examples/node_example.mjs" --url "$url" --key "$work/room.key" --id example \
  --skeleton "$work/skeleton.json" --poses "$work/poses.jsonl" --rate 60 --count 40 > "$work/example.out" \
  || { cat "$work/example.out" >&2; fail "node_example.mjs"; }
cat "$work/example.out"
grep -q "^joined as example: session" "$work/example.out" || fail "the example did not join"
grep -q "contact at s" "$work/example.out" || fail "the example printed no contact"
# (Pairs the daemon skips when behind are fine: the answers reach the last pose.)
grep -q "^left: 40 poses sent, [0-9]* events answering up to seq 39," "$work/example.out" || fail "the example lost the last answer"
kill -TERM $daemon
wait $daemon || true
echo "js_client_e2e: passed"

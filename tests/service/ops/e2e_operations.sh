#!/usr/bin/env bash
# The daemon's operator interfaces end to end (docs/DEPLOY.md), inside a
# private network namespace this script creates (never the host network):
#  - systemd: a fake NOTIFY_SOCKET (notify_socket.py) gets READY=1 first, then
#    WATCHDOG=1 repeatedly (WATCHDOG_USEC=400000), none while the loop is
#    wedged (the test hook SWEPTCCD_TEST_WEDGE_FILE), again after, STOPPING=1
#    on SIGTERM;
#  - Agones (--agones): the SDK sidecar stand-in (agones_sdk_standin.py)
#    records Ready first, Health while the loop runs, none while it is wedged
#    or after the daemon ended, Shutdown once, after the empty-room time;
#    a second run: a live client joined through the WebSocket door
#    (ws_hold_room.py) postpones Shutdown until empty_shutdown_s after it left;
#  - /metrics on --metrics-listen parses strictly (prom_parse.py) and counts
#    the room; other paths are 404; the door (no metrics_token_file) has
#    no /metrics.
#   e2e_operations.sh SERVICE SOURCE_DIR WORK_DIR
set -euo pipefail
source "$(dirname "$0")/../../../tools/netns.sh"
enter_private_netns "$@"
service=$1 src=$2 work=$3
here=$src/tests/service/ops
py=/usr/bin/python3  # Debian's, with python3-websockets
rm -rf "$work" && mkdir -p "$work"
setup_loopback_multicast
cd "$work"
printf 'v -10 -10 0\nv 10 -10 0\nv 10 10 0\nv -10 10 0\nf 1 2 3\nf 1 3 4\n' > floor.obj
cat > two.json <<'JSON'
{"name": "two", "links": [
  {"name": "pelvis", "parent": null, "a": [0, 0, 0], "b": [0, 0, 0.3], "radius": 0.1},
  {"name": "arm", "parent": "pelvis", "a": [0, 0, 0], "b": [0.3, 0, 0], "radius": 0.05}]}
JSON
cat > room.yaml <<'YAML'
lcm_url: "udpm://239.255.76.67:7667?ttl=0"
environment: [floor.obj]
clients: [{id: alice, skeleton: two.json}]
backend: cpu
log_level: warn
security: {mode: unsigned}
room: e2e-room
metrics: {listen: "127.0.0.1:9464"}
agones: {enabled: true, health_period_s: 0.2, empty_shutdown_s: 4}
YAML
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2> /dev/null || true; done; }
trap cleanup EXIT
fail() { echo "e2e_operations: $*" >&2; echo "--- daemon log" >&2; cat daemon.log >&2 || true; exit 1; }
"$py" "$here/notify_socket.py" "$work/notify.sock" notify.log & pids+=($!)
"$py" "$here/agones_sdk_standin.py" 127.0.0.1 9358 agones.log & pids+=($!)
for _ in $(seq 100); do [ -S notify.sock ] && curl -s -o /dev/null http://127.0.0.1:9358/none && break; sleep 0.05; done
: > agones.log  # The probe above is not the daemon's.
# --agones without AGONES_SDK_HTTP_PORT: refused in one line, status 2.
status=0
"$service" --config room.yaml 2> bad.log || status=$?
[ "$status" = 2 ] && [ "$(wc -l < bad.log)" = 1 ] && grep -q AGONES_SDK_HTTP_PORT bad.log ||
  fail "no AGONES_SDK_HTTP_PORT: status $status, $(cat bad.log)"
# A metrics address off loopback: refused (plain HTTP stays on the host).
status=0
AGONES_SDK_HTTP_PORT=9358 "$service" --config room.yaml --metrics-listen 0.0.0.0:9464 2> bad.log || status=$?
[ "$status" = 2 ] && grep -q 'metrics.listen' bad.log || fail "0.0.0.0 metrics: status $status"

wedge=$work/wedge
NOTIFY_SOCKET=$work/notify.sock WATCHDOG_USEC=400000 AGONES_SDK_HTTP_PORT=9358 \
  SWEPTCCD_TEST_WEDGE_FILE=$wedge "$service" --config room.yaml --log-level info 2> daemon.log & daemon=$!
pids+=($daemon)
count() { grep -c "$2" "$1" 2> /dev/null || true; }
for _ in $(seq 200); do [ "$(count notify.log READY=1)" = 1 ] && [ "$(count agones.log '"/ready"')" -ge 1 ] && break; sleep 0.05; done
[ "$(head -1 notify.log | cut -d' ' -f2)" = READY=1 ] || fail "first notification: $(head -1 notify.log)"
[ "$(head -1 agones.log | "$py" -c 'import json,sys; print(json.load(sys.stdin)["path"])')" = /ready ] ||
  fail "first Agones call: $(head -1 agones.log)"
grep -q 'environment: 1 objects' daemon.log || fail "READY before the scene loaded"
grep -q '"bad": true' agones.log && fail "a malformed call: $(grep '"bad": true' agones.log)"

# /metrics: strict parse; the room's label and client; 404 elsewhere.
curl -sf http://127.0.0.1:9464/metrics > metrics.txt || fail "GET /metrics"
"$py" "$here/prom_parse.py" < metrics.txt > metrics.json || fail "metrics do not parse"
"$py" - metrics.json <<'PY' || fail "metrics content"
import json, sys
m = json.load(open(sys.argv[1]))
assert m['sweptccd_clients{room="e2e-room"}'] == 1, m
assert 'sweptccd_poses_received_total{room="e2e-room",client="alice"}' in m
assert 'sweptccd_pair_latency_seconds_count{room="e2e-room"}' in m
PY
code=$(curl -s -o /dev/null -w '%{http_code}' http://127.0.0.1:9464/other)
[ "$code" = 404 ] || fail "/other answered $code"
code=$(curl -s -o /dev/null -w '%{http_code}' -X POST http://127.0.0.1:9464/metrics)
[ "$code" = 405 ] || fail "POST /metrics answered $code"

# Running: WATCHDOG=1 and Health keep coming.
w0=$(count notify.log WATCHDOG=1) h0=$(count agones.log '"/health"')
sleep 1.2
w1=$(count notify.log WATCHDOG=1) h1=$(count agones.log '"/health"')
[ $((w1 - w0)) -ge 3 ] || fail "WATCHDOG while running: $w0 -> $w1"
[ $((h1 - h0)) -ge 3 ] || fail "Health while running: $h0 -> $h1"
# Wedged: none (after what was on its way: Health stops 1 s after the loop's
# last tick, AgonesLifecycle::kStallLimit).
touch "$wedge"
sleep 1.5
w1=$(count notify.log WATCHDOG=1) h1=$(count agones.log '"/health"')
sleep 1.2
w2=$(count notify.log WATCHDOG=1) h2=$(count agones.log '"/health"')
[ "$w2" = "$w1" ] || fail "WATCHDOG from a wedged loop: $w1 -> $w2"
[ "$h2" = "$h1" ] || fail "Health from a wedged loop: $h1 -> $h2"
grep -q 'loop has not run' daemon.log || fail "no log line for the wedged loop"
[ "$(grep -c 'loop has not run' daemon.log)" = 1 ] || fail "a loop that ran was called wedged"
# Unwedged: both again.
rm "$wedge"
sleep 1.2
w3=$(count notify.log WATCHDOG=1) h3=$(count agones.log '"/health"')
[ $((w3 - w2)) -ge 3 ] || fail "WATCHDOG after the wedge: $w2 -> $w3"
[ $((h3 - h2)) -ge 3 ] || fail "Health after the wedge: $h2 -> $h3"

# The room stayed empty (no live client): Shutdown once, not before 4 s after Ready.
for _ in $(seq 100); do [ "$(count agones.log '"/shutdown"')" -ge 1 ] && break; sleep 0.05; done
"$py" - agones.log <<'PY' || fail "Shutdown timing"
import json, sys
calls = [json.loads(l) for l in open(sys.argv[1])]
ready = next(c["t"] for c in calls if c["path"] == "/ready")
shut = [c["t"] for c in calls if c["path"] == "/shutdown"]
assert len(shut) == 1, shut
assert shut[0] - ready >= 4.0 - 0.05, (ready, shut)
assert shut[0] - ready < 4.0 + 2.0, (ready, shut)
PY

# SIGTERM (what Agones sends after Shutdown): STOPPING=1, a clean exit, no Health after.
kill -TERM "$daemon"
status=0
wait "$daemon" || status=$?
[ "$status" = 0 ] || fail "daemon exit status $status"
grep -q STOPPING=1 notify.log || fail "no STOPPING=1"
h4=$(count agones.log '"/health"')
sleep 0.6
[ "$(count agones.log '"/health"')" = "$h4" ] || fail "Health after the daemon ended"

# A live client keeps the room: a second run whose client (through the
# WebSocket door, tests/service/ops/ws_hold_room.py) joins at once and stays
# 4 s, past empty_shutdown_s (2 s): no Shutdown while it is there, one
# Shutdown 2 s after it left.
: > agones.log
sed -e 's/empty_shutdown_s: 4/empty_shutdown_s: 2/' -e 's/^log_level: warn/silence_timeout_ms: 60000/' \
  room.yaml > room2.yaml
printf 'max_live_clients: 4\nwebsocket: {listen: "127.0.0.1:8765"}\n' >> room2.yaml
AGONES_SDK_HTTP_PORT=9358 "$service" --config room2.yaml --log-level info 2> daemon.log & daemon=$!
pids+=($daemon)
for _ in $(seq 200); do grep -q '"/ready"' agones.log && break; sleep 0.05; done
# A door without websocket.metrics_token_file does not serve /metrics.
code=$(curl -s -o /dev/null -w '%{http_code}' http://127.0.0.1:8765/metrics)
[ "$code" = 404 ] || fail "door /metrics without a token file answered $code"
"$py" "$here/ws_hold_room.py" ws://127.0.0.1:8765/ws bob 4 > hold.log || fail "ws client: $(cat hold.log)"
for _ in $(seq 100); do grep -q '"/shutdown"' agones.log && break; sleep 0.05; done
"$py" - agones.log hold.log <<'PY' || fail "Shutdown with a live client"
import json, sys
calls = [json.loads(l) for l in open(sys.argv[1])]
hold = dict(l.split() for l in open(sys.argv[2]))
ready = next(c["wall"] for c in calls if c["path"] == "/ready")
joined, leaving, left = (float(hold[k]) for k in ("joined", "leaving", "left"))
shut = [c["wall"] for c in calls if c["path"] == "/shutdown"]
assert joined - ready < 1.5, ("joined too late to test", ready, joined)
assert leaving - ready > 2.5, ("left too early to test", ready, leaving)
assert len(shut) == 1, shut
# The daemon saw the leave between `leaving` and `left` (the close came after).
assert shut[0] >= leaving + 2.0 and shut[0] < left + 2.0 + 1.5, (leaving, left, shut)
PY
kill -TERM "$daemon"
wait "$daemon" || fail "second daemon exit status $?"
echo "e2e_operations: passed (watchdog $w3, health $h3 pings)"

#!/usr/bin/env bash
# The room a GameServer holds, read from the Agones SDK sidecar (docs/DEPLOY.md
# "Which room a server holds"), end to end inside a private network namespace
# this script creates: the daemon starts as its configured `room`; after
# Ready the sidecar stand-in (agones_sdk_standin.py) labels the GameServer
# sweptccd.dev/room=lobby-7 and streams the change on GET /watch/gameserver;
# the daemon then says lobby-7 in /metrics' room label, in the WebSocket
# door's hello and status, and in one log line. A label that breaks the id
# rule is refused (the room stays, one escaped warning); a streamed line over
# the limit drops the stream, the daemon reconnects and reads the label set
# meanwhile (GET /gameserver once the stream is open). The door is TLS
# (wss://, a self-signed certificate) with websocket.metrics_token_file:
# GET /metrics on the door's port needs the bearer token (401 without it or
# with another) and then answers the same room; a token file readable by
# others is refused at start. /ws?room=NAME of another room is refused (409).
#   e2e_room_label.sh SERVICE SOURCE_DIR WORK_DIR
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
openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 1 \
  -subj /CN=localhost -keyout door.key -out door.crt 2> /dev/null
openssl rand -hex 32 > metrics.token
chmod 644 metrics.token
cat > room.yaml <<'YAML'
lcm_url: "udpm://239.255.76.67:7667?ttl=0"
environment: [floor.obj]
backend: cpu
security: {mode: unsigned}
max_live_clients: 4
status_period_s: 0.2
room: config-room
metrics: {listen: "127.0.0.1:9464"}
websocket: {listen: "127.0.0.1:8765", cert: door.crt, key: door.key, metrics_token_file: metrics.token}
agones: {enabled: true, health_period_s: 0.5, empty_shutdown_s: 0}
YAML
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2> /dev/null || true; done; }
trap cleanup EXIT
fail() { echo "e2e_room_label: $*" >&2; echo "--- daemon log" >&2; cat daemon.log >&2 || true; exit 1; }
"$py" "$here/agones_sdk_standin.py" 127.0.0.1 9358 agones.log & pids+=($!)
for _ in $(seq 100); do curl -s -o /dev/null http://127.0.0.1:9358/none && break; sleep 0.05; done
control() { curl -sf -H 'Content-Type: application/json' -d "$2" "http://127.0.0.1:9358/standin/$1" > /dev/null; }
watches() { grep -c '"/watch/gameserver"' agones.log || true; }
metrics_room() { curl -sf http://127.0.0.1:9464/metrics | sed -n 's/^sweptccd_clients{room="\([^"]*\)"}.*/\1/p'; }
wait_room() {  # wait_room NAME: /metrics says NAME within 5 s
  for _ in $(seq 100); do [ "$(metrics_room)" = "$1" ] && return 0; sleep 0.05; done
  fail "metrics room: '$(metrics_room)', expected '$1'"
}
# A token file readable by others: refused in one error line, status 2.
status=0
AGONES_SDK_HTTP_PORT=9358 "$service" --config room.yaml 2> bad.log || status=$?
[ "$status" = 2 ] && [ "$(grep -c '^error:' bad.log)" = 1 ] && tail -1 bad.log | grep -q 'chmod 600' ||
  fail "token file mode 644: status $status, $(cat bad.log)"
: > agones.log
chmod 600 metrics.token
AGONES_SDK_HTTP_PORT=9358 "$service" --config room.yaml --log-level info 2> daemon.log & daemon=$!
pids+=($daemon)
for _ in $(seq 200); do [ "$(watches)" -ge 1 ] && grep -q '"/gameserver"' agones.log && break; sleep 0.05; done
[ "$(watches)" -ge 1 ] || fail "no GET /watch/gameserver after Ready: $(cat agones.log)"

# Unlabelled: the configured room everywhere.
wait_room config-room
"$py" "$here/ws_room.py" wss://127.0.0.1:8765/ws alice > ws.log || fail "ws: $(cat ws.log)"
[ "$(cat ws.log)" = $'hello config-room\nstatus config-room' ] || fail "before the label: $(cat ws.log)"

# Labelled after Ready: streamed, and the daemon tells lobby-7.
control labels '{"sweptccd.dev/room": "lobby-7", "other": "x"}'
wait_room lobby-7
"$py" "$here/ws_room.py" wss://127.0.0.1:8765/ws alice > ws.log || fail "ws: $(cat ws.log)"
[ "$(cat ws.log)" = $'hello lobby-7\nstatus lobby-7' ] || fail "after the label: $(cat ws.log)"
[ "$(grep -c "holds room 'lobby-7'" daemon.log)" = 1 ] || fail "no single log line for lobby-7"

# A label that breaks the id rule (a newline, an escape): refused, escaped once.
control labels '{"sweptccd.dev/room": "bad\nroom\u001b[31m"}'
for _ in $(seq 100); do grep -q 'breaks the id rule' daemon.log && break; sleep 0.05; done
[ "$(grep -c 'breaks the id rule' daemon.log)" = 1 ] || fail "the bad label: not one warning"
grep -q $'\x1b' daemon.log && fail "a raw escape byte in the log"
[ "$(metrics_room)" = lobby-7 ] || fail "a bad label changed the room: $(metrics_room)"

# A streamed line over the limit (256 KiB): the stream is dropped, the daemon
# reconnects and reads the label set while it was away.
w0=$(watches)
control raw '{"bytes": 300000}'
for _ in $(seq 100); do grep -q 'a line over 262144 bytes' daemon.log && break; sleep 0.05; done
grep -q 'a line over 262144 bytes' daemon.log || fail "no log line for the long line"
control labels '{"sweptccd.dev/room": "lobby-8"}'
wait_room lobby-8
[ "$(watches)" -gt "$w0" ] || fail "the watch did not reconnect"
"$py" "$here/ws_room.py" wss://127.0.0.1:8765/ws alice > ws.log || fail "ws: $(cat ws.log)"
[ "$(cat ws.log)" = $'hello lobby-8\nstatus lobby-8' ] || fail "after the reconnect: $(cat ws.log)"

# /ws?room=NAME: the room held is let in, another room is refused (409), a
# name that breaks the id rule too (400).
"$py" "$here/ws_room.py" 'wss://127.0.0.1:8765/ws?room=lobby-8' alice > ws.log || fail "ws ?room=lobby-8: $(cat ws.log)"
[ "$(cat ws.log)" = $'hello lobby-8\nstatus lobby-8' ] || fail "?room=lobby-8: $(cat ws.log)"
upgrade() {
  curl -sk -o upgrade.txt -w '%{http_code}' --max-time 3 -H 'Connection: Upgrade' -H 'Upgrade: websocket' \
    -H 'Sec-WebSocket-Version: 13' -H 'Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==' \
    -H 'Sec-WebSocket-Protocol: sweptccd.v1' "https://127.0.0.1:8765/ws?$1" || true
}
code=$(upgrade room=lobby-7) && [ "$code" = 409 ] && grep -q "holds room 'lobby-8'" upgrade.txt ||
  fail "?room=lobby-7 answered $code: $(cat upgrade.txt)"
code=$(upgrade 'x=1&room=bad%0Aroom') && [ "$code" = 400 ] || fail "?room=bad answered $code"

# /metrics through the door's TLS port: the bearer token or nothing.
door_metrics() { curl -sk -o door_metrics.txt -w '%{http_code}' "$@" https://127.0.0.1:8765/metrics; }
code=$(door_metrics) && [ "$code" = 401 ] || fail "door /metrics without the token: $code"
code=$(door_metrics -H "Authorization: Bearer $(openssl rand -hex 32)") && [ "$code" = 401 ] ||
  fail "door /metrics with another token: $code"
code=$(door_metrics -H "Authorization: Bearer $(cat metrics.token)") && [ "$code" = 200 ] ||
  fail "door /metrics with the token: $code"
"$py" "$here/prom_parse.py" < door_metrics.txt > door_metrics.json || fail "door metrics do not parse"
$py -c 'import json,sys; m = json.load(open(sys.argv[1])); sys.exit(m.get("sweptccd_clients{room=\"lobby-8\"}") is None)' \
  door_metrics.json || fail "door metrics: $(head -c 300 door_metrics.json)"
code=$(curl -s -o /dev/null -w '%{http_code}' -H "Authorization: Bearer $(cat metrics.token)" \
  http://127.0.0.1:8765/metrics) || true
[ "$code" != 200 ] || fail "door /metrics answered over plain HTTP on the TLS port"

kill -TERM "$daemon"
status=0
wait "$daemon" || status=$?
[ "$status" = 0 ] || fail "daemon exit status $status"
echo "e2e_room_label: passed"

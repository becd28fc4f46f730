#!/usr/bin/env bash
# Attacks on the WebSocket door (docs/WEBSOCKET.md), inside a private network
# namespace this script creates (never the host network), each bounded in
# count and time (ws_attack_tool: connection flood, slowloris handshakes,
# oversized and fragmented messages, malformed JSON and binary frames, a
# join under a wrong key, a message burst, a client that never reads), all
# at once WHILE a good WebSocket client and LCM clients share the room
# (shared_world_tool play-ws): every good answer stays equal to
# `sweptccd world`, and the daemon logs the closes with escaped text.
#   e2e_websocket_attacks.sh SWEPTCCD SERVICE SHARED_WORLD_TOOL SOURCE_DIR WORK_DIR ATTACK_TOOL
set -euo pipefail
source "$(dirname "$0")/../../tools/netns.sh"
enter_private_netns "$@"
sweptccd=$1 service=$2 tool=$3 work=$5 attack=$6
rm -rf "$work"
mkdir -p "$work"
setup_loopback_multicast
# Every reader of the bus (the daemon, the play's LCM side) gets a 2 MiB
# socket buffer (as e2e_attacks.sh): a reader stopped for a few hundred ms
# (a loaded machine) can otherwise lose what is sent meanwhile past the
# kernel's default (208 KiB).
url="$SWEPTCCD_URL&recv_buf_size=2097152"
port=18766
"$tool" write "$work"
"$sweptccd" world --world "$work/world.json" --output "$work/offline.jsonl"
"$sweptccd" keygen --out "$work/room.key"
# The good client's play is checked exactly, so no admission of its poses
# may depend on scheduling: the play sends in real time beside the attacks,
# and on a loaded 2-core machine (or under the sanitizers) the daemon or the
# player can stall for hundreds of ms and then catch up in a burst. With
# silence_timeout_ms 300 and the default pose limits (240 Hz, burst 16) a
# 450 ms stop of either dropped alice for silence and shed the catch-up
# poses rate_limited ("alice pair 28 against bob never published"). So the
# daemon keeps the default silence timeout (5000 ms) and per-client pose
# limits no burst reaches (pose rate limits are tested in e2e_attacks.sh
# and the service's unit tests). The door's limits are the attacks'
# subject and stay small, but its send queue also holds the good client's
# answers while its reader is stalled: 32 messages / 16 KiB closed alice
# with slow_reader after a 300-600 ms stop of the player or the daemon, so
# the queue holds 1024 messages / 1 MiB (a few seconds of alice's answers);
# never_reads still fills it (its error frames) and is closed slow_reader.
cat > "$work/sweptccd.yaml" <<YAML
lcm_url: "$url"
environment: [floor.obj]
workers: 2
silence_timeout_ms: 5000
max_pose_rate_hz: 1000000
max_object_pose_rate_hz: 1000000
shared_world: true
clients:
  - {id: bob, skeleton: arm.json, ignore_entities: [{link: fore, entity: alice, other_link: 1}]}
  - {id: carol, skeleton: arm.json}
objects:
  - {id: cup, mesh: cube.obj}
security: {room_key: room.key}
websocket:
  listen: "127.0.0.1:$port"
  max_connections: 48
  max_connections_per_address: 4
  handshake_timeout_ms: 1000
  max_message_bytes: 65536
  message_rate_hz: 1000
  message_burst: 100
  send_queue_messages: 1024
  send_queue_bytes: 1048576
  socket_send_buffer_bytes: 8192
YAML
"$service" --config "$work/sweptccd.yaml" 2> "$work/daemon.log" &
daemon=$!
attacker=
trap 'kill -KILL $daemon $attacker 2>/dev/null || true' EXIT
wait_for "$work/daemon.log" ready
"$attack" $port "$work/room.key" 4 1000 65536 > "$work/attack.out" 2>&1 &
attacker=$!
"$tool" --key "$work/room.key" play-ws "$url" $port "$work" "$work/offline.jsonl" \
  | tee "$work/play.out"
status=0
wait $attacker || status=$?
cat "$work/attack.out"
[ "$status" = 0 ]
grep -q "alice over the WebSocket: [1-9][0-9]* contact events" "$work/play.out"
for name in flood slowloris oversized oversized_fragmented fragmented malformed wrong_key rate \
  never_reads; do
  grep -q "^ok $name:" "$work/attack.out"
done
grep -q "closing with slow_reader" "$work/daemon.log"
# Both oversized messages (whole and fragmented) closed by the door for size.
[ "$(grep -c "message over 65536 bytes: closed (1009)" "$work/daemon.log")" -ge 2 ]
grep -q "join of 'mallory' with a wrong proof" "$work/daemon.log"
kill -TERM $daemon
wait $daemon
grep -q stopped "$work/daemon.log"
echo "e2e_websocket_attacks: passed"

#!/usr/bin/env bash
# One room, many doors (docs/WEBSOCKET.md), inside a private network
# namespace this script creates (never the host network): a signed daemon
# holding room arcade-7 with its WebSocket door on 127.0.0.1 and one client
# of its configuration, "walker", with a key of its own.
#  - The C++ client names its room (/ws?room=): a client of another room is
#    refused with 409 before any frame, one clear error; arcade-7's joins.
#  - walker joins through the door with its own key (the room key is
#    bad_proof for it) and streams the bundled walk: every pair equal to
#    `sweptccd query`, the LCM door's session rules and rejection codes; a
#    second instance gets id_in_use while it holds the id, and a new one
#    takes it (a greater session) once it left; the same in unsigned mode
#    (no proofs).
#  - Joint frames: a hand (webxr-hand) streams joint frames through the C++
#    client's PublishJointFrame; every pair equal to `sweptccd query` on
#    `sweptccd skeleton --joints`' conversion of the same frames; an
#    untracked joint and another joint set's frame refused, nothing sent.
#  - The epoch fence: a stale server of arcade-7 (started first: an older
#    instance) answered once by the resolver after the daemon is killed and
#    restarted: its hello is fenced, the restarted daemon joined.
#   e2e_websocket_rooms.sh SWEPTCCD SERVICE WS_ROOM_TOOL SOURCE_DIR WORK_DIR
set -euo pipefail
source "$(dirname "$0")/../../tools/netns.sh"
enter_private_netns "$@"
sweptccd=$1 service=$2 tool=$3 src=$4 work=$5
rm -rf "$work"
mkdir -p "$work"
setup_loopback_multicast
port=18781 stale=18782
import_walk "$sweptccd" "$src" 30 "$work"
env=$src/data/env/morse_apartment.ply.gz
query_walk "$sweptccd" "$env" "$work"
"$sweptccd" keygen --out "$work/room.key"
"$sweptccd" keygen --out "$work/walker.key"
# The stale server of the room: started first, so its instance is older.
"$service" --lcm-url "udpm://239.255.76.68:7668?ttl=0" --env "$env" --room-key "$work/room.key" \
  --room arcade-7 --backend cpu --ws-listen "127.0.0.1:$stale" 2> "$work/stale.log" &
stale_daemon=$!
trap 'kill -KILL $stale_daemon 2>/dev/null || true' EXIT
wait_for "$work/stale.log" ready
sleep 0.01
# Lock-step outruns any tracker: the pose rate limit is raised.
start_daemon() {
  "$service" --lcm-url "$SWEPTCCD_URL" --env "$env" --client "walker=$work/skeleton.json" \
    --client-key "walker=$work/walker.key" --room-key "$work/room.key" --room arcade-7 \
    --backend cpu --max-pose-rate 100000 --ws-listen "127.0.0.1:$port" --log-level info \
    2> "$1" &
  daemon=$!
}
start_daemon "$work/daemon.log"
trap 'kill -KILL $daemon $stale_daemon 2>/dev/null || true' EXIT
wait_for "$work/daemon.log" "websocket door on ws://127.0.0.1:$port"
wait_for "$work/daemon.log" ready
"$tool" rooms $port arcade-7 "$work/room.key" "$work/skeleton.json" | tee "$work/rooms.out"
grep -q "^ok rooms:" "$work/rooms.out"
"$tool" configured $port walker "$work/walker.key" "$work/room.key" "$work/skeleton.json" \
  "$work/poses.jsonl" "$work/expected.jsonl" | tee "$work/configured.out"
grep -q "^ok configured:" "$work/configured.out"
grep -q "'walker' joined, session" "$work/daemon.log"
grep -q "configured client 'walker' joined: session" "$work/daemon.log"
"$tool" joint-frames "$work/hand_frames.jsonl"
"$sweptccd" skeleton --from webxr-hand --out "$work/hand.json" --joints "$work/hand_frames.jsonl" \
  --poses-out "$work/hand_poses.jsonl"
"$sweptccd" query --skeleton "$work/hand.json" --poses "$work/hand_poses.jsonl" --env "$env" \
  --output "$work/hand_expected.jsonl"
"$tool" joints $port "$work/room.key" "$work/hand_frames.jsonl" "$work/hand_expected.jsonl" |
  tee "$work/joints.out"
grep -q "^ok joints:" "$work/joints.out"
# Unsigned mode (a lab bench): the configured client joins without a proof,
# the same rules otherwise.
"$service" --lcm-url "udpm://239.255.76.69:7669?ttl=0" --env "$env" --security-mode unsigned \
  --client "walker=$work/skeleton.json" --room arcade-7 --backend cpu --max-pose-rate 100000 \
  --ws-listen "127.0.0.1:18783" 2> "$work/unsigned.log" &
unsigned_daemon=$!
trap 'kill -KILL $daemon $stale_daemon $unsigned_daemon 2>/dev/null || true' EXIT
wait_for "$work/unsigned.log" ready
"$tool" configured 18783 walker - - "$work/skeleton.json" "$work/poses.jsonl" \
  "$work/expected.jsonl" | tee "$work/unsigned.out"
grep -q "^ok configured: 'walker' over the door (unsigned)" "$work/unsigned.out"
kill -TERM $unsigned_daemon
wait $unsigned_daemon
# The fence: the client joins the daemon, which dies (SIGKILL) and starts
# again; the resolver's stale answer (the older server) is refused.
"$tool" fence $port $stale arcade-7 "$work/room.key" "$work/skeleton.json" > "$work/fence.out" &
client=$!
wait_for "$work/fence.out" "joined instance"
kill -KILL $daemon
wait $daemon || true
start_daemon "$work/daemon2.log"
wait $client || { cat "$work/fence.out"; exit 1; }
cat "$work/fence.out"
grep -q "^ok fence:" "$work/fence.out"
kill -TERM $daemon $stale_daemon
wait $daemon
wait $stale_daemon
grep -q stopped "$work/daemon2.log"
# Nothing raw from the network reached the log.
! grep -q $'\x1b' "$work/daemon.log"
echo "ok: rooms and configured clients through the WebSocket door"

#!/usr/bin/env bash
# The shared world end to end (SPEC 8 "Live"; docs/SERVICE.md "Shared
# world"), over udpm:// inside a private network namespace this script
# creates (never the host network): the daemon with three configured avatars
# (90, 60 and 72 Hz, different phases) and a tracked object (30 Hz), over a
# floor they touch now and then; every environment event and every shared
# entry equal to `sweptccd world` on the same samples, except entries ended
# by the timeout and pairs merged by latest-wins; an object pose for an
# unknown object is one clear rejection and disturbs nothing; then
# `simulate-tracker` plays one stream for both avatars at their own rates and
# phases (--client-rate, --client-phase-us), checked the same way.
#   e2e_shared_world.sh SWEPTCCD SERVICE SHARED_WORLD_TOOL SOURCE_DIR WORK_DIR
set -euo pipefail
source "$(dirname "$0")/../../tools/netns.sh"
enter_private_netns "$@"
sweptccd=$1 service=$2 tool=$3 work=$5
rm -rf "$work"
mkdir -p "$work"
setup_loopback_multicast
# Every reader of the bus (the daemon, the tool, monitor) gets a 2 MiB
# socket buffer (as e2e_attacks.sh): a reader stopped for a few hundred ms
# (a loaded machine) can otherwise lose what is sent meanwhile past the
# kernel's default (208 KiB).
url="$SWEPTCCD_URL&recv_buf_size=2097152"
"$tool" write "$work"
"$sweptccd" world --world "$work/world.json" --output "$work/offline.jsonl"
"$sweptccd" keygen --out "$work/room.key"
# Every play below is checked exactly, so no admission may depend on
# scheduling: the players send in real time, and on a loaded 2-core machine
# (or under the sanitizers) the daemon or a player can stall for hundreds
# of ms and then catch up in a burst, which the default pose limits (240 Hz,
# burst 16) shed rate_limited ("expected exactly one unknown_object
# rejection for 'ghost'"; in the listen phase alice's shed samples changed
# bob's entries against her). So the daemon takes pose limits no burst
# reaches (rate limits are tested in e2e_attacks.sh and the service's unit
# tests) and the default silence timeout (5000 ms): a stall no longer ends
# entries by the timeout mid-play (those are not compared), only the ones
# whose other entity's samples have ended.
cat > "$work/sweptccd.yaml" <<YAML
lcm_url: "$url"
environment: [floor.obj]
workers: 2
silence_timeout_ms: 5000
max_pose_rate_hz: 1000000
max_object_pose_rate_hz: 1000000
shared_world: true
clients:
  - {id: alice, skeleton: arm.json, ignore_entities: [{link: upper, entity: cup}]}
  - {id: bob, skeleton: arm.json, ignore_entities: [{link: fore, entity: alice, other_link: fore}]}
  - {id: carol, skeleton: arm.json}
objects:
  - {id: cup, mesh: cube.obj}
security: {room_key: room.key}
YAML
"$service" --config "$work/sweptccd.yaml" 2> "$work/daemon.log" &
daemon=$!
monitor=
listener=
trap 'kill -KILL $daemon $monitor $listener 2>/dev/null || true' EXIT
wait_for "$work/daemon.log" ready
# `sweptccd monitor` shows the shared entries (verified with the service key).
"$sweptccd" monitor --lcm-url "$url" --key "$work/room.key" --json --all --timeout 60 \
  > "$work/monitor.out" 2> "$work/monitor.err" &
monitor=$!
wait_for "$work/monitor.out" listening
"$tool" --key "$work/room.key" play "$url" "$work" "$work/offline.jsonl"
# `sweptccd simulate-tracker` plays a tracked object too (--object), 10 s
# later on the shared time base, in new sessions: alice's pairs against the
# cup come out of it.
"$sweptccd" simulate-tracker --lcm-url "$url" --key "$work/room.key" --poses "$work/alice.jsonl" \
  --client alice --object "cup=$work/cup.jsonl" --utime-start 10000000 --speed 2 \
  > "$work/simulate.out"
grep -q "^simulate-tracker: $(grep -c . "$work/cup.jsonl") object poses sent, 0 object line" \
  "$work/simulate.out"
wait_for "$work/monitor.out" '"type":"shared_[a-z]*","client":"alice".*"entity":"cup".*"window":\[11'
kill -INT $monitor
wait $monitor
grep -q '"type":"shared_contact".*"entity":"cup".*"entity_kind":"object"' "$work/monitor.out"
grep -q '"type":"shared_contact".*"entity":"bob".*"entity_kind":"client"' "$work/monitor.out"
! grep '"type":"shared' "$work/monitor.out" | grep -q '"verified":false'
# The shared world's counters of status_t: entries answered in messages, and
# the one refused object pose (the ghost, below).
grep -q '"type":"service".*"shared_messages":[1-9][0-9]*,"shared_entries":[1-9]' \
  "$work/monitor.out"
grep -q '"type":"service".*"object_poses_received":[1-9][0-9]*,"object_poses_rejected":1,' \
  "$work/monitor.out"
# The only rejection of the whole run: the unknown object.
[ "$(grep -c '"type":"reject"' "$work/monitor.out")" = 1 ]
grep -q '"type":"reject".*"client":"ghost".*unknown_object' "$work/monitor.out"
# simulate-tracker's own rates and phases (--client-rate, --client-phase-us):
# one 360 Hz stream played for alice at 90 Hz and for bob at 60 Hz 5 ms
# later (and 0.25 m away), in new sessions; every shared entry equal to
# `sweptccd world` on the samples it sends (shared_world_tool computes them
# from the stream: DIR/sim_world.json), and no rejection.
"$sweptccd" world --world "$work/sim_world.json" --output "$work/sim_offline.jsonl"
"$tool" --key "$work/room.key" listen "$url" "$work" "$work/sim_offline.jsonl" \
  > "$work/listen.out" &
listener=$!
wait_for "$work/listen.out" listening
"$sweptccd" simulate-tracker --lcm-url "$url" --key "$work/room.key" --poses "$work/stream.jsonl" \
  --client alice --client bob --spacing 0.25 0.05 0 --client-rate alice=90 --client-rate bob=60 \
  --client-phase-us bob=5000 > "$work/simulate_rates.out"
sent=$(($(grep -c . "$work/sim_alice.jsonl") + $(grep -c . "$work/sim_bob.jsonl")))
grep -q "^simulate-tracker: sent $sent, " "$work/simulate_rates.out"
wait $listener || { cat "$work/listen.out"; exit 1; }
cat "$work/listen.out"
kill -TERM $daemon
wait $daemon
grep -q stopped "$work/daemon.log"
grep -q "unknown_object" "$work/daemon.log"
# Per-link mode (query.per_link): a second daemon, the same world played
# again; every entry's per-link brackets equal `sweptccd world --per-link`.
"$sweptccd" world --world "$work/world.json" --per-link --output "$work/offline_links.jsonl"
sed 's/^shared_world: true$/shared_world: true\nquery: {per_link: true}/' "$work/sweptccd.yaml" \
  > "$work/sweptccd_links.yaml"
grep -q "per_link: true" "$work/sweptccd_links.yaml"
"$service" --config "$work/sweptccd_links.yaml" 2> "$work/daemon_links.log" &
daemon=$!
wait_for "$work/daemon_links.log" ready
"$tool" --key "$work/room.key" play "$url" "$work" "$work/offline_links.jsonl" \
  | tee "$work/play_links.out"
grep -q "per-link brackets" "$work/play_links.out"
kill -TERM $daemon
wait $daemon
# Renamed channels (config `channels`): simulate-tracker --object-channel
# and monitor --shared-channel follow them. The monitor prints plain text
# here (`shared contact|free CLIENT pair ... with object ID window ...`).
sed 's/^shared_world: true$/shared_world: true\nchannels: {object_pose: ROOM2_OBJECTS, shared_contact: ROOM2_SHARED}/' \
  "$work/sweptccd.yaml" > "$work/sweptccd_renamed.yaml"
grep -q "ROOM2_OBJECTS" "$work/sweptccd_renamed.yaml"
"$service" --config "$work/sweptccd_renamed.yaml" 2> "$work/daemon_renamed.log" &
daemon=$!
wait_for "$work/daemon_renamed.log" ready
"$sweptccd" monitor --lcm-url "$url" --key "$work/room.key" --all --timeout 60 \
  --shared-channel ROOM2_SHARED > "$work/monitor_renamed.out" 2> "$work/monitor_renamed.err" &
monitor=$!
wait_for "$work/monitor_renamed.out" listening
grep -q "^monitor: listening on .*, shared ROOM2_SHARED)" "$work/monitor_renamed.out"
"$sweptccd" simulate-tracker --lcm-url "$url" --key "$work/room.key" --poses "$work/alice.jsonl" \
  --client alice --object "cup=$work/cup.jsonl" --object-channel ROOM2_OBJECTS --speed 2 \
  > "$work/simulate_renamed.out"
grep -q "^simulate-tracker: $(grep -c . "$work/cup.jsonl") object poses sent, 0 object line" \
  "$work/simulate_renamed.out"
wait_for "$work/monitor_renamed.out" \
  "^shared contact alice pair [0-9]* seq [0-9]*-[0-9]* with object cup window"
kill -INT $monitor
wait $monitor
grep -q "^shared free alice pair [0-9]* seq [0-9]*-[0-9]* with object cup window" \
  "$work/monitor_renamed.out"
! grep -q "^reject\|UNVERIFIED" "$work/monitor_renamed.out"
kill -TERM $daemon
wait $daemon
echo "e2e_shared_world: passed"

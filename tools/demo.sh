#!/usr/bin/env bash
# The demo (the README's main command): the collision daemon on a real
# furnished apartment (MORSE, bundled), fed a real motion-capture walk (CMU
# 02_01, bundled) replayed at its real 30 Hz over LCM by `sweptccd
# simulate-tracker`; `sweptccd monitor` prints the contact events as they
# come; then `sweptccd render` draws the first contact. LCM runs over
# udpm:// on the loopback of a private network namespace this script creates
# (unshare), so the host's network is neither needed nor touched.
#   SWEPTCCD_BUILD: build folder (default build); DEMO_OUT: output folder
#   (default $SWEPTCCD_BUILD/demo).
set -euo pipefail
source "$(dirname "$0")/netns.sh"
enter_private_netns "$@"
cd "$(dirname "$0")/.."
build=${SWEPTCCD_BUILD:-build}
bin=$build/bin
out=${DEMO_OUT:-$build/demo}
mkdir -p "$out"
setup_loopback_multicast
url=$SWEPTCCD_URL
scene=data/env/morse_apartment.ply.gz

# The apartment is Z-up; walk 1 m off the clip's origin, where it meets a
# table, and 2 cm up (the clip's soles otherwise dip 3 mm into the floor, and
# the first contact would be a foot on the floor at the start).
"$bin/sweptccd" import-bvh --bvh data/mocap/cmu_02_01_walk.bvh.gz --up z --rate 30 \
  --offset 0 -1 0.02 --utime-start 1000000 --skeleton-out "$out/walk_skeleton.json" \
  --poses-out "$out/walk_poses.jsonl" 2> "$out/import.log"

# Signed messages: one room key (mode 600) shared by daemon, tracker and monitor.
rm -f "$out/room.key"
"$bin/sweptccd" keygen --out "$out/room.key"
"$bin/sweptccd-service" --lcm-url "$url" --env "$scene" --backend auto \
  --client "walker=$out/walk_skeleton.json" --room-key "$out/room.key" --log-level info \
  2> "$out/daemon.log" &
daemon=$!
monitor=
trap 'kill -KILL $daemon $monitor 2>/dev/null || true' EXIT
wait_for "$out/daemon.log" ready
echo "== daemon ready: $(grep -o 'backend .*' "$out/daemon.log" | head -1 || echo 'backend cpu')"

# The monitor prints each contact event as it arrives (and a summary at the end).
# (Output through tee in a process substitution, so that $! is the monitor.)
"$bin/sweptccd" monitor --lcm-url "$url" --skeleton "$out/walk_skeleton.json" --timeout 60 \
  --key "$out/room.key" \
  > >(tee "$out/monitor.log") &
monitor=$!
wait_for "$out/monitor.log" listening
echo "== replaying the walk at 30 Hz (86 samples, about 3 s) =="
"$bin/sweptccd" simulate-tracker --lcm-url "$url" --poses "$out/walk_poses.jsonl" \
  --skeleton "$out/walk_skeleton.json" --client walker --key "$out/room.key"
# Let the last answers arrive (each takes well under a millisecond), then stop
# the monitor (it prints its summary) and the daemon (it drains and exits).
sleep 1
kill -INT "$monitor"
wait "$monitor" || true
kill -TERM "$daemon"
wait "$daemon"

echo "== drawing the first contact =="
"$bin/sweptccd" render --skeleton "$out/walk_skeleton.json" --poses "$out/walk_poses.jsonl" \
  --env "$scene" --up z --out "$out/first_contact.png" --info-out "$out/first_contact.json" \
  --timeline "$out/timeline.png"
contacts=$(grep -c '^contact' "$out/monitor.log" || true)
echo "== $contacts contact events; picture of the first contact: $out/first_contact.png," \
  "timeline of the walk: $out/timeline.png; daemon log: $out/daemon.log =="
[ "$contacts" -gt 0 ]

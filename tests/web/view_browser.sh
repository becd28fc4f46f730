#!/usr/bin/env bash
# The live view in Debian's headless Chromium against the real daemon, in a
# private network namespace this script creates (never the host network):
# view_browser.mjs (see its header). Screenshots stay in WORK_DIR.
#   view_browser.sh SWEPTCCD SERVICE NODE SOURCE_DIR WORK_DIR JS_DIR VIEW_DIR
set -euo pipefail
source "$(dirname "$0")/../../tools/netns.sh"
enter_private_netns "$@"
sweptccd=$1 service=$2 node=$3 src=$4 work=$5 js=$6 view=$7
rm -rf "$work"; mkdir -p "$work"
setup_loopback_multicast
fail() { echo "view_browser: FAILED: $*" >&2; exit 1; }
[ -x /usr/bin/chromium ] || fail "no /usr/bin/chromium (Debian package chromium, deploy/debian-packages.txt)"
[ -f "$view/index.html" ] || fail "no live view in $view (build target sweptccd-js-view)"
import_walk "$sweptccd" "$src" 30 "$work"
query_walk "$sweptccd" "$src/data/env/morse_apartment.ply.gz" "$work"
"$sweptccd" import-bvh --bvh "$src/data/mocap/cmu_02_01_walk.bvh.gz" --up z --rate 90 --offset 0 -1 0 \
  --utime-start 1000000 --skeleton-out "$work/skeleton90.json" --poses-out "$work/poses90.jsonl"
"$sweptccd" keygen --out "$work/room.key"
# A tracked object (a 0.3 m cube) for the shared world, configured in YAML.
cat > "$work/box.obj" <<OBJ
v -0.15 -0.15 -0.15
v 0.15 -0.15 -0.15
v 0.15 0.15 -0.15
v -0.15 0.15 -0.15
v -0.15 -0.15 0.15
v 0.15 -0.15 0.15
v 0.15 0.15 0.15
v -0.15 0.15 0.15
f 1 3 2
f 1 4 3
f 5 6 7
f 5 7 8
f 1 2 6
f 1 6 5
f 2 3 7
f 2 7 6
f 3 4 8
f 3 8 7
f 4 1 5
f 4 5 8
OBJ
cat > "$work/sweptccd.yaml" <<YAML
shared_world: true
objects:
  - {id: box, mesh: box.obj}
security: {room_key: room.key}
YAML
# Two rooms: the avatars' (environment only), and a shared world with the box
# (its own daemon on another port and LCM channel set).
port=7702 port2=7703
"$service" --lcm-url "$SWEPTCCD_URL" --env "$src/data/env/morse_apartment.ply.gz" \
  --room-key "$work/room.key" --max-live-clients 20 --status-period 0.25 \
  --ws-listen "127.0.0.1:$port" --ws-view-dir "$view" --ws-max-connections-per-address 32 --log-level info 2> "$work/daemon.log" &
daemon=$!
"$service" --config "$work/sweptccd.yaml" --lcm-url "udpm://239.255.76.68:7668?ttl=0" \
  --env "$src/data/env/morse_apartment.ply.gz" --ws-listen "127.0.0.1:$port2" --ws-view-dir "$view" \
  --log-level info 2> "$work/daemon2.log" &
daemon2=$!
trap 'kill -KILL $daemon $daemon2 2>/dev/null || true' EXIT
wait_for "$work/daemon.log" ready || { cat "$work/daemon.log" >&2; fail "no daemon"; }
wait_for "$work/daemon2.log" ready || { cat "$work/daemon2.log" >&2; fail "no shared-world daemon"; }
SWEPTCCD_BIN=$sweptccd SWEPTCCD_LCM_URL=$SWEPTCCD_URL SWEPTCCD_JS_DIR=$js HOME=$work "$node" "$(dirname "$0")/view_browser.mjs" "http://127.0.0.1:$port" \
  "$work/room.key" "$work/skeleton.json" "$work/poses.jsonl" "$work/expected.jsonl" "$work/poses90.jsonl" "$work" \
  "http://127.0.0.1:$port2" \
  || { tail -n 20 "$work/daemon.log" "$work/daemon2.log" >&2; fail "view_browser.mjs (screenshots in $work)"; }
kill -TERM $daemon $daemon2
wait $daemon || true
wait $daemon2 || true
echo "view_browser: passed"

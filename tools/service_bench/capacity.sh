#!/usr/bin/env bash
# Rooms per host (docs/BENCHMARKS.md "Capacity", docs/DEPLOY.md): N rooms on
# this host at once, each a sweptccd-service (CPU backend, 1 worker, signed,
# the WebSocket door on its own loopback) in its own network namespace (its
# LCM bus on its loopback, never the host network), each under the same
# fixed load: CLIENTS live LCM clients at HZ on the bundled walk
# (sweptccd_ws_latency, the latency bench's client), all rooms at the same
# time. Per room: RSS (VmRSS after the load, VmHWM the peak) and the
# pose-to-event p99 of its clients. Two tables:
#  1. memory per room for each scene, one room at a time (SCENES);
#  2. N = ROOMS (default "1 2 4 8") rooms at once, for each of SCALE_SCENES
#     (default: the apartment and the 1.1 M-triangle room).
# Every step has a deadline (a room not ready in READY_S is killed and its
# row says so); the whole run stops itself (about 5 min with the defaults on 2 cores).
#   bash tools/service_bench/capacity.sh [BUILD_DIR]   (default build)
# ROOMS, CLIENTS (2), HZ (90), SECONDS_PER_RUN (8; the walk holds 343 poses,
# 3.8 s at 90 Hz, so runs are at most that long), READY_S (150), SCENES
# (names below; "" skips table 1), SCALE_SCENES ("" skips table 2),
# P99_BOUND_US (20000), BACKEND (cpu; gpu on a GPU host: tools/gpu_bundle.sh). A room is ready at its "ready:" log line (scene
# loaded, backend calibrated, door built); the load starts when every room
# is ready or the deadline passed.
set -euo pipefail
source "$(dirname "$0")/../netns.sh"
enter_private_hosts_ns "$@"  # Each room's namespace is a named one (ip netns add).
cd "$(dirname "$0")/../.."
src=$(pwd)
build=$(cd "${1:-build}" && pwd)
work=$build/capacity_bench
rm -rf "$work" && mkdir -p "$work"
clients=${CLIENTS:-2} hz=${HZ:-90} secs=${SECONDS_PER_RUN:-8} ready_s=${READY_S:-150}
bound=${P99_BOUND_US:-20000}
backend=${BACKEND:-cpu}
d=$src/data/env
declare -A scene_files=(
  [apartment]="$d/morse_apartment.ply.gz"
  [bunny]="$d/stanford_bunny.obj.gz"
  [dragon_res4]="$d/stanford_dragon_vrip_res4.ply.gz"
  [dragon]="$d/stanford_dragon_vrip.ply.gz"
  [grey_white_room]="$d/bitterli_grey_white_room.ply.gz"
  [breakfast_room]="$d/bitterli_breakfast_room.ply.gz"
  [breakfast+dragon_1.1M]="$d/bitterli_breakfast_room.ply.gz $d/stanford_dragon_vrip.ply.gz"
)
scenes=${SCENES-apartment bunny dragon grey_white_room breakfast_room breakfast+dragon_1.1M}
tag=sccdcap$$
pids=() nets=()
cleanup() {
  for p in "${pids[@]}"; do kill -KILL "$p" 2> /dev/null || true; done
  for n in "${nets[@]}"; do ip netns del "$n" 2> /dev/null || true; done
}
trap cleanup EXIT
"$build/bin/sweptccd" keygen --out "$work/room.key"
import_walk "$build/bin/sweptccd" . "$hz" "$work" > /dev/null
url=$SWEPTCCD_URL
mib() { awk -v k="$1:" '$1 == k {printf "%.0f", $2 / 1024}' "/proc/$2/status"; }

# run_rooms SCENE N: N rooms of SCENE at once; one line per room in
# $work/rooms.txt: "room ready_s rss_mib hwm_mib | table row of its clients".
run_rooms() {
  local scene=$1 n=$2 i env="" f
  for f in ${scene_files[$1]}; do env="$env --env $f"; done
  local dpids=() t0
  : > "$work/rooms.txt"
  t0=$(date +%s.%N)
  for i in $(seq "$n"); do
    local ns=$tag$i
    ip netns add "$ns" && nets+=("$ns")
    ip -n "$ns" link set lo up
    ip -n "$ns" route add 224.0.0.0/4 dev lo
    # shellcheck disable=SC2086
    ip netns exec "$ns" "$build/bin/sweptccd-service" --lcm-url "$url" $env --backend "$backend" \
      --workers 1 --room-key "$work/room.key" --log-level info --max-live-clients 16 \
      --ws-listen 127.0.0.1:8765 2> "$work/daemon_$i.log" &
    dpids+=($!) && pids+=($!)
  done
  local ready=() deadline=$(($(date +%s) + ready_s))
  for i in $(seq "$n"); do
    while ! grep -q '\] ready:' "$work/daemon_$i.log" && [ "$(date +%s)" -lt "$deadline" ]; do
      sleep 0.1
    done
    if grep -q '\] ready:' "$work/daemon_$i.log"; then
      ready+=("$(awk -v a="$(date +%s.%N)" -v b="$t0" 'BEGIN { printf "%.2f", a - b }')")
    else
      ready+=(none)
    fi
  done
  # The load: every room's clients at once, each run bounded by `timeout`.
  local cpids=()
  for i in $(seq "$n"); do
    timeout $((secs + 30)) ip netns exec "$tag$i" "$build/bin/sweptccd_ws_latency" lcm "$url" \
      "$work/skeleton.json" "$work/poses.jsonl" "$clients" "$hz" "$secs" "$work/room.key" \
      > "$work/clients_$i.txt" 2> "$work/clients_$i.err" &
    cpids+=($!)
  done
  for p in "${cpids[@]}"; do wait "$p" || true; done
  for i in $(seq "$n"); do
    local p=${dpids[$((i - 1))]} row
    row=$(grep '^| ' "$work/clients_$i.txt" | tail -1 || true)
    echo "$i ${ready[$((i - 1))]} $(mib VmRSS "$p") $(mib VmHWM "$p") ${row:-| no answer: $(head -c 200 "$work/clients_$i.err" | tr '\n' ' ')}" \
      >> "$work/rooms.txt"
  done
  for p in "${dpids[@]}"; do kill -TERM "$p" 2> /dev/null || true; done
  for p in "${dpids[@]}"; do timeout 10 tail --pid="$p" -f /dev/null || kill -KILL "$p" 2> /dev/null || true; done
  for i in $(seq "$n"); do ip netns del "$tag$i" 2> /dev/null || true; done
  nets=()
}

# A client row "| door | clients | Hz | poses sent | events | p50 | p99 | max |
# intervals |" split on '|': poses field 5, p99 field 8, intervals field 10
# (the pose intervals its events cover: poses - clients when every pose was
# answered once, whether or not latest-wins merged pairs under load).
field() { awk -F'|' -v c="$1" '{gsub(/ /, "", $c); print $c}'; }

echo "Per-room memory by scene: 1 room, $clients clients x $hz Hz for $secs s, $backend backend, 1 worker, door on"
echo
echo
[ -n "$scenes" ] && echo "| scene | triangles | start to ready s | RSS MiB | peak RSS MiB | pose intervals answered / poses | p99 us |"
[ -n "$scenes" ] && echo "|---|---:|---:|---:|---:|---:|---:|"
for s in $scenes; do
  run_rooms "$s" 1
  read -r _ rdy rss hwm row < "$work/rooms.txt"
  tris=$(sed -n 's/.*environment: [0-9]* objects, \([0-9]*\) triangles.*/\1/p' "$work/daemon_1.log")
  echo "| $s | ${tris:-?} | $rdy | $rss | $hwm | $(echo "$row" | field 10) / $(echo "$row" | field 5) | $(echo "$row" | field 8) |"
done
echo
echo "Rooms at once: each $clients clients x $hz Hz for $secs s, $backend backend, 1 worker each, door on; p99 bound $bound us"
echo
scales=${SCALE_SCENES-apartment breakfast+dragon_1.1M}
[ -n "$scales" ] && echo "| scene | rooms | RSS MiB per room (median / max) | start to ready s (max) | pose intervals answered / poses per room (min) | p99 us per room (median / max) | p99 <= bound in every room |"
[ -n "$scales" ] && echo "|---|---:|---:|---:|---:|---:|---|"
for scale in $scales; do
 for n in ${ROOMS:-1 2 4 8}; do
  run_rooms "$scale" "$n"
  rss=$(awk '{print $3}' "$work/rooms.txt" | sort -n)
  rdy=$(awk '$2 != "none" {print $2}' "$work/rooms.txt" | sort -g | tail -1)
  late=$(awk '$2 == "none"' "$work/rooms.txt" | wc -l)
  [ "$late" = 0 ] || rdy="${rdy:--}; $late not ready in $ready_s s"
  ev=$(while read -r _ _ _ _ row; do echo "$(echo "$row" | field 10) / $(echo "$row" | field 5)"; done < "$work/rooms.txt" | sort -n)
  p99=$(while read -r _ _ _ _ row; do echo "$row" | field 8; done < "$work/rooms.txt" | sort -n)
  med() { sed -n "$((($(wc -l <<< "$1") + 1) / 2))p" <<< "$1"; }
  ok=yes
  for v in $p99; do
    if ! [[ $v =~ ^[0-9]+$ ]] || [ "$v" -gt "$bound" ]; then ok=no; fi
  done
  echo "| $scale | $n | $(med "$rss") / $(tail -1 <<< "$rss") | $rdy | $(head -1 <<< "$ev") | $(med "$p99") / $(tail -1 <<< "$p99") | $ok |"
 done
done

#!/usr/bin/env bash
# tools/service_bench/capacity.sh at a tiny size: the apartment alone, then
# 1 and 2 rooms at once, 2 clients x 90 Hz for 2 s each: every table row
# is there, every room reports its memory, was ready before its load and
# answered every pose that has a sweep once (the pose intervals its events
# cover = poses - clients: a pair merged by latest-wins under load covers
# several, so the count holds on a loaded machine; a lost or repeated pair
# breaks it). Counts only, never times.
#   capacity_bench_test.sh SOURCE_DIR BUILD_DIR
set -euo pipefail
src=$1
build=$2
out=$(SCENES=apartment SCALE_SCENES=apartment ROOMS="1 2" SECONDS_PER_RUN=2 READY_S=30 \
  bash "$src/tools/service_bench/capacity.sh" "$build" 2>&1) || {
  echo "$out"
  exit 1
}
echo "$out"
fail() { echo "FAIL: $*"; exit 1; }
# | apartment | TRIANGLES | READY | RSS | PEAK | INTERVALS / POSES | P99 |
row=$(grep -E '^\| apartment \| [0-9]+ \| ' <<< "$out") || fail "no memory row"
read -r rss events poses < <(awk -F'|' '{split($7, e, "/"); print $5 + 0, e[1] + 0, e[2] + 0}' <<< "$row")
[ "$rss" -gt 0 ] || fail "no RSS in: $row"
[ "$poses" -gt 2 ] && [ "$events" = $((poses - 2)) ] || fail "not every pose answered: $row"
for n in 1 2; do
  # | apartment | N | RSS med / max | READY | INTERVALS / POSES (min) | P99 med / max | OK |
  row=$(grep -E "^\| apartment \| $n \| " <<< "$out") || fail "no row for $n rooms"
  grep -q 'not ready' <<< "$row" && fail "a room not ready: $row"
  read -r events poses < <(awk -F'|' '{split($6, e, "/"); print e[1] + 0, e[2] + 0}' <<< "$row")
  [ "$poses" -gt 2 ] && [ "$events" = $((poses - 2)) ] || fail "$n rooms: not every pose answered: $row"
done
[ "$(wc -l < "$build/capacity_bench/rooms.txt")" = 2 ] || fail "the last run had not 2 rooms"
echo "OK: memory row and 1, 2 rooms, every pose answered"

#!/usr/bin/env bash
# The daemon on the CPU backend, then on the GPU backend, same load, one run
# (issue 30), inside a private network namespace (never the host network):
# CLIENTS simulated clients at RATE Hz in a bench scene written by `sweptccd
# bench --write-scene` (default the 1.1 M-triangle breakfast+dragon room),
# each on a grid 0.5 m apart at its own point of the CMU walk, WORKERS worker
# threads (the GPU backend's workers share its dispatches through the
# CullCombiner). One table: pose publication -> contact event latency
# (median, p99, max), and the pairs merged by latest-wins, per backend; with
# SHARED=true the shared world is on and its part (avatar against avatar,
# from the covering sample) has its own row. Last, the answers of the pairs
# both runs answered, compared pair by pair, each backend against the
# first: "differ" must be 0.
#   bash tools/service_bench/backends.sh [BUILD_DIR] [SECONDS]   (default build 10)
# CLIENTS (64), RATE (120), WORKERS (default the number of cores), SHARED
# (false), SCENE (breakfast+dragon_1.1M; any `sweptccd bench --scene` name),
# BACKENDS ("cpu gpu"; "gpu-descent": the GPU backend with device_descent
# on, docs/SERVICE.md "The device descent", batches of DESCENT_MAX_BATCH
# (16) pairs, gather window DESCENT_GATHER_US (0) us), REQUIRE_HARDWARE=1
# (GPU host: refuse llvmpipe),
# PHASES (burst|spread, latency_bench --phases), WORK (the work folder,
# default BUILD_DIR/service_bench_backends). The issue's sizes: 64 x 120
# Hz, shared off; 32 clients, shared on (RATE=90 as shared_world.sh).
# Each row is printed when its run ends, so a run cut short by `timeout`
# still leaves the rows done. "merged" is the daemon's own count (its last
# status_t per client, as `sweptccd monitor` shows it): pairs skipped by
# latest-wins, of the pairs it received (answered + merged). A pair that
# the daemon merged is not a miss: the next pair covers its time (SERVICE.md).
set -euo pipefail
source "$(dirname "$0")/../netns.sh"
enter_private_netns "$@"
cd "$(dirname "$0")/../.."
build=${1:-build}
seconds=${2:-10}
clients=${CLIENTS:-64}
rate=${RATE:-120}
workers=${WORKERS:-$(nproc)}
shared=${SHARED:-false}
scene=${SCENE:-breakfast+dragon_1.1M}
work=${WORK:-$(cd "$build" && pwd)/service_bench_backends}
rm -rf "$work"
mkdir -p "$work"
setup_loopback_multicast
url=$SWEPTCCD_URL
s=$SECONDS
"$build/bin/sweptccd" bench --scene "$scene" --write-scene "$work/scene.ply" --gpu off > /dev/null
echo "scene $scene written in $((SECONDS - s)) s; $clients clients at $rate Hz for $seconds s," \
  "$workers workers, shared world $shared, load before $(cut -d' ' -f1-3 /proc/loadavg)"
# The bundled CMU walk, y up, placed by the bench in the breakfast room (as
# shared_world.sh): its root path centred on (x -0.67, z -1.9), floor y -1.42.
"$build/bin/sweptccd" import-bvh --bvh data/mocap/cmu_02_01_walk.bvh.gz --up y --rate "$rate" \
  --utime-start 1000000 --skeleton-out "$work/skeleton.json" --poses-out "$work/poses.jsonl" \
  > /dev/null
"$build/bin/sweptccd" keygen --out "$work/room.key"
placement=(--room -1.35 -0.67 -1.9 --grid 8 0.5 --stagger)
if [ -n "${PHASES:-}" ]; then placement+=(--phases "$PHASES"); fi
if [ "$shared" = true ]; then placement+=(--shared); fi

daemon=
monitor=
trap 'kill -KILL $daemon $monitor 2>/dev/null || true' EXIT
echo
echo "| backend | part | events | median us | p99 us | max us | pairs received | merged |"
echo "|---|---|---:|---:|---:|---:|---:|---:|"
notes=()
for backend in ${BACKENDS:-cpu gpu}; do
  {
    echo "lcm_url: \"$url\""
    echo "environment: [$work/scene.ply]"
    echo "workers: $workers"
    echo "backend: ${backend%-descent}"
    if [ "$backend" = gpu-descent ]; then
      echo "device_descent: true"
      echo "descent_max_batch: ${DESCENT_MAX_BATCH:-16}"
      echo "descent_gather_us: ${DESCENT_GATHER_US:-0}"
    fi
    if [ "${REQUIRE_HARDWARE:-}" = 1 ]; then echo "require_hardware: true"; fi
    echo "log_level: info"
    echo "shared_world: $shared"
    echo "security: {room_key: room.key}"
    echo "clients:"
    for c in $(seq 0 $((clients - 1))); do echo "  - {id: client$c, skeleton: skeleton.json}"; done
  } > "$work/sweptccd_$backend.yaml"
  "$build/bin/sweptccd-service" --config "$work/sweptccd_$backend.yaml" \
    2> "$work/daemon_$backend.log" &
  daemon=$!
  # The dragon's BVH (and the GPU's upload) take seconds on a loaded machine.
  for _ in $(seq 600); do grep -qs ready "$work/daemon_$backend.log" && break; sleep 0.1; done
  grep -q ready "$work/daemon_$backend.log" || { cat "$work/daemon_$backend.log" >&2; exit 1; }
  sleep 0.5
  timeout $((seconds + 40)) "$build/bin/sweptccd" monitor --lcm-url "$url" \
    --key "$work/room.key" --json --timeout $((seconds + 35)) > "$work/monitor_$backend.jsonl" \
    2> /dev/null &
  monitor=$!
  timeout $((seconds + 30)) "$build/bin/sweptccd_latency_bench" "$url" "$work/poses.jsonl" \
    "$clients" "$rate" "$seconds" "$work/room.key" "${placement[@]}" --label "env part" \
    --answers-out "$work/answers_$backend.txt" \
    > "$work/bench_$backend.out" 2> "$work/bench_$backend.err" || true
  sleep 1.5  # A status period, so the monitor has the daemon's last counts.
  kill -TERM $daemon
  wait $daemon || true
  daemon=
  kill -TERM $monitor 2> /dev/null || true
  wait $monitor || true
  monitor=
  # The daemon's counts: last status_t per client, summed.
  read -r received merged < <(grep '^{"type":"status","client":' "$work/monitor_$backend.jsonl" |
    awk -F'[:,]' '{ for (i = 1; i < NF; ++i) { if ($i == "\"client\"") c = $(i + 1);
        if ($i == "\"pairs_answered\"") a[c] = $(i + 1); if ($i == "\"pairs_skipped\"") k[c] = $(i + 1) } }
      END { for (c in a) { A += a[c]; K += k[c] } print A + K, K }')
  merged_cell=$(awk -v r="$received" -v m="$merged" 'BEGIN {
    if (r > 0) printf "%d (%.1f%%)", m, 100 * m / r; else print "-" }')
  # The row says the backend the daemon ran on: a GPU it could not open
  # (require_hardware on llvmpipe, no driver) leaves it on the CPU.
  ran=$(grep -o 'backend [a-z]*' "$work/daemon_$backend.log" | head -1 | cut -d' ' -f2)
  if [ "$backend" = gpu-descent ] && [ "$ran" = gpu ] &&
    grep -q 'device descent on' "$work/daemon_$backend.log"; then
    ran=gpu-descent
  fi
  label=$backend
  if [ "$ran" != "$backend" ]; then label="$backend requested, ran ${ran:-?}"; fi
  # Non-shared rows: | clients | Hz | sent | events | median | p99 | max |;
  # shared rows: | label | messages | median | p99 | max |.
  if [ "$shared" = true ]; then
    grep '^| ' "$work/bench_$backend.out" | while IFS='|' read -r _ part n med p99 max _; do
      echo "| $label |$part|$n|$med|$p99|$max| $received | $merged_cell |"
    done
  else
    grep '^| ' "$work/bench_$backend.out" | while IFS='|' read -r _ _ _ _ n med p99 max _; do
      echo "| $label | env part |$n|$med|$p99|$max| $received | $merged_cell |"
    done
  fi
  grep -q '^| ' "$work/bench_$backend.out" ||
    echo "| $label | (no result: $(tail -1 "$work/bench_$backend.err")) | | | | | | |"
  notes+=("$backend: $(grep -o 'backend .*' "$work/daemon_$backend.log" | head -1)")
  if [ "$shared" = true ]; then
    notes+=("$backend: $(grep -E '^shared entries:' "$work/bench_$backend.out" | head -1)")
  fi
  d=$(grep -E 'dispatch' "$work/daemon_$backend.log" | tail -1 || true)
  if [ -n "$d" ]; then notes+=("$backend: $d"); fi
done
echo
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
for n in "${notes[@]}"; do echo "$n"; done
# The answers, pair by pair, where both runs answered the same pair (same
# client, seq0 and seq1: latest-wins merges different pairs under different
# timing): result, flags and the certified bracket must be equal.
set -- ${BACKENDS:-cpu gpu}
first=$1
shift
for other in "$@"; do
  if [ -s "$work/answers_$first.txt" ] && [ -s "$work/answers_$other.txt" ]; then
    awk -v a="$first" -v b="$other" 'NR == FNR { k = $1 " " $2 " " $3; v[k] = $0; next }
      { k = $1 " " $2 " " $3; if (k in v) { ++common; if (v[k] != $0) ++differ } }
      END { printf "answers %s against %s: %d pairs answered by both, differ %d (must be 0)\n",
            b, a, common, differ }' "$work/answers_$first.txt" "$work/answers_$other.txt"
  fi
done

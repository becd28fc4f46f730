#!/usr/bin/env bash
# Compares two builds' query paths by what the CPU is asked to do, not by the
# clock: valgrind's callgrind counts the instructions executed (Ir) and
# simulates the caches and branch predictors (D1 and last-level misses,
# conditional and indirect mispredicts) while inside the answering functions
# only (--toggle-collect), on the same input for both builds. The counts do
# not depend on the machine's load, so two builds can be compared on a
# shared machine where wall-clock medians move by several per cent between
# runs (docs/BENCHMARKS.md, "issue 28's speed check").
#
#   tools/bench_callgrind.sh OLD_SWEPTCCD NEW_SWEPTCCD [DATA_DIR]
#
# Two workloads: `bench` (the environment query, CcdEngine::Query; 120 pairs
# per clip at 15 Hz in two scenes) and `world-bench` (the shared world,
# WorldAnswerer::Answer*; 8 avatars, 1 s). Prints one markdown table.
# About 3 minutes on one core.
set -euo pipefail
old=$1 new=$2
data=${3:-$(cd "$(dirname "$0")/.." && pwd)/../shared/data}
command -v valgrind >/dev/null || { echo "bench_callgrind.sh: needs valgrind (apt-get install valgrind)" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# totals FILE: the PROGRAM TOTALS row of a callgrind output, as numbers.
totals() {
  callgrind_annotate "$1" | awk '/PROGRAM TOTALS/ {
    n = 0; for (i = 1; i <= NF; ++i) if ($i ~ /^[0-9,]+$/) { v = $i; gsub(",", "", v); f[++n] = v }
    # Ir Dr Dw I1mr D1mr D1mw ILmr DLmr DLmw Bc Bcm Bi Bim
    printf "%s %s %s %s %s\n", f[1], f[5] + f[6], f[8] + f[9], f[11], f[13] }'
}

run() {  # run NAME BINARY TOGGLE ARGS...
  local name=$1 bin=$2 toggle=$3
  shift 3
  valgrind --tool=callgrind --cache-sim=yes --branch-sim=yes "--toggle-collect=$toggle" \
    --callgrind-out-file="$work/$name.out" "$bin" "$@" >"$work/$name.log" 2>&1
  totals "$work/$name.out"
}

echo "| workload | build | instructions | D1 misses | LL misses | cond. mispredicts | ind. mispredicts |"
echo "|---|---|---:|---:|---:|---:|---:|"
for workload in bench world-bench; do
  declare -A row=()
  for build in old new; do
    bin=$old
    [ "$build" = new ] && bin=$new
    if [ "$workload" = bench ]; then
      row[$build]=$(run "$workload-$build" "$bin" 'sweptccd::CcdEngine::Query*' bench --data "$data" \
        --gpu off --no-peers --max-pairs 120 --rate 15 --scene breakfast_room --scene morse_apartment)
    else
      row[$build]=$(run "$workload-$build" "$bin" 'sweptccd::world::WorldAnswerer::Answer*' world-bench \
        --out "$work/world-$build" --data "$data" --avatars 8 --seconds 1)
    fi
    read -r ir d1 ll bcm bim <<<"${row[$build]}"
    echo "| $workload | $build | $ir | $d1 | $ll | $bcm | $bim |"
  done
  read -r oir _ <<<"${row[old]}"
  read -r nir _ <<<"${row[new]}"
  awk -v o="$oir" -v n="$nir" -v w="$workload" 'BEGIN { printf "| %s | new / old | %.4f | | | | |\n", w, n / o }'
done

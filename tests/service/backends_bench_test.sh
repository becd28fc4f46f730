#!/usr/bin/env bash
# tools/service_bench/backends.sh at a tiny size (4 clients at 60 Hz for 2 s
# in the breakfast room, 2 workers): the daemon on the CPU backend, then on
# OTHER (default gpu: the GPU backend, llvmpipe in CI; gpu-descent: the GPU
# backend with the device descent), each gives its table row, and the pairs
# both runs answered have the same answers (differ 0, at least one pair and
# one contact compared). Counts only, never times.
#   backends_bench_test.sh SOURCE_DIR BUILD_DIR [OTHER]
set -euo pipefail
src=$1
build=$2
other=${3:-gpu}
work=$(cd "$build" && pwd)/service_bench_backends_$other
extra=()
# The device descent: a gather window, so batches hold several pairs.
if [ "$other" = gpu-descent ]; then extra=(DESCENT_GATHER_US=4000 DESCENT_MAX_BATCH=8); fi
out=$(env "${extra[@]}" WORK="$work" BACKENDS="cpu $other" CLIENTS=4 RATE=60 WORKERS=2 \
  SCENE=breakfast_room bash "$src/tools/service_bench/backends.sh" "$build" 2 2>&1) || {
  echo "$out"
  exit 1
}
echo "$out"
fail() { echo "FAIL: $*"; exit 1; }
grep -q '^| cpu | env part | [0-9]' <<< "$out" || fail "no CPU row"
grep -q "^| $other | env part | [0-9]" <<< "$out" || fail "no $other row (or it did not run)"
line=$(grep "^answers $other against cpu: " <<< "$out") || fail "no comparison line"
read -r common differ < <(sed -E 's/.*: ([0-9]+) pairs answered by both, differ ([0-9]+).*/\1 \2/' <<< "$line")
[ "$common" -gt 0 ] || fail "no pair answered by both runs"
[ "$differ" = 0 ] || fail "$differ answers differ between the backends"
contacts=$(awk '$4 == 1' "$work/answers_cpu.txt" | wc -l)
[ "$contacts" -gt 0 ] || fail "no contact among the CPU's answers: the comparison proves little"
if [ "$other" = gpu-descent ]; then
  d=$(grep -o 'GPU device descent: [0-9]* batches, [0-9]* pairs' "$work/daemon_gpu-descent.log") ||
    fail "no device descent summary in the daemon's log"
  read -r batches pairs < <(sed -E 's/.*: ([0-9]+) batches, ([0-9]+) pairs/\1 \2/' <<< "$d")
  [ "$batches" -gt 0 ] || fail "no device batch"
  echo "device descent: $batches batches, $pairs pairs"
fi
echo "OK: $common pairs compared, $contacts CPU contacts, differ 0"

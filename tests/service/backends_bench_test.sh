#!/usr/bin/env bash
# tools/service_bench/backends.sh at a tiny size (4 clients at 60 Hz for 2 s
# in the breakfast room, 2 workers): the daemon on the CPU backend, then on
# the GPU backend (llvmpipe in CI), each gives its table row, and the pairs
# both runs answered have the same answers (differ 0, at least one pair and
# one contact compared). Counts only, never times.
#   backends_bench_test.sh SOURCE_DIR BUILD_DIR
set -euo pipefail
src=$1
build=$2
out=$(CLIENTS=4 RATE=60 WORKERS=2 SCENE=breakfast_room \
  bash "$src/tools/service_bench/backends.sh" "$build" 2 2>&1) || {
  echo "$out"
  exit 1
}
echo "$out"
fail() { echo "FAIL: $*"; exit 1; }
grep -q '^| cpu | env part | [0-9]' <<< "$out" || fail "no CPU row"
grep -q '^| gpu | env part | [0-9]' <<< "$out" || fail "no GPU row (or the GPU did not run)"
line=$(grep '^answers gpu against cpu: ' <<< "$out") || fail "no comparison line"
read -r common differ < <(sed -E 's/.*: ([0-9]+) pairs answered by both, differ ([0-9]+).*/\1 \2/' <<< "$line")
[ "$common" -gt 0 ] || fail "no pair answered by both runs"
[ "$differ" = 0 ] || fail "$differ answers differ between the backends"
contacts=$(awk '$4 == 1' "$build/service_bench_backends/answers_cpu.txt" | wc -l)
[ "$contacts" -gt 0 ] || fail "no contact among the CPU's answers: the comparison proves little"
echo "OK: $common pairs compared, $contacts CPU contacts, differ 0"

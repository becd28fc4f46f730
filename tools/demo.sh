#!/usr/bin/env bash
# The demo: a real motion-capture walk (CMU 02_01, bundled) through a real
# furnished apartment (MORSE, bundled), 30 Hz, every pair answered by
# `sweptccd query`. Prints each contact record and a summary.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=build/bin/sweptccd
out=${DEMO_OUT:-build/demo}
mkdir -p "$out"
# The apartment is Z-up; walk 1 m off the clip's origin, where it meets furniture.
"$bin" import-bvh --bvh data/demo/cmu_02_01_walk.bvh --up z --rate 30 --offset 0 -1 0 \
  --utime-start 1000000 --skeleton-out "$out/walk_skeleton.json" --poses-out "$out/walk_poses.jsonl"
"$bin" query --skeleton "$out/walk_skeleton.json" --poses "$out/walk_poses.jsonl" \
  --env data/morse_apartment.ply --per-link --output "$out/results.jsonl"
echo "== contact records (one JSON object per pair; see SPEC section 7) =="
grep '"result":"contact"' "$out/results.jsonl" || true
pairs=$(wc -l < "$out/results.jsonl")
contacts=$(grep -c '"result":"contact"' "$out/results.jsonl" || true)
free=$(grep -c '"result":"free"' "$out/results.jsonl" || true)
echo "== $pairs pairs: $contacts contact, $free free; all results in $out/results.jsonl =="

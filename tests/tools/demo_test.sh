#!/usr/bin/env bash
# The README's main command end to end (tools/demo.sh, after the build):
# exits 0, prints contact events as the daemon publishes them (as many as
# `sweptccd query` finds on the same stream), and writes PNG pictures of the
# first contact and of the timeline.
#   demo_test.sh SOURCE_DIR BUILD_DIR WORK_DIR
set -euo pipefail
src=$1 build=$2 work=$3
rm -rf "$work"
mkdir -p "$work"
status=0
SWEPTCCD_BUILD=$build DEMO_OUT=$work bash "$src/tools/demo.sh" > "$work/demo.out" 2>&1 || status=$?
cat "$work/demo.out"
[ "$status" = 0 ] || { echo "demo_test: tools/demo.sh exited $status" >&2; exit 1; }
events=$(grep -c '^contact ' "$work/demo.out" || true)
expected=$("$build/bin/sweptccd" query --skeleton "$work/walk_skeleton.json" \
  --poses "$work/walk_poses.jsonl" --env "$src/data/env/morse_apartment.ply.gz" \
  | grep -c '"result":"contact"' || true)
echo "demo_test: $events contact events printed, sweptccd query finds $expected"
[ "$events" -ge 1 ] && [ "$events" = "$expected" ]
for png in first_contact.png timeline.png; do
  [ "$(head -c 8 "$work/$png" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] \
    || { echo "demo_test: $work/$png is not a PNG" >&2; exit 1; }
done
echo "demo_test: passed"

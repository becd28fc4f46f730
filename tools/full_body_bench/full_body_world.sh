#!/usr/bin/env bash
# The shared world with 8 full-body avatars (issue 31) against 8 16-link
# ones, same run: the CMU walk (120 Hz) as the 16-link avatar and as the
# 81-link meta-full-body avatar (fingers PROCEDURALLY ANIMATED, not
# captured: sweptccd_full_body_bench --convert), eight copies on a 2 x 4
# grid SPACING metres apart (default 0.7: neighbours' hands meet), in the
# Morse apartment placed as tools/service_bench places the walk
# (tools/netns.sh import_walk); `sweptccd world --bench` on each world, 16
# links first.
#   bash tools/full_body_bench/full_body_world.sh [BUILD_DIR] [WORK_DIR]
# Environment: SPACING (metres).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=$(realpath "${1:-$root/build}")
work=${2:-$(mktemp -d /tmp/full_body_world.XXXXXX)}
spacing=${SPACING:-0.7}
mkdir -p "$work/full"
"$build/bin/sweptccd" import-bvh --bvh "$root/data/mocap/cmu_02_01_walk.bvh.gz" --up z \
  --rate 120 --offset 0 -1 0 --utime-start 1000000 \
  --skeleton-out "$work/skeleton16.json" --poses-out "$work/poses16.jsonl" >/dev/null
"$build/bin/sweptccd_full_body_bench" --convert "$work/skeleton16.json" "$work/poses16.jsonl" \
  "$work/full" 2>/dev/null
cp "$work/full/skeleton.json" "$work/skeleton81.json"
cp "$work/full/poses.jsonl" "$work/poses81.jsonl"
for links in 16 81; do
  python3 - "$work" "$links" "$spacing" "$root/data/env/morse_apartment.ply.gz" <<'PY'
import json, sys
work, links, spacing, env = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4]
lines = open(f"{work}/poses{links}.jsonl").read().split("\n")
avatars = []
for k in range(8):
    dx, dy = (k % 4) * spacing, (k // 4) * spacing
    with open(f"{work}/a{links}_{k}.jsonl", "w") as out:
        for line in lines:
            if not line.strip():
                continue
            pose = json.loads(line)
            for link in pose["links"]:
                link[0] += dx
                link[1] += dy
            out.write(json.dumps(pose) + "\n")
    avatars.append({"id": f"a{k}", "skeleton": f"skeleton{links}.json", "poses": f"a{links}_{k}.jsonl"})
json.dump({"avatars": avatars, "env": [env]}, open(f"{work}/world{links}.json", "w"))
PY
  echo "## $links links, 8 avatars, spacing $spacing m"
  "$build/bin/sweptccd" world --world "$work/world$links.json" --backend cpu --bench
done
echo "(work folder: $work)"

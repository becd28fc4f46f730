#!/usr/bin/env bash
# The cost bound for large skeletons (docs/BENCHMARKS.md): a chain of N
# capsule links 1 km from the apartment (every link culled), P pairs, answered
# by `sweptccd query --backend cpu`; prints the median and minimum per-pair
# time (the records' elapsed_us: the engine only, not the parsing).
#   tools/chain_bench/run.sh SWEPTCCD [N=256] [PAIRS=400]
set -euo pipefail
sweptccd=$1 n=${2:-256} pairs=${3:-400}
src=$(cd "$(dirname "$0")/../.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python3 - "$n" "$pairs" "$work" <<'PY'
import json, sys
n, pairs, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
links = [{"name": f"l{i}", "parent": None if i == 0 else f"l{i-1}",
          "a": [0, 0, 0], "b": [0, 0.01, 0], "radius": 0.005} for i in range(n)]
json.dump({"name": f"chain{n}", "links": links}, open(f"{out}/chain.json", "w"))
with open(f"{out}/poses.jsonl", "w") as f:
    for k in range(pairs + 1):
        pose = [[1000.0 + 0.01 * k, 0.01 * i, 0.0, 1, 0, 0, 0] for i in range(n)]
        f.write(json.dumps({"utime": 1000000 + 11111 * k, "links": pose}) + "\n")
PY
limit=()
if [ "$n" -gt 256 ]; then limit=(--max-links "$n"); fi
"$sweptccd" query --backend cpu "${limit[@]}" --skeleton "$work/chain.json" \
  --poses "$work/poses.jsonl" --env "$src/data/morse_apartment.ply" --output "$work/out.jsonl"
python3 - "$work/out.jsonl" "$n" <<'PY'
import json, statistics, sys
records = [json.loads(line) for line in open(sys.argv[1])]
t = [r["elapsed_us"] for r in records]
culled = min(r["stats"]["links_culled"] for r in records)
print(f"chain of {sys.argv[2]} links: {len(t)} pairs, every pair culled at least {culled} links, "
      f"median {statistics.median(t):.1f} us, min {min(t):.1f} us per pair")
PY

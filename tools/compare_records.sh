#!/usr/bin/env bash
# Compares the records of two `sweptccd` binaries on the real data: every
# scene of DATA/env against a set of BVH clips from DATA/mocap, with both
# motion models, with and without --per-link, and with a small work limit
# (--max-intervals 3, undecided answers). Records are compared with
# `elapsed_us` and `stats` removed; every other field must be equal.
#
# Usage: tools/compare_records.sh OLD_SWEPTCCD NEW_SWEPTCCD [DATA_DIR] [WORK_DIR]
#   DATA_DIR  default the project's data/ (NAME or NAME.gz, whichever is there)
#   WORK_DIR  default a fresh temporary folder (kept, printed at the end)
# Environment: CLIPS (space-separated .bvh names), FRAMES (poses per clip,
# default 90), RATE (Hz, default 30), BACKEND (default cpu; OLD_BACKEND and
# NEW_BACKEND, default BACKEND, for each binary alone), NEW_FLAGS (more
# query flags for the new binary, e.g. `--device-descent`), SCENES
# (space-separated scene names from the list below; default all). E.g. the
# device descent on llvmpipe against the CPU, one binary:
#   NEW_BACKEND=gpu NEW_FLAGS=--device-descent tools/compare_records.sh \
#     build/bin/sweptccd build/bin/sweptccd
# Exit status 0 when no record differs, 1 when some do, 2 on a usage error.
set -euo pipefail

if [[ $# -lt 2 ]]; then
  echo "usage: $0 OLD_SWEPTCCD NEW_SWEPTCCD [DATA_DIR] [WORK_DIR]" >&2
  exit 2
fi
old=$(realpath "$1")
new=$(realpath "$2")
root=$(cd "$(dirname "$0")/.." && pwd)
data=$(realpath "${3:-$root/data}")
# A data file by its plain name, else its gzip (data/ ships NAME.gz).
datafile() { if [ -e "$1" ]; then echo "$1"; else echo "$1.gz"; fi; }
work=${4:-$(mktemp -d /tmp/compare_records.XXXXXX)}
mkdir -p "$work"
for bin in "$old" "$new"; do
  [[ -x "$bin" ]] || { echo "$0: '$bin' is not an executable sweptccd; give its path" >&2; exit 2; }
done
[[ -d "$data/env" && -d "$data/mocap" ]] ||
  { echo "$0: '$data' has no env/ and mocap/; give the data folder as the third argument" >&2; exit 2; }

clips=${CLIPS:-"cmu_02_01_walk.bvh cmu_02_03_run_jog.bvh cmu_13_10_jump_grab_reach_tiptoe.bvh cmu_05_06_dance_cartwheel_pirouettes_jete.bvh boxing_toes.bvh"}
frames=${FRAMES:-90}
rate=${RATE:-30}
backend=${BACKEND:-cpu}
old_backend=${OLD_BACKEND:-$backend}
new_backend=${NEW_BACKEND:-$backend}
new_flags=${NEW_FLAGS:-}

# Scenes: name, mesh, up axis, height of the avatar's lowest point, centre
# (the two other axes). Rooms are placed as the bench places them (2 cm over
# the floor); the Stanford models
# (about 0.2 m) stand under the avatar's path as obstacles, the feet 5 cm
# above their base so the legs sweep through them.
scenes=(
  "morse_apartment morse_apartment.ply z 0.02 1.0 1.0"
  "grey_white_room bitterli_grey_white_room.ply y 0.02 2.3 -1.5"
  "breakfast_room bitterli_breakfast_room.ply y -1.40 -0.67 -1.9"
  "bunny stanford_bunny.obj y 0.05 -0.02 0.0"
  "dragon stanford_dragon_vrip.ply y 0.08 0.0 0.0"
  "dragon_res2 stanford_dragon_vrip_res2.ply y 0.08 0.0 0.0"
  "dragon_res4 stanford_dragon_vrip_res4.ply y 0.08 0.0 0.0"
)

# Imports a clip (once per up axis) and writes it placed for a scene.
place() {  # clip up floor c0 c1 out
  local clip=$1 up=$2 floor=$3 c0=$4 c1=$5 out=$6
  local raw="$work/raw_${clip%.bvh}_$up"
  if [[ ! -f "$raw.jsonl" ]]; then
    "$old" import-bvh --bvh "$(datafile "$data/mocap/$clip")" --up "$up" --rate "$rate" \
      --skeleton-out "$raw.skeleton.json" --poses-out "$raw.jsonl" >/dev/null
  fi
  python3 - "$raw.jsonl" "$raw.skeleton.json" "$up" "$floor" "$c0" "$c1" "$frames" "$out" <<'PY'
import json, sys
src, skel, up, floor, c0, c1, frames, out = sys.argv[1:]
lines = [json.loads(l) for l in open(src) if l.strip()][: int(frames)]
links = json.load(open(skel))["links"]
u = 2 if up == "z" else 1
h = [0, 1] if up == "z" else [0, 2]

def height(p, e):  # Up coordinate of p + q * e (q = w, x, y, z).
    w, x, y, z = p[3:7]
    v = [e[0], e[1], e[2]]
    t = [2 * (y * v[2] - z * v[1]), 2 * (z * v[0] - x * v[2]), 2 * (x * v[1] - y * v[0])]
    r = [v[0] + w * t[0] + y * t[2] - z * t[1], v[1] + w * t[1] + z * t[0] - x * t[2],
         v[2] + w * t[2] + x * t[1] - y * t[0]]
    return p[u] + r[u]

# The lowest capsule surface point over the clip sits `floor` high.
lowest = min(height(p, l[e]) - l["radius"] for pose in lines
             for p, l in zip(pose["links"], links) for e in ("a", "b"))
mid = [sum(pose["links"][0][k] for pose in lines) / len(lines) for k in h]
off = [0.0, 0.0, 0.0]
off[u] = float(floor) - lowest
off[h[0]] = float(c0) - mid[0]
off[h[1]] = float(c1) - mid[1]
with open(out, "w") as f:
    for pose in lines:
        for p in pose["links"]:
            for k in range(3):
                p[k] += off[k]
        f.write(json.dumps(pose) + "\n")
PY
}

runs=0
for scene in "${scenes[@]}"; do
  read -r name mesh up floor c0 c1 <<<"$scene"
  if [[ -n ${SCENES:-} && " $SCENES " != *" $name "* ]]; then continue; fi
  for clip in $clips; do
    poses="$work/${name}_${clip%.bvh}.jsonl"
    place "$clip" "$up" "$floor" "$c0" "$c1" "$poses"
    skel="$work/raw_${clip%.bvh}_$up.skeleton.json"
    for motion in articulated independent; do
      # The last variant runs out of work often (undecided brackets).
      for per_link in "" "--per-link" "--per-link --max-intervals 3"; do
        variant=${per_link//--max-intervals /_limit}
        variant=${variant//--per-link/_perlink}
        tag="${name}_${clip%.bvh}_${motion}${variant// /}"
        for which in old new; do
          bin=$old; which_backend=$old_backend; flags=""
          if [[ $which == new ]]; then bin=$new; which_backend=$new_backend; flags=$new_flags; fi
          "$bin" query --backend "$which_backend" --skeleton "$skel" --poses "$poses" \
            --env "$(datafile "$data/env/$mesh")" --motion "$motion" $per_link $flags \
            --output "$work/$tag.$which.jsonl" 2>"$work/$tag.$which.log"
        done
        runs=$((runs + 1))
      done
    done
  done
done

python3 "$(dirname "$0")/compare_record_files.py" "$work/*.old.jsonl" "records"
status=$?
echo "query runs: $runs per binary; files in $work"
exit $status

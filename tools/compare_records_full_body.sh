#!/usr/bin/env bash
# Compares the records of two `sweptccd` binaries on 81-link full-body
# avatars (issue 31: link groups and loose capsules run only on skeletons
# of 32 links and more, which tools/compare_records.sh's BVH imports are
# not). Reads the placed 16-link clips a run of compare_records.sh left in
# its WORK_DIR, converts each to the meta-full-body avatar
# (`sweptccd_full_body_bench --convert`, fingers procedurally animated),
# and queries it with both binaries (`articulated`): plain, --per-link,
# --per-link --max-intervals 3 and --max-intervals 5. Records are compared
# with `elapsed_us` and `stats` removed; every other field must be equal.
#
# Usage: tools/compare_records_full_body.sh OLD_SWEPTCCD NEW_SWEPTCCD \
#          FULL_BODY_BENCH COMPARE_WORK_DIR [OUT_DIR]
#   FULL_BODY_BENCH   build/bin/sweptccd_full_body_bench
#   COMPARE_WORK_DIR  the WORK_DIR of a finished compare_records.sh run
#   OUT_DIR           default a fresh temporary folder (kept, printed)
# Environment: SCENES (default "grey_white_room breakfast_room
# morse_apartment bunny"), CLIPS (names without .bvh; default walk, dance,
# boxing_toes, jump_grab_reach_tiptoe), DATA (default the project's data/).
# Exit status 0 when no record differs, 1 when some do, 2 on a usage error.
set -euo pipefail

if [[ $# -lt 4 ]]; then
  echo "usage: $0 OLD_SWEPTCCD NEW_SWEPTCCD FULL_BODY_BENCH COMPARE_WORK_DIR [OUT_DIR]" >&2
  exit 2
fi
old=$(realpath "$1")
new=$(realpath "$2")
bench=$(realpath "$3")
placed=$(realpath "$4")
out=${5:-$(mktemp -d /tmp/compare_full_body.XXXXXX)}
mkdir -p "$out"
root=$(cd "$(dirname "$0")/.." && pwd)
data=$(realpath "${DATA:-$root/data}")
for bin in "$old" "$new" "$bench"; do
  [[ -x "$bin" ]] || { echo "$0: '$bin' is not an executable" >&2; exit 2; }
done
datafile() { if [ -e "$1" ]; then echo "$1"; else echo "$1.gz"; fi; }

# Scenes as compare_records.sh names and places them: name, mesh, up axis.
declare -A mesh=([grey_white_room]=bitterli_grey_white_room.ply
  [breakfast_room]=bitterli_breakfast_room.ply [morse_apartment]=morse_apartment.ply
  [bunny]=stanford_bunny.obj)
declare -A up=([grey_white_room]=y [breakfast_room]=y [morse_apartment]=z [bunny]=y)
scenes=${SCENES:-"grey_white_room breakfast_room morse_apartment bunny"}
clips=${CLIPS:-"cmu_02_01_walk cmu_05_06_dance_cartwheel_pirouettes_jete boxing_toes cmu_13_10_jump_grab_reach_tiptoe"}

for scene in $scenes; do
  [[ -n ${mesh[$scene]:-} ]] || { echo "$0: unknown scene '$scene'" >&2; exit 2; }
  for clip in $clips; do
    skel16="$placed/raw_${clip}_${up[$scene]}.skeleton.json"
    poses16="$placed/${scene}_${clip}.jsonl"
    [[ -f $skel16 && -f $poses16 ]] ||
      { echo "$0: $poses16 or $skel16 missing: run compare_records.sh with this scene and clip" >&2; exit 2; }
    dir="$out/${scene}_${clip}"
    mkdir -p "$dir"
    "$bench" --convert "$skel16" "$poses16" "$dir" 2>"$dir/convert.log"
    for variant in "" "--per-link" "--per-link --max-intervals 3" "--max-intervals 5"; do
      tag=articulated$(echo "$variant" | tr -d ' -')
      for which in old new; do
        bin=$old
        [[ $which == new ]] && bin=$new
        "$bin" query --backend cpu --skeleton "$dir/skeleton.json" --poses "$dir/poses.jsonl" \
          --env "$(datafile "$data/env/${mesh[$scene]}")" --motion articulated $variant \
          --output "$dir/$tag.$which.jsonl" 2>"$dir/$tag.$which.log"
      done
    done
  done
done

status=0
python3 "$(dirname "$0")/compare_record_files.py" "$out/*/*.old.jsonl" "81-link records" --undecided --full-paths || status=$?
echo "files in $out"
exit $status

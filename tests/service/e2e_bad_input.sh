#!/usr/bin/env bash
# End-to-end bad input over udpm:// inside a private network namespace this
# script creates (never the host network): while a good client streams the
# bundled walk lock-step, a bad client and an unknown client send a wrong link
# count, non-finite numbers, a zero quaternion, an out-of-range position, a
# duplicate seq, a decreasing utime, and raw garbage / truncated bytes go on
# the pose channel; each gets a rejection_t with the right reason and the
# good client's every event equals `sweptccd query`.
#   e2e_bad_input.sh SWEPTCCD SERVICE E2E_TOOL SOURCE_DIR WORK_DIR
set -euo pipefail
source "$(dirname "$0")/../../tools/netns.sh"
enter_private_netns "$@"
sweptccd=$1 service=$2 tool=$3 src=$4 work=$5
rm -rf "$work"; mkdir -p "$work"
setup_loopback_multicast
url=$SWEPTCCD_URL
env_ply="$src/data/env/morse_apartment.ply.gz"
import_walk "$sweptccd" "$src" 30 "$work"
query_walk "$sweptccd" "$env_ply" "$work"
"$sweptccd" keygen --out "$work/room.key"
"$service" --lcm-url "$url" --env "$env_ply" --client "alice=$work/skeleton.json" \
  --client "bob=$work/skeleton.json" --room-key "$work/room.key" --log-level info \
  --max-pose-rate 100000 2> "$work/daemon.log" &  # Lock-step outruns any tracker.
daemon=$!
trap 'kill -KILL $daemon 2>/dev/null || true' EXIT
wait_for "$work/daemon.log" ready
"$tool" --key "$work/room.key" badinput "$url" alice bob "$work/poses.jsonl" "$work/expected.jsonl"
kill -TERM $daemon
wait $daemon
grep -q stopped "$work/daemon.log"
# The forged id (newline, ESC) reaches the log only escaped (when not
# suppressed by the log rate): no raw ESC byte, no line the id started.
if grep -q $'\x1b' "$work/daemon.log"; then echo "e2e_bad_input: raw ESC in the log" >&2; exit 1; fi
if grep -q '^.\[31mforged' "$work/daemon.log"; then echo "e2e_bad_input: forged log line" >&2; exit 1; fi
echo "e2e_bad_input: passed"

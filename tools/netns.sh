# Sourced by the service's end-to-end tests and its latency benchmark: LCM
# over udpm:// inside a private network namespace, never the host network.

SWEPTCCD_URL='udpm://239.255.76.67:7667?ttl=0'

# enter_private_netns "$@": re-executes the calling script, with the same
# arguments, inside a new network namespace (as root: unshare -n; otherwise a
# user namespace too: unshare -rn). Returns only when already inside.
enter_private_netns() {
  if [ "${SWEPTCCD_IN_NETNS:-}" != 1 ]; then
    local flags=-rn
    if [ "$(id -u)" = 0 ]; then flags=-n; fi
    exec env SWEPTCCD_IN_NETNS=1 unshare $flags bash "$0" "$@"
  fi
}

# setup_loopback_multicast: refuses to go on unless this namespace holds only
# "lo" (a fresh one), then routes multicast over loopback.
setup_loopback_multicast() {
  [ "$(ip -o link show | wc -l)" = 1 ] || { echo "$0: not in a private network namespace" >&2; exit 1; }
  ip link set lo up
  ip route add 224.0.0.0/4 dev lo
}

# import_walk SWEPTCCD SOURCE_DIR RATE_HZ WORK: the bundled CMU walk (real
# mocap, data/mocap/cmu_02_01_walk.bvh.gz) as
# WORK/skeleton.json and WORK/poses.jsonl, placed in the bundled apartment.
import_walk() {
  "$1" import-bvh --bvh "$2/data/mocap/cmu_02_01_walk.bvh.gz" --up z --rate "$3" \
    --offset 0 -1 0 --utime-start 1000000 \
    --skeleton-out "$4/skeleton.json" --poses-out "$4/poses.jsonl"
}

# query_walk SWEPTCCD ENV_MESH WORK: what `sweptccd query` answers for the
# imported walk, as WORK/expected.jsonl (the reference for the daemon).
query_walk() {
  "$1" query --skeleton "$3/skeleton.json" --poses "$3/poses.jsonl" --env "$2" \
    --output "$3/expected.jsonl"
}

# wait_for FILE PATTERN: bounded wait (10 s) for PATTERN to appear in FILE.
wait_for() {
  for _ in $(seq 100); do grep -q "$2" "$1" 2>/dev/null && return 0; sleep 0.1; done
  echo "$0: no '$2' in $1 within 10 s" >&2
  return 1
}

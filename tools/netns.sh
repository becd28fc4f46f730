# Sourced by the service's end-to-end tests and its benchmarks: LCM over
# udpm:// inside a private network namespace, never the host network; hosts
# of network namespaces behind a router (the fleet's tests and benchmarks).

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

# enter_private_hosts_ns "$@": for scripts that make hosts of network
# namespaces (`ip netns add`): re-executes the calling script in a new
# network namespace (the router) AND a new mount namespace with a /run of
# its own, so the named namespaces' bind mounts are seen by nobody else and
# go with the script (as root: unshare -nm; otherwise a user namespace too:
# -rnm). Then refuses to go on unless this namespace holds only "lo", and
# sets it up. Always re-executes (an inherited SWEPTCCD_IN_NETNS does not
# count): /run is never mounted over in a namespace it did not make.
enter_private_hosts_ns() {
  if [ "${SWEPTCCD_IN_HOSTS_NS:-}" != $$ ]; then
    local flags=-rnm
    if [ "$(id -u)" = 0 ]; then flags=-nm; fi
    # exec keeps the pid: the re-executed script knows it made the namespaces.
    exec env SWEPTCCD_IN_NETNS=1 SWEPTCCD_IN_HOSTS_NS=$$ unshare $flags bash "$0" "$@"
  fi
  unset SWEPTCCD_IN_HOSTS_NS
  [ "$(ip -o link show | wc -l)" = 1 ] || { echo "$0: not in a private network namespace" >&2; exit 1; }
  mount -t tmpfs -o mode=755 tmpfs /run
  ip link set lo up
}

# add_routed_hosts TAG H...: hosts H (network namespaces named TAG+H) joined
# to this namespace, the router, by veth pairs: the n-th host (from 1) is
# 10.0.n.2/24 on its eth0, the router's end "rH" 10.0.n.1, the host's
# default route via the router. The router forwards unicast (ip_forward=1)
# and routes no multicast (as a cloud network); each host's multicast stays
# on its own loopback (224.0.0.0/4 dev lo: a room's LCM bus stays on its
# host, as in a pod). After enter_private_hosts_ns only.
add_routed_hosts() {
  local tag=$1 n=0 h
  shift
  sysctl -qw net.ipv4.ip_forward=1
  for h in "$@"; do
    n=$((n + 1))
    ip netns add "$tag$h"
    ip link add "r$h" type veth peer name eth0 netns "$tag$h"
    ip addr add "10.0.$n.1/24" dev "r$h"
    ip link set "r$h" up
    ip -n "$tag$h" link set lo up
    ip -n "$tag$h" addr add "10.0.$n.2/24" dev eth0
    ip -n "$tag$h" link set eth0 up
    ip -n "$tag$h" route add default via "10.0.$n.1"
    ip -n "$tag$h" route add 224.0.0.0/4 dev lo
  done
}

# del_hosts TAG H...: removes the hosts' namespaces (for an EXIT trap).
del_hosts() {
  local tag=$1 h
  shift
  for h in "$@"; do ip netns del "$tag$h" 2> /dev/null || true; done
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

#!/usr/bin/env bash
# A fleet of rooms end to end (docs/DEPLOY.md, "Failover"), never on the host
# network: this script's private network namespace is the router; hosts A,
# B, C and D are network namespaces joined to it by veth pairs
# (10.0.{1,2,3,4}.0/24), ip_forward=1, no multicast routing (checked: a
# multicast datagram from A does not reach B, a unicast one does).
#  - The Agones SDK sidecar stand-in on each room host
#    (tests/service/ops/agones_sdk_standin.py) records its calls and keeps its
#    GameServer in a file; the allocator stand-in (agones_allocator_standin.py,
#    on the router) allocates among them and records every call.
#  - D runs a room server started first (an older instance, never allocated
#    by the rules); A runs the room's server. Clients on B (failover_tool,
#    4 WsLiveClients) find room "arcade-7" through the allocator, join A
#    over wss:// (signed), and stream the walk.
#  - A dies: its link goes down (a host gone: no FIN) and its daemon gets
#    SIGKILL; the replacement starts on C. The allocator answers once with
#    D (a stale cache, fault injection): the client must refuse D (another
#    room's door: 409 to ?room=arcade-7), resolve again, get C, re-join
#    within 2 s of C's Ready, and every pair of the walk is answered exactly
#    once, equal to `sweptccd query`.
#   e2e_failover.sh SWEPTCCD SERVICE FAILOVER_TOOL SOURCE_DIR WORK_DIR
set -euo pipefail
source "$(dirname "$0")/../../../tools/netns.sh"
# The router: a private network namespace, and a private mount namespace for
# the hosts' named network namespaces (tools/netns.sh).
enter_private_hosts_ns "$@"
sweptccd=$1 service=$2 tool=$3 src=$4 work=$5
here=$src/tests/service/fleet
py=/usr/bin/python3
rm -rf "$work" && mkdir -p "$work/gameservers"
cd "$work"
tag=sccd$$
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -KILL "$p" 2> /dev/null || true; done
  del_hosts "$tag" a b c d
}
trap cleanup EXIT
fail() {
  echo "e2e_failover: $*" >&2
  for f in daemon_*.log clients.out; do echo "--- $f" >&2; tail -5 "$f" >&2 || true; done
  exit 1
}
add_routed_hosts "$tag" a b c d
# on HOST CMD...: CMD on host HOST. In the background use `ip netns exec`
# directly (it execs CMD: $! is CMD's pid, so the kills below reach it).
on() { local h=$1; shift; ip netns exec "$tag$h" "$@"; }
# The router forwards unicast, not multicast.
ip netns exec "${tag}b" "$py" "$here/udp_probe.py" recv 10.0.2.2 239.255.9.9 17001 1.5 > probe_m.out &
pids+=($!)
ip netns exec "${tag}b" "$py" "$here/udp_probe.py" recv 10.0.2.2 10.0.2.2 17002 1.5 > probe_u.out &
pids+=($!)
sleep 0.3
on a "$py" "$here/udp_probe.py" send 10.0.1.2 239.255.9.9 17001 5
on a "$py" "$here/udp_probe.py" send 10.0.1.2 10.0.2.2 17002 5
wait "${pids[-1]}" "${pids[-2]}"
[ "$(cat probe_u.out)" = 5 ] || fail "unicast A->B: $(cat probe_u.out) of 5 datagrams"
[ "$(cat probe_m.out)" = 0 ] || fail "multicast A->B crossed the router: $(cat probe_m.out)"

# The room: the walk in the apartment, what `sweptccd query` answers.
import_walk "$sweptccd" "$src" 240 "$work"
query_walk "$sweptccd" "$src/data/env/morse_apartment.ply.gz" "$work"
"$sweptccd" keygen --out room.key
openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=sweptccd-room \
  -keyout door.key -out door.crt 2> /dev/null
chmod 600 door.key
cat > room.yaml <<YAML
lcm_url: "udpm://239.255.76.67:7667?ttl=0"
environment: [$src/data/env/morse_apartment.ply.gz]
backend: cpu
status_period_s: 0.2
log_level: info
security: {room_key: room.key}
websocket: {listen: "0.0.0.0:8765", cert: door.crt, key: door.key}
agones: {enabled: true, health_period_s: 0.2, empty_shutdown_s: 0}
YAML
# start_room HOST N: the SDK stand-in and the daemon on host HOST (10.0.N.2).
start_room() {
  local h=$1 n=$2
  ip netns exec "$tag$h" "$py" "$src/tests/service/ops/agones_sdk_standin.py" 127.0.0.1 9358 \
    "sdk_$h.log" "$work/gameservers/room-$h.json" "room-$h" "10.0.$n.2" 8765 \
    sweptccd.dev/scene=apartment &
  pids+=($!)
  for _ in $(seq 100); do on "$h" curl -s -o /dev/null http://127.0.0.1:9358/none && break; sleep 0.05; done
  ip netns exec "$tag$h" env AGONES_SDK_HTTP_PORT=9358 "$service" --config room.yaml \
    2> "daemon_$h.log" &
  pids+=($!)
  eval "daemon_$h=\$!"
}
ready_wall() { grep '"path": "/ready"' "sdk_$1.log" | head -1 | sed 's/.*"wall": \([0-9.]*\).*/\1/'; }
: > sdk_d.log
start_room d 4
wait_for sdk_d.log '"/ready"' || fail "D not Ready"
"$py" "$here/agones_allocator_standin.py" 0.0.0.0 18080 "$work/gameservers" allocator.log \
  --unhealthy-after 0.4 --stale room-d 1 &
pids+=($!)
for _ in $(seq 100); do curl -s -o /dev/null http://127.0.0.1:18080/ && break; sleep 0.05; done
alloc() {
  curl -s -X POST -H 'Content-Type: application/json' -o "$1" -w '%{http_code}' \
    http://127.0.0.1:18080/gameserverallocation -d "$2"
}
# Refusals: a body that is no AllocationRequest 400, nothing matching 429.
[ "$(alloc bad.json '{"gameServerSelectors": "x"}')" = 400 ] || fail "a bad request was not 400"
[ "$(alloc none.json '{"gameServerSelectors":[{"matchLabels":{"sweptccd.dev/scene":"other"}}]}')" = 429 ] ||
  fail "an allocation that matches nothing was not 429"
# D is allocated to another room: the room's server will be A, and D stays
# alive with an older instance (the stale answer later).
[ "$(alloc first.json '{"namespace":"default","gameServerSelectors":[{"matchLabels":{"sweptccd.dev/scene":"apartment"}}],"metadata":{"labels":{"sweptccd.dev/room":"other-room"}}}')" = 200 ] &&
  grep -q '"gameServerName": "room-d"' first.json || fail "the first allocation was not D: $(cat first.json)"
sleep 0.05  # D's instance (µs) strictly older than A's.
start_room a 1
wait_for sdk_a.log '"/ready"' || fail "A not Ready"

# Clients on B find arcade-7 (A: the one Ready server left) and stream.
ip netns exec "${tag}b" "$tool" http://10.0.2.1:18080 arcade-7 apartment room.key door.crt skeleton.json poses.jsonl \
  expected.jsonl 4 100 > clients.out 2> clients.err &
client=$!
pids+=($client)
wait_for clients.out "streaming" || fail "the clients did not join"
grep -c "^join .*door wss://10.0.1.2:8765/ws" clients.out | grep -q 4 || fail "the clients did not join A"
sleep 1.5
# A dies: the host first (no FIN reaches anyone), then its daemon.
ip link set ra down
kill_wall=$(date +%s.%N)
kill -KILL "$daemon_a"
start_room c 3
wait_for sdk_c.log '"/ready"' || fail "C not Ready"
wait "$client" || { cat clients.out clients.err >&2; fail "the clients failed"; }
cat clients.out
c_ready=$(ready_wall c)
# Every client re-joined C within 2 s of C's Ready, and within 5 s of the kill.
for c in c0 c1 c2 c3; do
  line=$(grep "^join $c .*door wss://10.0.3.2:8765/ws" clients.out | head -1)
  [ -n "$line" ] || fail "$c never joined C"
  wall=$(echo "$line" | sed 's/.* wall \([0-9.]*\) .*/\1/')
  awk -v w="$wall" -v r="$c_ready" -v k="$kill_wall" -v c="$c" 'BEGIN {
    printf "e2e_failover: %s re-joined C %.3f s after C was Ready, %.3f s after the kill\n", c, w - r, w - k;
    exit !(w - r <= 2.0 && w - r > -1.0) }' || fail "$c re-joined too late"
done
# Refused: D (another room's server, an older instance) was offered once (the
# stale answer); the client names its room (/ws?room=arcade-7), so D's door
# refuses it with 409 before any frame (the instance fence behind it:
# e2e_websocket_rooms.sh and the clients' unit suites). (C's door may refuse too, while its
# daemon has not yet read the allocation's room label: the client retries.)
[ "$(grep -o "[0-9]* doors of another room refused" clients.out | awk '{s += $1} END {print s}')" -ge 1 ] ||
  fail "D's door was not refused"
! grep -q "^join .*10.0.4.2" clients.out || fail "a client joined D's older instance"
[ "$(grep -c '^ok client' clients.out)" = 4 ] || fail "not every client had every pair once"
# The stand-ins' records: A Ready then Health and no Shutdown; C Ready after
# the kill; the allocator answered A, then (after A went Unhealthy) 429 or the
# stale D, then C.
"$py" - "$kill_wall" <<'PY' || fail "the stand-ins' records"
import json, sys
kill = float(sys.argv[1])
def lines(p):
    return [json.loads(l) for l in open(p)]
def posts(p):  # The daemon's calls (the start-up probe was a GET).
    return [x for x in lines(p) if x["method"] == "POST"]
a, c = posts("sdk_a.log"), posts("sdk_c.log")
assert a[0]["path"] == "/ready" and any(x["path"] == "/health" for x in a), "A: Ready, Health"
assert not any(x["path"] == "/shutdown" for x in a + c), "no Shutdown"
assert all(x["wall"] < kill + 0.05 for x in a), "A called the sidecar after it was killed"
assert c[0]["path"] == "/ready" and c[0]["wall"] > kill, "C Ready after the kill"
alloc = [x for x in lines("allocator.log") if x["path"] == "/gameserverallocation"]
room = [x for x in alloc if x["body"] and x["body"].get("metadata", {}).get("labels", {}).get("sweptccd.dev/room") == "arcade-7"]
names = [x["answer"].get("gameServerName") for x in room if x["code"] == 200]
assert names and names[0] == "room-a", names
assert "room-c" in names and names.index("room-c") > names.index("room-a"), names
assert names.count("room-d") == 1, names
first_c = names.index("room-c")
assert all(n == "room-c" for n in names[first_c:]), names
for x in room:
    sel = x["body"]["gameServerSelectors"]
    assert sel[0] == {"matchLabels": {"sweptccd.dev/room": "arcade-7"}, "gameServerState": "ALLOCATED"}, sel
    assert sel[1] == {"matchLabels": {"sweptccd.dev/scene": "apartment"}, "gameServerState": "READY"}, sel
print("e2e_failover: allocator answers for arcade-7:", " ".join(names[:3]), "...",
      "(%d requests, %d answered 429)" % (len(room), sum(1 for x in room if x["code"] == 429)))
PY
echo "e2e_failover: passed"

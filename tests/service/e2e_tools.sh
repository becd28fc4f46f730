#!/usr/bin/env bash
# End-to-end test of `sweptccd simulate-tracker` and `sweptccd monitor`
# against the real daemon over udpm:// inside a private network namespace
# this script creates (never the host network). The bundled walk (CMU 02_01,
# imported in-process from the BVH at 30 Hz) is played at 4x by two clients
# 2 m apart; the monitor must show every client's events, consistent with
# `sweptccd query` on the same streams (17 contacts of 85 pairs for client0)
# and with the daemon's status. Then a lossy run (--drop, --late, --jitter-us)
# whose late samples the monitor must show as non_increasing_seq rejections,
# one per late sample, while the events still chain up and match the query.
# Also: bad input to both tools is refused with one line and status 2, the
# monitor stops by itself on --count and --timeout, and on SIGINT with its
# summary. Every wait is bounded; the whole script takes a few seconds.
#   e2e_tools.sh SWEPTCCD SERVICE E2E_TOOL SOURCE_DIR WORK_DIR
set -euo pipefail
source "$(dirname "$0")/../../tools/netns.sh"
enter_private_netns "$@"
sweptccd=$1 service=$2 tool=$3 src=$4 work=$5
rm -rf "$work"; mkdir -p "$work"
setup_loopback_multicast
url=$SWEPTCCD_URL
env_ply="$src/data/env/morse_apartment.ply.gz"
bvh="$src/data/mocap/cmu_02_01_walk.bvh.gz"
fail() { echo "e2e_tools: FAILED: $*" >&2; exit 1; }

# refused EXPECTED_TEXT COMMAND...: exit status 2 and exactly one line on
# standard error that contains EXPECTED_TEXT.
refused() {
  local want=$1 status=0; shift
  "$@" > "$work/refused.out" 2> "$work/refused.err" < /dev/null || status=$?
  [ "$status" = 2 ] || fail "$* exited $status, want 2"
  [ "$(wc -l < "$work/refused.err")" = 1 ] || { cat "$work/refused.err" >&2; fail "$*: not one line"; }
  grep -qF -- "$want" "$work/refused.err" || { cat "$work/refused.err" >&2; fail "$*: no '$want'"; }
  echo "refused: $(cat "$work/refused.err")"
}
refused missing.jsonl "$sweptccd" simulate-tracker --lcm-url "$url" --poses "$work/missing.jsonl"
refused missing.bvh "$sweptccd" simulate-tracker --lcm-url "$url" --bvh "$work/missing.bvh"
printf '{"utime": 1, "links": [[0, 0, 0, 1, 0, 0, 0]]}\n{"utime": 2, "links": [[0, 0\n' > "$work/bad.jsonl"
# A line that is no pose is skipped with a counted warning (SPEC 2: an
# invalid pose, not a fatal error), as `query` reads the same file.
"$sweptccd" simulate-tracker --lcm-url "$url" --poses "$work/bad.jsonl" --client badfile \
  > "$work/bad.out" 2> "$work/bad.err" < /dev/null || fail "simulate-tracker refused bad.jsonl"
grep -qF "bad.jsonl: line 2" "$work/bad.err" || fail "no warning naming bad.jsonl: line 2"
grep -q "skipped 1 malformed line" "$work/bad.out" || fail "the skipped line is not counted"
refused "--drop" "$sweptccd" simulate-tracker --lcm-url "$url" --bvh "$bvh" --drop 1.5
refused "--speed" "$sweptccd" simulate-tracker --lcm-url "$url" --bvh "$bvh" --speed -2
refused "--clients" "$sweptccd" simulate-tracker --lcm-url "$url" --bvh "$bvh" --clients many
refused "--speed" "$sweptccd" simulate-tracker --lcm-url "$url" --bvh "$bvh" --speed 1e-300
refused "--seq-start" "$sweptccd" simulate-tracker --lcm-url "$url" --bvh "$bvh" --seq-start 9223372036854775807
refused "--utime-start" "$sweptccd" simulate-tracker --lcm-url "$url" --bvh "$bvh" --utime-start 1e19
"$sweptccd" keygen --out "$work/room.key"
key=(--key "$work/room.key")
"$sweptccd" keygen --out "$work/open.key"
chmod 640 "$work/open.key"
refused "chmod 600" "$sweptccd" simulate-tracker --lcm-url "$url" --bvh "$bvh" --key "$work/open.key"
refused "chmod 600" "$sweptccd" monitor --lcm-url "$url" --key "$work/open.key" --timeout 1
refused "never overwritten" "$sweptccd" keygen --out "$work/room.key"
refused missing.json "$sweptccd" monitor --lcm-url "$url" --skeleton "$work/missing.json" --timeout 1
refused "--timeout" "$sweptccd" monitor --lcm-url "$url" --timeout -1

# The references: the walk as client0 (offset 0 -1 0) and client1 (one
# --spacing further: 0 1 0) plays it, answered by `sweptccd query`.
import_walk "$sweptccd" "$src" 30 "$work"
query_walk "$sweptccd" "$env_ply" "$work"
mkdir -p "$work/c1"
"$sweptccd" import-bvh --bvh "$bvh" --up z --rate 30 --offset 0 1 0 --utime-start 1000000 \
  --skeleton-out "$work/c1/skeleton.json" --poses-out "$work/c1/poses.jsonl"
query_walk "$sweptccd" "$env_ply" "$work/c1"
poses=$(wc -l < "$work/poses.jsonl")
pairs=$((poses - 1))
want0=$(grep -c '"result":"contact"' "$work/expected.jsonl" || true)
want1=$(grep -c '"result":"contact"' "$work/c1/expected.jsonl" || true)
echo "query: $pairs pairs; contacts: client0 $want0, client1 $want1"
[ "$want0" -gt 0 ] && [ "$want1" -gt 0 ] || fail "the reference has no contact"

"$service" --lcm-url "$url" --env "$env_ply" --status-period 0.2 \
  --client "client0=$work/skeleton.json" --client "client1=$work/skeleton.json" \
  --client "lossy0=$work/skeleton.json" --client "lossy1=$work/skeleton.json" \
  --room-key "$work/room.key" --log-level info 2> "$work/daemon.log" &
daemon=$!
monitor= monitor_json=
trap 'kill -KILL $daemon $monitor $monitor_json 2>/dev/null || true' EXIT
wait_for "$work/daemon.log" ready
"$sweptccd" monitor --lcm-url "$url" "${key[@]}" --skeleton "$work/skeleton.json" --all --timeout 50 \
  > "$work/monitor.out" 2> "$work/monitor.err" &
monitor=$!
wait_for "$work/monitor.out" "^monitor: listening"

# wait_settled POSES CLIENT...: bounded wait (10 s) until the monitor shows
# daemon statuses in which the CLIENTs received POSES poses in all and every
# accepted pose is paired (poses - rejected - 1 = answered + skipped). The
# daemon counts a pair as answered after publishing its event, and the status
# comes after the events on the same socket: every event is printed by then.
wait_settled() {
  local total=$1; shift
  for _ in $(seq 100); do
    awk -v clients="$*" -v total="$total" '
      $1 == "status" && $3 == "poses" { p[$2] = $4; a[$2] = $6; s[$2] = $8; r[$2] = $10 }
      END {
        n = split(clients, c, " ")
        for (i = 1; i <= n; i++) {
          if (!(c[i] in p) || p[c[i]] - r[c[i]] - 1 != a[c[i]] + s[c[i]]) exit 1
          sum += p[c[i]]
        }
        exit sum != total
      }' "$work/monitor.out" && return 0
    sleep 0.1
  done
  fail "no settled daemon status for $* ($total poses) within 10 s"
}

# check_client CLIENT EXPECTED.jsonl: the monitor's events of CLIENT chain
# the poses (pair 0, 1, ... and seq0 = the previous seq1), and every event of
# two consecutive poses has the result `sweptccd query` gives for that pair.
# Prints "events contact compared".
check_client() {
  awk -v c="$1" '
    NR == FNR { match($0, /"result":"[a-z]+"/); want[NR - 1] = substr($0, RSTART + 10, RLENGTH - 11); next }
    ($1 == "contact" || $1 == "free" || $1 == "invalid") && $2 == c {
      split($6, s, "-")
      if ($4 != n || (n > 0 && s[1] != last)) { print c ": event " n " out of order: " $0 > "/dev/stderr"; bad++ }
      last = s[2]; n++; contact += $1 == "contact"
      if (s[2] == s[1] + 1) { compared++; if (want[s[1]] != $1) { print c ": differs from query: " $0 > "/dev/stderr"; bad++ } }
    }
    END { print n + 0, contact + 0, compared + 0; exit (bad > 0) }' "$2" "$work/monitor.out"
}

# Run 1: two clients, no loss, 4x real time.
declare -A events_of
"$sweptccd" simulate-tracker --lcm-url "$url" "${key[@]}" --bvh "$bvh" --up z --rate 30 \
  --offset 0 -1 0 --utime-start 1000000 --clients 2 --spacing 0 2 0 --speed 4 \
  | tee "$work/sim1.out"
grep -q "^simulate-tracker: sent $((2 * poses)), dropped 0, late 0 " "$work/sim1.out" \
  || fail "simulate-tracker did not send every pose of both clients"
wait_settled $((2 * poses)) client0 client1
for c in client0 client1; do
  ref="$work/expected.jsonl" want=$want0
  [ $c = client1 ] && ref="$work/c1/expected.jsonl" want=$want1
  out=$(check_client $c "$ref") || fail "$c: events out of order or unlike query"
  read -r events contact compared <<< "$out"
  events_of[$c]=$events
  grep -q "^contact $c pair [0-9]* seq [0-9]*-[0-9]* t [0-9.]*\.\.[0-9.]* us links [a-z_,]* object 0 separation " \
    "$work/monitor.out" || fail "no readable contact line for $c"
  skipped=$(awk -v c=$c '$1 == "status" && $2 == c { s = $8 } END { print s + 0 }' "$work/monitor.out")
  echo "$c: $events events ($contact contact), $skipped skipped, $compared compared with query"
  [ $((events + skipped)) = $pairs ] || fail "$c: $events events + $skipped skipped != $pairs pairs"
  # Latest-wins may join pairs under load; without a skip, the counts are exact.
  if [ "$skipped" = 0 ]; then
    [ "$events" = $pairs ] && [ "$contact" = "$want" ] \
      || fail "$c: $events events, $contact contact; query: $pairs pairs, $want contact"
  fi
done

# Run 2: the same walk, lossy. A second monitor in --json mode must stop by
# itself after 3 contact events.
"$sweptccd" monitor --lcm-url "$url" "${key[@]}" --json --count 3 --timeout 30 > "$work/monitor.jsonl" &
monitor_json=$!
wait_for "$work/monitor.jsonl" '"type":"listening"'
"$sweptccd" simulate-tracker --lcm-url "$url" "${key[@]}" --bvh "$bvh" --up z --rate 30 \
  --offset 0 -1 0 --utime-start 1000000 --clients 2 --client-prefix lossy --spacing 0 2 0 \
  --speed 4 --drop 0.1 --late 0.1 --jitter-us 3000 --seed 7 | tee "$work/sim2.out"
read -r sent dropped late < <(sed -n 's/^simulate-tracker: sent \([0-9]*\), dropped \([0-9]*\), late \([0-9]*\) .*/\1 \2 \3/p' "$work/sim2.out")
[ "$late" -gt 0 ] && [ "$dropped" -gt 0 ] || fail "the lossy run dropped $dropped and held back $late samples"
[ $((sent + dropped)) = $((2 * poses)) ] || fail "sent $sent + dropped $dropped != 2 x $poses poses"
wait $monitor_json || fail "monitor --json --count 3 exited $?"
monitor_json=
[ "$(grep -c '^{"type":"contact","client":"' "$work/monitor.jsonl")" = 3 ] \
  || { cat "$work/monitor.jsonl" >&2; fail "monitor --json --count 3 printed other than 3 contacts"; }
grep -q '^{"type":"total",' "$work/monitor.jsonl" || fail "monitor --json printed no total"
! grep -q '"verified":false' "$work/monitor.jsonl" || fail "monitor --key: a message did not verify"
# The default backend is auto: calibrated at start, both figures in the log
# and in status_t (issue 11; CI's llvmpipe always gives a context to time).
figures='\(auto: cpu [0-9]+ us, gpu [0-9]+ us per pair'
grep -Eq "^status service backend (cpu|gpu) $figures\) security signed " "$work/monitor.out" \
  || fail "monitor shows no signed service with auto's figures"
grep -Eq "backend (cpu|gpu) $figures, medians of [1-9][0-9]* timed pairs each; " "$work/daemon.log" \
  || fail "the daemon log does not name auto's figures"
! grep -q "^UNVERIFIED" "$work/monitor.out" || fail "monitor --key marked a message UNVERIFIED"
wait_settled "$sent" lossy0 lossy1
rejections=$(grep -c "^reject lossy[01] seq [0-9]* non_increasing_seq: " "$work/monitor.out" || true)
all_rejections=$(grep -c "^reject " "$work/monitor.out" || true)
echo "lossy: sent $sent, dropped $dropped, late $late; monitor: $rejections non_increasing_seq rejections"
[ "$rejections" = "$late" ] && [ "$all_rejections" = "$late" ] \
  || fail "$late late samples but $rejections non_increasing_seq rejections ($all_rejections in all)"
received=0
for c in lossy0 lossy1; do
  ref="$work/expected.jsonl"
  [ $c = lossy1 ] && ref="$work/c1/expected.jsonl"
  out=$(check_client $c "$ref") || fail "$c: events out of order or unlike query"
  read -r events contact compared <<< "$out"
  read -r p a s r g < <(awk -v c=$c '$1 == "status" && $2 == c { p = $4; a = $6; s = $8; r = $10; g = $12 } END { print p, a, s, r, g }' "$work/monitor.out")
  echo "$c: $events events ($contact contact), $compared compared with query; daemon: $p poses, $a answered, $s skipped, $r rejected, $g seq numbers missing"
  gaps=$((${gaps:-0} + g))
  [ "$events" = "$a" ] || fail "$c: monitor saw $events events, daemon answered $a"
  [ "$compared" -gt 0 ] || fail "$c: no event to compare"
  received=$((received + p))
done
[ "$received" = "$sent" ] || fail "daemon received $received poses of the lossy clients, $sent sent"
# Every dropped or late (rejected) sample leaves a hole in the accepted seq
# numbers, except drops at the very end of a stream (nothing after them).
[ "$gaps" -gt 0 ] && [ "$gaps" -le $((dropped + late)) ] \
  || fail "daemon reports $gaps missing seq numbers for $dropped dropped and $late late samples"

# SIGINT: the monitor stops with its summary and status 0.
kill -INT $monitor
status=0; wait $monitor || status=$?
monitor=
[ "$status" = 0 ] || fail "monitor exited $status on SIGINT"
for c in client0 client1; do
  grep -q "^summary $c events ${events_of[$c]} contact [0-9]* free [0-9]* invalid 0 rejected 0 " \
    "$work/monitor.out" || fail "no summary for $c"
done
grep -q "^monitor: [0-9]* events " "$work/monitor.out" || fail "no total line"
! grep -q " gaps [1-9]" "$work/monitor.out" || fail "the monitor missed events"
# --timeout alone ends the monitor (nothing published now).
# A tracker that restarts numbers from 0 again: with a new session (the wall
# clock at its start, by default) it is not locked out. client0 got $poses
# poses above; two restarts later: no rejection, and
# accepted - 3 streams = answered + skipped.
timeout 30 "$sweptccd" monitor --lcm-url "$url" "${key[@]}" --json --timeout 20 \
  > "$work/restart.jsonl" &
monitor_restart=$!
wait_for "$work/restart.jsonl" '"type":"listening"'
total=$poses
for _ in 1 2; do
  "$sweptccd" simulate-tracker --lcm-url "$url" "${key[@]}" --bvh "$bvh" --up z --rate 30 \
    --offset 0 -1 0 --utime-start 1000000 --client client0 --frames 40 --speed 4 > "$work/restart.out"
  total=$((total + $(sed -n 's/^simulate-tracker: sent \([0-9]*\),.*/\1/p' "$work/restart.out")))
  sleep 0.01  # Two runs in one microsecond would share a session.
done
# poses_received counts a pose when it arrives and pairs_answered when its
# pair is done, so a status can show every pose received with the last pair
# still queued: wait for one where both have caught up.
restarted=
for _ in $(seq 100); do
  line=$(grep '^{"type":"status","client":"client0",' "$work/restart.jsonl" | tail -1)
  if grep -q "\"poses_received\":$total,\"pairs_answered\":[0-9]*,\"pairs_skipped\":[0-9]*,\"rejected\":0," <<< "$line"; then
    read -r answered skipped < <(sed 's/.*"pairs_answered":\([0-9]*\),"pairs_skipped":\([0-9]*\),.*/\1 \2/' <<< "$line")
    restarted=1
    [ $((answered + skipped)) = $((total - 3)) ] && break
  fi
  sleep 0.1
done
kill -INT $monitor_restart; wait $monitor_restart || true
[ -n "$restarted" ] || { grep client0 "$work/restart.jsonl" | tail -2 >&2; fail "a restarted tracker was refused"; }
[ $((answered + skipped)) = $((total - 3)) ] \
  || fail "client0: $answered answered + $skipped skipped != $total poses - 3 streams"
echo "restarts: client0 $total poses in 3 streams, $answered answered, $skipped skipped, 0 rejected"

# The 36-byte datagram that crashed lcm-gen's decoders, on each channel the
# monitor decodes: refused, counted, and the monitor goes on.
timeout 20 "$sweptccd" monitor --lcm-url "$url" "${key[@]}" --timeout 3 \
  > "$work/monitor_crash.out" 2> "$work/monitor_crash.err" &
monitor_crash=$!
wait_for "$work/monitor_crash.out" "^monitor: listening"
"$tool" crash "$url" SWEPTCCD_CONTACT contact
"$tool" crash "$url" SWEPTCCD_STATUS status
"$tool" crash "$url" SWEPTCCD_REJECT reject
wait $monitor_crash || fail "monitor exited $? after the crash datagrams"
grep -q " 3 undecodable, " "$work/monitor_crash.out" || { cat "$work/monitor_crash.out" >&2; fail "monitor did not refuse 3 crash datagrams"; }
[ "$(grep -c "string length -2147483648" "$work/monitor_crash.err")" = 3 ] \
  || fail "monitor did not name the bad string length"

# A monitor with another key marks every message it cannot verify.
"$sweptccd" keygen --out "$work/other.key"
timeout 10 "$sweptccd" monitor --lcm-url "$url" --key "$work/other.key" --timeout 1 \
  > "$work/monitor_other.out"
grep -Eq "^UNVERIFIED status service backend (cpu|gpu)( \([^)]*\))? security signed " \
  "$work/monitor_other.out" \
  || fail "monitor with a wrong key did not mark the status UNVERIFIED"
! grep -v "^UNVERIFIED \|^monitor: " "$work/monitor_other.out" | grep -q . \
  || fail "monitor with a wrong key showed a message as verified"
timeout 10 "$sweptccd" monitor --lcm-url "$url" --key "$work/other.key" --json --timeout 1 \
  > "$work/monitor_other.jsonl"
grep -q '^{"type":"service",.*"verified":false}$' "$work/monitor_other.jsonl" \
  || fail "monitor --json with a wrong key did not say verified false"
# Without --key nothing is verified, and the monitor says so.
timeout 10 "$sweptccd" monitor --lcm-url "$url" --timeout 0.3 > "$work/monitor_timeout.out" \
  2> "$work/monitor_timeout.err"
grep -q "nothing is verified" "$work/monitor_timeout.err" || fail "monitor without --key is silent"
grep -q "^monitor: 0 events" "$work/monitor_timeout.out" || fail "monitor --timeout"

kill -TERM $daemon
wait $daemon
grep -q stopped "$work/daemon.log"
echo "e2e_tools: passed"

#!/usr/bin/env bash
# Service latency benchmark inside a private network namespace (never the host
# network): for 1, 8 and 32 clients at 90 Hz, publication -> contact event.
#   bash tools/service_bench/run.sh [BUILD_DIR]   (default build)
# RUNS="CLIENTS:HZ ..." changes the runs (default "1:90 8:90 32:90"; issue 11's
# throughput targets: RUNS="1:90 32:90 64:120"). The walk is imported at each
# rate. "merged" = consecutive pairs (poses - clients) not answered, the
# pairs latest-wins merged (or lost). After the table, one line per run says
# where they went: the daemon's own counts (its last status_t per client, as
# `sweptccd monitor` shows it: poses received, pairs answered, pairs merged
# by latest-wins, rejected) and the namespace's UDP receive-buffer drops
# (/proc/net/snmp RcvbufErrors: datagrams the kernel dropped on any socket,
# the daemon's or the bench's) and send drops (SndbufErrors).
# PHASES=burst|spread (default burst) says when the clients sample in each
# tick (latency_bench --phases): burst, all at its start, one after another;
# spread, client c at c/CLIENTS of the period, as headsets on independent
# clocks. BREAKDOWN=1 adds, per run, where the environment part's time went
# (latency_bench --breakdown). LATENCY_BENCH=PATH runs another bench binary
# against the same daemon (default BUILD_DIR/bin/sweptccd_latency_bench; an
# older bench takes neither option, so leave PHASES and BREAKDOWN unset).
# FULL_BODY=1: every client is the 81-link meta-full-body avatar walking the
# same walk, its fingers procedurally animated (sweptccd_full_body_bench
# --convert; docs/SKELETONS.md), instead of the 16-link CMU avatar.
set -euo pipefail
source "$(dirname "$0")/../netns.sh"
enter_private_netns "$@"
cd "$(dirname "$0")/../.."
build=${1:-build}
work=$build/service_bench
mkdir -p "$work"
setup_loopback_multicast
url=$SWEPTCCD_URL
bench=${LATENCY_BENCH:-$build/bin/sweptccd_latency_bench}
bench_opts=()
if [ -n "${PHASES:-}" ]; then bench_opts+=(--phases "$PHASES"); fi
if [ "${BREAKDOWN:-}" = 1 ]; then bench_opts+=(--breakdown); fi
rm -f "$work/room.key"
"$build/bin/sweptccd" keygen --out "$work/room.key"
echo "| clients | Hz | poses sent | events | median us | p99 us | max us | merged |"
echo "|---:|---:|---:|---:|---:|---:|---:|---:|"
udp_drops() { awk '$1 == "Udp:" && $2 ~ /^[0-9]+$/ { print $6, $7 }' /proc/net/snmp; }
where=()
for run in ${RUNS:-1:90 8:90 32:90}; do
  n=${run%%:*} hz=${run#*:}
  import_walk "$build/bin/sweptccd" . "$hz" "$work" >/dev/null
  if [ "${FULL_BODY:-}" = 1 ]; then
    # The same walk as the 81-link meta-full-body avatar (procedurally
    # animated fingers; tools/full_body_bench --convert), in place of the
    # 16-link one.
    mkdir -p "$work/full_body"
    "$build/bin/sweptccd_full_body_bench" --convert "$work/skeleton.json" "$work/poses.jsonl" \
      "$work/full_body" 2>/dev/null
    cp "$work/full_body/skeleton.json" "$work/full_body/poses.jsonl" "$work/"
  fi
  args=()
  for c in $(seq 0 $((n - 1))); do args+=(--client "client$c=$work/skeleton.json"); done
  "$build/bin/sweptccd-service" --lcm-url "$url" --env data/env/morse_apartment.ply.gz --workers 2 \
    --room-key "$work/room.key" --log-level warn "${args[@]}" 2> "$work/daemon_$n.log" &
  daemon=$!
  sleep 1
  timeout 30 "$build/bin/sweptccd" monitor --lcm-url "$url" --key "$work/room.key" --json \
    --timeout 14 > "$work/monitor_$n.jsonl" 2>/dev/null &
  monitor=$!
  read -r rcv0 snd0 < <(udp_drops)
  line=$("$bench" "$url" "$work/poses.jsonl" "$n" "$hz" 10 "$work/room.key" \
    "${bench_opts[@]}" 2> "$work/bench_$n.err") || { cat "$work/bench_$n.err" >&2; exit 1; }
  read -r sent events < <(awk -F'|' '{ gsub(/ /, ""); print $4, $5 }' <<< "$line")
  echo "$line $(awk -v s="$sent" -v e="$events" -v n="$n" 'BEGIN { printf "%.2f%% |", 100 * (s - n - e) / (s - n) }')"
  sleep 1.5  # A status period, so the monitor has the daemon's last counts.
  read -r rcv1 snd1 < <(udp_drops)
  kill -TERM $daemon
  wait $daemon
  wait $monitor || true
  where+=("$n clients at $hz Hz: daemon $(grep '^{"type":"status","client":' "$work/monitor_$n.jsonl" \
    | awk -F'[:,]' '{ for (i = 1; i < NF; ++i) { if ($i == "\"client\"") c = $(i + 1);
        if ($i == "\"poses_received\"") p[c] = $(i + 1); if ($i == "\"pairs_answered\"") a[c] = $(i + 1);
        if ($i == "\"pairs_skipped\"") k[c] = $(i + 1); if ($i == "\"rejected\"") r[c] = $(i + 1) } }
      END { for (c in p) { P += p[c]; A += a[c]; K += k[c]; R += r[c] }
        printf "%d poses received, %d pairs answered, %d merged by latest-wins, %d rejected", P, A, K, R }');" \
    "kernel: UDP RcvbufErrors $((rcv1 - rcv0)), SndbufErrors $((snd1 - snd0))")
  if [ "${BREAKDOWN:-}" = 1 ]; then where+=("$n clients at $hz Hz: $(grep '^breakdown' "$work/bench_$n.err")"); fi
done
echo
for w in "${where[@]}"; do echo "$w"; done

#!/usr/bin/env bash
# Bounded soak of the daemon inside a private network namespace (never the
# host network): 16 signed clients at 120 Hz for SECONDS (default 180)
# through latency_bench, the daemon's RSS (/proc/PID/status VmRSS) sampled
# every 5 s, its counters read from `sweptccd monitor --json`. Prints RSS
# first/last/slope (KiB per minute, least squares), poses sent, answered,
# skipped, seq_gaps, rate_limited, rejected, and the latency row.
#   bash tools/service_bench/soak.sh [BUILD_DIR] [SECONDS]   (default build 180)
set -euo pipefail
source "$(dirname "$0")/../netns.sh"
enter_private_netns "$@"
cd "$(dirname "$0")/../.."
build=${1:-build}
seconds=${2:-180}
clients=16 rate=120
work=$build/service_soak
mkdir -p "$work"
setup_loopback_multicast
url=$SWEPTCCD_URL
import_walk "$build/bin/sweptccd" . 120 "$work"
rm -f "$work/room.key"
"$build/bin/sweptccd" keygen --out "$work/room.key"
args=()
for c in $(seq 0 $((clients - 1))); do args+=(--client "client$c=$work/skeleton.json"); done
"$build/bin/sweptccd-service" --lcm-url "$url" --env data/env/morse_apartment.ply.gz --workers 2 \
  --room-key "$work/room.key" --status-period 1 --log-level warn "${args[@]}" \
  2> "$work/daemon.log" &
daemon=$!
monitor= sampler=
trap 'kill -KILL $daemon $monitor $sampler 2>/dev/null || true' EXIT
sleep 2  # Loading the environment (log level warn: no "ready" line).
"$build/bin/sweptccd" monitor --lcm-url "$url" --key "$work/room.key" --json \
  --timeout $((seconds + 30)) > "$work/monitor.out" 2> "$work/monitor.err" &
monitor=$!
# RSS sampler: one "seconds KiB" line every 5 s while the daemon lives (bounded).
(
  start=$(date +%s%N)
  for _ in $(seq $((seconds / 5 + 10))); do
    rss=$(awk '/^VmRSS/ { print $2 }' /proc/$daemon/status 2>/dev/null) || break
    [ -n "$rss" ] || break
    echo "$(( ($(date +%s%N) - start) / 1000000 ))e-3 $rss"
    sleep 5
  done
) > "$work/rss.txt" &
sampler=$!
echo "| clients | Hz | poses sent | events | median us | p99 us | max us |" > "$work/latency.md"
"$build/bin/sweptccd_latency_bench" "$url" "$work/poses.jsonl" $clients $rate "$seconds" \
  "$work/room.key" >> "$work/latency.md"
sleep 2  # A status after the last event.
kill -TERM $daemon
wait $daemon
kill -INT $monitor 2>/dev/null || true
wait $monitor || true
kill $sampler 2>/dev/null || true
wait $sampler 2>/dev/null || true
python3 - "$work/rss.txt" "$work/monitor.out" "$work/latency.md" "$seconds" <<'EOF'
import json, sys
pts = [tuple(map(float, l.split())) for l in open(sys.argv[1]) if len(l.split()) == 2]
n = len(pts)

def slope_of(p):  # Least squares, KiB per second.
    mx = sum(t for t, _ in p) / len(p)
    my = sum(r for _, r in p) / len(p)
    return sum((t - mx) * (r - my) for t, r in p) / max(1e-9, sum((t - mx) ** 2 for t, _ in p))

slope = slope_of(pts)
warm = [q for q in pts if q[0] >= 30] or pts  # After the first 30 s (buffers warmed up).
slope_warm = slope_of(warm) if len(warm) > 1 else float("nan")
status, service = {}, {}
for line in open(sys.argv[2], errors="replace"):
    try:
        j = json.loads(line)
    except ValueError:
        continue
    if j.get("type") == "status": status[j["client"]] = j
    if j.get("type") == "service": service = j
tot = lambda k: sum(s.get(k, 0) for s in status.values())
row = open(sys.argv[3]).read().splitlines()[-1].strip("|").split("|")
print(f"| seconds | clients x Hz | poses sent | answered | skipped | seq_gaps | rate_limited "
      f"| rejected | RSS first KiB | RSS last KiB | RSS slope KiB/min | slope after 30 s | samples |")
print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
print(f"| {sys.argv[4]} | {row[0].strip()} x {row[1].strip()} | {row[2].strip()} | "
      f"{tot('pairs_answered')} | {tot('pairs_skipped')} | {tot('seq_gaps')} | "
      f"{tot('rate_limited')} | {tot('rejected') + service.get('rejected_unattributed', 0)} | "
      f"{int(pts[0][1])} | {int(pts[-1][1])} | {slope * 60:.1f} | {slope_warm * 60:.2f} | {n} |")
print(f"latency (publication -> event): median {row[4].strip()} us, p99 {row[5].strip()} us, "
      f"max {row[6].strip()} us; clients reported: {len(status)}")
EOF

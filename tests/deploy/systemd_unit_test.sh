#!/usr/bin/env bash
# The deployed systemd unit stays hardened: `systemd-analyze security
# --offline=true` scores deploy/sweptccd-service.service, alone and with the
# GPU drop-in, at most 3.0 (docs/SECURITY.md), and `systemd-analyze verify`
# accepts both (with ExecStart pointing at the built daemon, since verify
# checks that the binary exists). Offline: no running systemd needed.
#   systemd_unit_test.sh SOURCE_DIR SERVICE_BINARY WORK_DIR
set -euo pipefail
src=$1 service=$2 work=$3
max_exposure=3.0
unit=sweptccd-service.service
rm -rf "$work"
mkdir -p "$work/cpu/etc/systemd/system" "$work/gpu/etc/systemd/system/$unit.d"
for root in cpu gpu; do
  sed "s|/usr/local/bin/sweptccd-service|$service|" "$src/deploy/$unit" \
    > "$work/$root/etc/systemd/system/$unit"
done
sed "s|/usr/local/bin/sweptccd-service|$service|" "$src/deploy/sweptccd-service-gpu.conf" \
  > "$work/gpu/etc/systemd/system/$unit.d/gpu.conf"

for root in cpu gpu; do
  report=$(systemd-analyze security --offline=true --root="$work/$root" "$unit")
  score=$(sed -n 's/.*Overall exposure level for [^:]*: \([0-9.]*\) .*/\1/p' <<< "$report")
  echo "$root: exposure $score (at most $max_exposure)"
  [ -n "$score" ] || { echo "no score in: $report" >&2; exit 1; }
  if awk -v s="$score" -v m="$max_exposure" 'BEGIN { exit !(s > m) }'; then
    grep '✗' <<< "$report" >&2
    echo "$root: exposure $score is above $max_exposure" >&2
    exit 1
  fi
  # The settings the score does not weigh enough, checked one by one.
  for setting in "MemoryMax=" "Restart=always" "IPAddressDeny=any" "DynamicUser=yes"; do
    grep -q "^$setting" "$src/deploy/$unit" || { echo "missing $setting" >&2; exit 1; }
  done
done
# verify: unit syntax, unknown settings (a warning on stderr, which must stay
# empty), the binary. SYSTEMD_UNIT_PATH makes it read the drop-in too.
for root in cpu gpu; do
  errors=$(SYSTEMD_UNIT_PATH="$work/$root/etc/systemd/system:" \
           systemd-analyze verify "$work/$root/etc/systemd/system/$unit" 2>&1) ||
    { echo "$errors" >&2; exit 1; }
  [ -z "$errors" ] || { echo "$root: systemd-analyze verify: $errors" >&2; exit 1; }
done
echo "systemd_unit_test: passed"

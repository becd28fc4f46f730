#!/usr/bin/env bash
# Packaging.DebianPackageRuns: `cpack -G DEB` makes sweptccd (daemon, tool,
# hardened systemd unit, example configuration, Java jar; Depends from
# dpkg-shlibdeps) and sweptccd-dev; the test unpacks sweptccd with
# `dpkg-deb -x` into a temporary root and runs the daemon from there: --help,
# then a real run with the packaged example configuration adjusted to
# temporary paths (a bundled mesh, a skeleton and a room key made by the
# packaged `sweptccd`, LCM to a file:// log, no network), stopped by SIGTERM
# once ready; its status messages are read back from the log by the packaged
# `sweptccd monitor` with the room key.
#   deb_package_test.sh SOURCE_DIR BUILD_DIR WORK_DIR
set -euo pipefail
src=$1 build=$2 work=$3
fail() { echo "deb_package_test: $*" >&2; exit 1; }
command -v cpack >/dev/null || fail "no cpack: install Debian package cmake"
command -v dpkg-deb >/dev/null || fail "no dpkg-deb: install Debian package dpkg"
command -v dpkg-shlibdeps >/dev/null || fail "no dpkg-shlibdeps: install Debian package dpkg-dev"
rm -rf "$work"
mkdir -p "$work/root"

(cd "$work" && cpack -G DEB -B "$work/out" --config "$build/CPackConfig.cmake") > "$work/cpack.log" 2>&1 ||
  { cat "$work/cpack.log" >&2; fail "cpack -G DEB failed"; }
deb=$(find "$work/out" -maxdepth 1 -name 'sweptccd_*.deb' | head -1)
dev=$(find "$work/out" -maxdepth 1 -name 'sweptccd-dev_*.deb' | head -1)
[ -n "$deb" ] || { cat "$work/cpack.log" >&2; fail "no sweptccd_*.deb in $work/out"; }
[ -n "$dev" ] || fail "no sweptccd-dev_*.deb in $work/out"
echo "packages: $(basename "$deb") $(basename "$dev")"

[ "$(dpkg-deb -f "$deb" Package)" = sweptccd ] || fail "package name is not sweptccd"
depends=$(dpkg-deb -f "$deb" Depends)
echo "Depends: $depends"
for lib in libc6 liblcm libsodium libssl; do
  grep -q "$lib" <<< "$depends" || fail "Depends lacks $lib (dpkg-shlibdeps did not run?)"
done
contents=$(dpkg-deb -c "$deb" | awk '{print $NF}')
for f in ./usr/bin/sweptccd-service ./usr/bin/sweptccd \
         ./usr/lib/systemd/system/sweptccd-service.service \
         ./usr/share/doc/sweptccd/examples/sweptccd.yaml \
         ./usr/share/doc/sweptccd/examples/sweptccd-service-gpu.conf \
         ./usr/share/java/sweptccd_msgs.jar; do
  grep -qx "$f" <<< "$contents" || fail "sweptccd package lacks $f"
done
dev_contents=$(dpkg-deb -c "$dev" | awk '{print $NF}')
for f in ./usr/lib/cmake/SweptCCD/SweptCCDConfig.cmake ./usr/lib/pkgconfig/sweptccd.pc \
         ./usr/include/sweptccd/sweptccd/tracker_pose_t.hpp ./usr/include/sweptccd/msgs/signing.h; do
  grep -qx "$f" <<< "$dev_contents" || fail "sweptccd-dev package lacks $f"
done

dpkg-deb -x "$deb" "$work/root"
root=$work/root
unit=$root/usr/lib/systemd/system/sweptccd-service.service
grep -qx 'ExecStart=/usr/bin/sweptccd-service --config /etc/sweptccd/sweptccd.yaml --backend cpu' "$unit" ||
  fail "packaged unit's ExecStart is not /usr/bin/sweptccd-service"
for setting in DynamicUser=yes NoNewPrivileges=yes ProtectSystem=strict PrivateTmp=yes \
               Restart=always "CapabilityBoundingSet="; do
  grep -qx "$setting" "$unit" || fail "packaged unit lacks $setting"
done
if command -v systemd-analyze >/dev/null; then
  report=$(systemd-analyze security --offline=true --root="$root" sweptccd-service.service 2>&1) ||
    { echo "$report" >&2; fail "systemd-analyze security failed on the packaged unit"; }
  score=$(sed -n 's/.*Overall exposure level for [^:]*: \([0-9.]*\) .*/\1/p' <<< "$report")
  echo "packaged unit: exposure $score"
  awk -v s="$score" 'BEGIN { exit !(s != "" && s <= 3.0) }' || fail "packaged unit exposure '$score' above 3.0"
else
  fail "no systemd-analyze: install Debian package systemd"
fi

# The daemon from the package.
daemon=$root/usr/bin/sweptccd-service tool=$root/usr/bin/sweptccd
"$daemon" --help > "$work/help.txt" || fail "packaged daemon --help failed"
grep -q -- '--config' "$work/help.txt" || fail "packaged daemon --help says nothing of --config"
"$tool" keygen --out "$work/room.key" > /dev/null
"$tool" import-bvh --bvh "$src/data/mocap/cmu_02_01_walk.bvh.gz" --up z \
  --skeleton-out "$work/skeleton.json" --poses-out "$work/poses.jsonl" --frames 5 > /dev/null
log=$work/daemon.lcmlog
sed -e "s|^lcm_url: .*|lcm_url: \"file://$log?mode=w\"|" \
    -e "s|^  - ../data/env/morse_apartment.ply.gz|  - $src/data/env/stanford_bunny.obj.gz|" \
    -e "s|skeleton: ../build/demo/walk_skeleton.json|skeleton: $work/skeleton.json|" \
    -e "s|room_key: ../build/demo/room.key|room_key: $work/room.key|" \
    -e "s|^status_period_s: [0-9.]*|status_period_s: 0.1|" \
    "$root/usr/share/doc/sweptccd/examples/sweptccd.yaml" > "$work/sweptccd.yaml"
for key in "file://$log" stanford_bunny "$work/skeleton.json" "$work/room.key" "status_period_s: 0.1"; do
  grep -qF "$key" "$work/sweptccd.yaml" || fail "example configuration changed: cannot set $key"
done
"$daemon" --config "$work/sweptccd.yaml" --backend cpu 2> "$work/daemon.log" &
pid=$!
for _ in $(seq 300); do
  grep -q 'ready:' "$work/daemon.log" && break
  kill -0 "$pid" 2>/dev/null || break
  sleep 0.1
done
grep -q 'ready:' "$work/daemon.log" || { kill "$pid" 2>/dev/null; cat "$work/daemon.log" >&2; fail "daemon not ready"; }
sleep 0.5  # a few status periods
kill -TERM "$pid"
rc=0
wait "$pid" || rc=$?
cat "$work/daemon.log"
[ "$rc" -eq 0 ] || fail "daemon exited $rc on SIGTERM"
grep -q 'stopped' "$work/daemon.log" || fail "daemon did not say it stopped"
[ -s "$log" ] || fail "daemon wrote no LCM log"
# Its status_t messages, read back and verified by the packaged monitor.
"$tool" monitor --lcm-url "file://$log?speed=0" --key "$work/room.key" --json --timeout 3 \
  > "$work/monitor.jsonl" 2> "$work/monitor.err" || { cat "$work/monitor.err" >&2; fail "monitor failed"; }
n=$(grep -c '"type": *"status"' "$work/monitor.jsonl" || true)
echo "status messages read back: $n"
[ "$n" -ge 1 ] || { cat "$work/monitor.jsonl" "$work/monitor.err" >&2; fail "no status_t in the daemon's log"; }
if grep -q '"verified": *false' "$work/monitor.jsonl"; then fail "a status_t does not verify"; fi
echo "deb_package_test: passed"

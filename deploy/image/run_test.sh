#!/usr/bin/env bash
# Runs the image that build.sh made, as Kubernetes would: read-only root
# file system, user 65532, no network but the container's own loopback, the
# room's files mounted read-only at /etc/sweptccd. The daemon must load the
# scene and say "ready"; then SIGTERM and "stopped". Not run in CI (build.sh
# needs the network to Debian's mirror and minutes).
#   deploy/image/run_test.sh OUT_DIR SOURCE_DIR [podman|chroot]
# podman (default; Debian package podman, root or subuids): the OCI image
# itself. chroot (root, where podman cannot run, e.g. inside a container
# whose cgroups crun refuses): the image's root file system (rootfs.tar,
# the one layer) bind-mounted read-only, the daemon run in it with chroot
# --userspec 65532:65532 in a fresh network namespace; the same checks.
set -euo pipefail
out=$1 src=$2 how=${3:-podman}
work=$out/run
rm -rf "$work" && mkdir -p "$work"
# The room: the bundled apartment, one configured client, a key only the
# daemon's user may read.
cp "$src/data/env/morse_apartment.ply.gz" "$work/"
printf '{"name": "two", "links": [{"name": "pelvis", "parent": null, "a": [0,0,0], "b": [0,0,0.3], "radius": 0.1}]}\n' > "$work/one.json"
head -c 32 /dev/urandom | od -An -tx1 | tr -d ' \n' > "$work/room.key"
cat > "$work/room.yaml" <<YAML
lcm_url: "memq://"
environment: [morse_apartment.ply.gz]
clients: [{id: alice, skeleton: one.json}]
backend: cpu
security: {room_key: room.key}
websocket: {listen: "127.0.0.1:8765", view_dir: /usr/share/sweptccd/view}
YAML
chown -R 65532:65532 "$work"
chmod 600 "$work/room.key"
if [ "$how" = chroot ]; then
  root=$out/root
  rm -rf "$root" && mkdir -p "$root"
  tar -xf "$out/rootfs.tar" -C "$root"
  unshare -m -n bash -s "$root" "$work" > "$work/daemon.log" 2>&1 <<'SH' &
set -e
root=$1 work=$2
ip link set lo up
mount --bind "$root" "$root"
mount --bind "$work" "$root/etc/sweptccd"
mount -o remount,bind,ro "$root/etc/sweptccd"
mount -t proc proc "$root/proc"
mount -t tmpfs tmpfs "$root/tmp"
mount -o remount,bind,ro "$root"
! touch "$root/usr/bin/x" 2> /dev/null
cd "$root/etc/sweptccd"
exec chroot --userspec=65532:65532 "$root" sh -c 'cd /etc/sweptccd && id -u && exec /usr/bin/sweptccd-service --config /etc/sweptccd/room.yaml'
SH
  pid=$!
  trap 'kill -KILL $pid 2> /dev/null || true' EXIT
  for _ in $(seq 100); do grep -q "ready:" "$work/daemon.log" && break; sleep 0.2; done
  tail -3 "$work/daemon.log"
  grep -q "ready:" "$work/daemon.log" || { echo "run_test: the daemon never said ready" >&2; exit 1; }
  [ "$(head -1 "$work/daemon.log")" = 65532 ] || { echo "run_test: not user 65532" >&2; exit 1; }
  kill -TERM $pid
  wait $pid || true
  grep -q stopped "$work/daemon.log" || { echo "run_test: no 'stopped' after SIGTERM" >&2; exit 1; }
  echo "run_test: the image's root file system ran read-only as 65532 (chroot): ready, stopped on SIGTERM"
  exit 0
fi
podman pull -q "oci:$out/oci" > "$work/image.id"
image=$(cat "$work/image.id")
name=sweptccd-image-test-$$
# Limits below the caller's (raising them needs CAP_SYS_RESOURCE).
podman run -d --name "$name" --read-only --network none --user 65532:65532 \
  --cap-drop ALL --security-opt no-new-privileges \
  --ulimit nofile=4096:4096 --ulimit nproc=4096:4096 \
  -v "$work:/etc/sweptccd:ro" "$image" > /dev/null
trap 'podman rm -f "$name" > /dev/null 2>&1 || true' EXIT
for _ in $(seq 100); do podman logs "$name" 2>&1 | grep -q "ready:" && break; sleep 0.2; done
podman logs "$name" 2>&1 | tail -3
podman logs "$name" 2>&1 | grep -q "ready:" || { echo "run_test: the daemon never said ready" >&2; exit 1; }
[ "$(podman exec "$name" id -u)" = 65532 ] || { echo "run_test: not user 65532" >&2; exit 1; }
! podman exec "$name" sh -c 'touch /usr/bin/x' 2> /dev/null || { echo "run_test: root file system writable" >&2; exit 1; }
podman stop -t 10 "$name" > /dev/null
podman logs "$name" 2>&1 | grep -q stopped || { echo "run_test: no 'stopped' after SIGTERM" >&2; exit 1; }
echo "run_test: the image ran read-only as 65532: ready, stopped on SIGTERM"

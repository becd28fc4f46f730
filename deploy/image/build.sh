#!/usr/bin/env bash
# The room daemon's OCI image, from Debian packages only (docs/DEPLOY.md,
# "The OCI image"): no base image is pulled from a registry.
#  1. cpack -G DEB: this build's sweptccd package (Depends from dpkg-shlibdeps);
#  2. mmdebstrap: a minimal Debian bookworm root file system from Debian's
#     mirror, sweptccd installed into it with apt (its Depends from the
#     mirror), a system user sweptccd (uid 65532), no apt lists, no docs;
#  3. oci_layout.py: the root file system as an OCI image layout (one layer;
#     user 65532, entrypoint sweptccd-service --config /etc/sweptccd/room.yaml).
# Needs root (mmdebstrap --mode=root) or unprivileged user namespaces
# (--mode=unshare), Debian's mmdebstrap (deploy/debian-packages-image.txt), dpkg-dev and the network to the
# Debian mirror. Takes minutes: it is not run in CI.
#   deploy/image/build.sh BUILD_DIR OUT_DIR [MIRROR]
# then, e.g.:  podman pull oci:OUT_DIR/oci   (or skopeo copy oci:OUT_DIR/oci docker://...)
set -euo pipefail
build=$1 out=$2 mirror=${3:-http://deb.debian.org/debian}
here=$(cd "$(dirname "$0")" && pwd)
mode=root
[ "$(id -u)" = 0 ] || mode=unshare
command -v mmdebstrap >/dev/null || {
  echo "build.sh: needs mmdebstrap: sudo apt-get install -y \$(grep -v '^#' deploy/debian-packages-image.txt)" >&2
  exit 2
}
mkdir -p "$out"
rm -rf "$out/deb" "$out/oci" "$out/rootfs.tar"
(cd "$out" && cpack -G DEB -B "$out/deb" --config "$build/CPackConfig.cmake") > "$out/cpack.log" 2>&1 ||
  { tail -20 "$out/cpack.log" >&2; echo "build.sh: cpack -G DEB failed (build the project first)" >&2; exit 1; }
deb=$(find "$out/deb" -maxdepth 1 -name 'sweptccd_*.deb' | head -1)
[ -n "$deb" ] || { echo "build.sh: no sweptccd_*.deb in $out/deb" >&2; exit 1; }
mmdebstrap --mode=$mode --variant=apt --format=tar \
  --dpkgopt='path-exclude=/usr/share/man/*' --dpkgopt='path-exclude=/usr/share/doc/*' \
  --dpkgopt='path-include=/usr/share/doc/*/copyright' \
  --dpkgopt='path-include=/usr/share/doc/sweptccd/*' \
  --dpkgopt='path-exclude=/usr/share/locale/*' \
  --include=ca-certificates \
  --customize-hook="copy-in $deb /tmp" \
  --customize-hook='chroot "$1" sh -c "apt-get install -y --no-install-recommends /tmp/sweptccd_*.deb"' \
  --customize-hook='chroot "$1" groupadd --system --gid 65532 sweptccd' \
  --customize-hook='chroot "$1" useradd --system --uid 65532 --gid 65532 --home-dir /nonexistent --no-create-home --shell /usr/sbin/nologin sweptccd' \
  --customize-hook='mkdir -p "$1/etc/sweptccd" && rm -f "$1"/tmp/*.deb && rm -rf "$1"/var/lib/apt/lists/* "$1"/var/cache/apt/*' \
  bookworm "$out/rootfs.tar" "$mirror" > "$out/mmdebstrap.log" 2>&1 ||
  { tail -20 "$out/mmdebstrap.log" >&2; echo "build.sh: mmdebstrap failed (see $out/mmdebstrap.log)" >&2; exit 1; }
python3 "$here/oci_layout.py" "$out/rootfs.tar" "$out/oci" sweptccd-service:dev

#!/usr/bin/env python3
"""Writes an OCI image layout (opencontainers image-spec v1: oci-layout,
index.json, blobs/sha256/...) with one layer, the root file system tarball
that mmdebstrap made, so that no container tool is needed to build the
image; podman, skopeo or any registry client can then take it
(`podman pull oci:DIR`, `skopeo copy oci:DIR docker://REGISTRY/NAME:TAG`).

  oci_layout.py ROOTFS_TAR OUT_DIR NAME:TAG

The image runs sweptccd-service as user 65532 (made by the build, no
login), from a root file system meant to be mounted read-only; the room's
configuration, meshes and keys are mounted at /etc/sweptccd.
"""
import gzip
import hashlib
import json
import os
import shutil
import sys

rootfs, out, ref = sys.argv[1], sys.argv[2], sys.argv[3]
blobs = os.path.join(out, "blobs", "sha256")
os.makedirs(blobs, exist_ok=True)


def put(data: bytes) -> str:
    digest = hashlib.sha256(data).hexdigest()
    with open(os.path.join(blobs, digest), "wb") as f:
        f.write(data)
    return digest


# The layer: the tarball gzipped (diff_id: the uncompressed digest).
raw = hashlib.sha256()
tmp = os.path.join(out, "layer.tar.gz.tmp")
with open(rootfs, "rb") as src, open(tmp, "wb") as dst:
    with gzip.GzipFile(fileobj=dst, mode="wb", mtime=0) as gz:
        while True:
            chunk = src.read(1 << 20)
            if not chunk:
                break
            raw.update(chunk)
            gz.write(chunk)
layer = hashlib.sha256()
with open(tmp, "rb") as f:
    for chunk in iter(lambda: f.read(1 << 20), b""):
        layer.update(chunk)
layer_digest, layer_size = layer.hexdigest(), os.path.getsize(tmp)
shutil.move(tmp, os.path.join(blobs, layer_digest))

config = json.dumps({
    "architecture": "amd64", "os": "linux",
    "config": {
        "User": "65532:65532",
        "Entrypoint": ["/usr/bin/sweptccd-service"],
        "Cmd": ["--config", "/etc/sweptccd/room.yaml"],
        "WorkingDir": "/etc/sweptccd",
        "Env": ["PATH=/usr/sbin:/usr/bin:/sbin:/bin"],
        "ExposedPorts": {"8765/tcp": {}},
        "StopSignal": "SIGTERM",
        "Labels": {"org.opencontainers.image.title": "sweptccd-service",
                   "org.opencontainers.image.description":
                       "SweptCCD room daemon; Debian bookworm packages only (mmdebstrap)"},
    },
    "rootfs": {"type": "layers", "diff_ids": ["sha256:" + raw.hexdigest()]},
    "history": [{"created_by": "deploy/image/build.sh (mmdebstrap)"}],
}, sort_keys=True).encode()
config_digest = put(config)
manifest = json.dumps({
    "schemaVersion": 2, "mediaType": "application/vnd.oci.image.manifest.v1+json",
    "config": {"mediaType": "application/vnd.oci.image.config.v1+json",
               "digest": "sha256:" + config_digest, "size": len(config)},
    "layers": [{"mediaType": "application/vnd.oci.image.layer.v1.tar+gzip",
                "digest": "sha256:" + layer_digest, "size": layer_size}],
}, sort_keys=True).encode()
manifest_digest = put(manifest)
with open(os.path.join(out, "oci-layout"), "w") as f:
    json.dump({"imageLayoutVersion": "1.0.0"}, f)
with open(os.path.join(out, "index.json"), "w") as f:
    json.dump({"schemaVersion": 2, "manifests": [{
        "mediaType": "application/vnd.oci.image.manifest.v1+json",
        "digest": "sha256:" + manifest_digest, "size": len(manifest),
        "annotations": {"org.opencontainers.image.ref.name": ref.split(":", 1)[-1]}}]}, f)
print(f"oci_layout: {out} ({ref}), layer {layer_size / 2**20:.1f} MiB gzipped")

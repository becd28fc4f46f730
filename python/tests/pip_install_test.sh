#!/usr/bin/env bash
# `pip install` of python/ into a fresh virtual environment, offline (no
# index, no build isolation: Debian's setuptools and numpy), packaging the
# extension ctest's build made (SWEPTCCD_PREBUILT_EXTENSION; python/setup.py
# builds it with CMake when unset, see docs/PYTHON.md). Then, from another
# folder: import, a query (a ball dropped on a triangle), the stubs and
# py.typed. Usage: pip_install_test.sh PYTHON PYTHON_SRC_DIR EXTENSION
set -euo pipefail
python=$1 src=$2 ext=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cp -r "$src" "$tmp/python"  # pip builds in the source tree: a copy.
rm -rf "$tmp/python/build" "$tmp/python"/*.egg-info
"$python" -m venv --system-site-packages "$tmp/venv"
SWEPTCCD_PREBUILT_EXTENSION=$ext PIP_NO_INDEX=1 PIP_DISABLE_PIP_VERSION_CHECK=1 \
  "$tmp/venv/bin/python" -m pip install --no-build-isolation -q "$tmp/python"
cd "$tmp"
printf 'v -10 -10 0\nv 10 -10 0\nv 0 10 0\nf 1 2 3\n' > floor.obj
site=$("$tmp/venv/bin/python" -c 'import sweptccd, os; print(os.path.dirname(sweptccd.__file__))')
case $site in "$tmp/venv/"*) ;; *) echo "imported from $site, not the venv"; exit 1 ;; esac
for f in py.typed _sweptccd.pyi __init__.py _records.py; do
  test -f "$site/$f" || { echo "missing $f in $site"; exit 1; }
done
ls "$site"/_sweptccd*.so > /dev/null
"$tmp/venv/bin/python" - <<'PY'
import numpy as np
import sweptccd
skeleton = {"name": "ball", "links": [{"name": "b", "parent": None, "a": [0, 0, 0],
                                       "b": [0, 0, 0], "radius": 0.1}]}
engine = sweptccd.Engine(skeleton, ["floor.obj"])
assert engine.num_triangles == 1
# A ball of radius 0.1 dropped from z = 3 to z = -1 meets the floor (z = 0)
# at s = 2.9 / 4.
poses = np.array([[[0, 0, 3, 1, 0, 0, 0]], [[0, 0, -1, 1, 0, 0, 0]]], dtype=float)
(rec,) = engine.query(np.array([0, 1000000]), poses)
assert rec.result == "contact", rec
# G1: nothing touches before s_lo; G3: within delta = 1e-3 m (s >= 0.72475) by s_hi.
assert rec.s_lo <= 0.725 and rec.s_hi >= 0.72475 - 1e-12, rec
assert rec.s_hi - rec.s_lo <= 1e-4 + 1e-12, rec
try:
    sweptccd.Engine(skeleton, ["none.ply"])
    raise SystemExit("no exception for a missing mesh")
except sweptccd.InputError as e:
    assert "none.ply" in str(e), e
print("installed sweptccd works:", rec.result, rec.s_lo)
PY

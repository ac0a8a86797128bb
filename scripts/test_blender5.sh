#!/usr/bin/env bash
# The add-on tests against Blender 5.0's Python API (pip bpy 5.0.1); `make test` covers 4.5 LTS (bpy in .venv).
# bpy 5 lives in its own venv (.venv-blender5, bpy alone: ~1 GB) so .venv keeps bpy 4.5; a .pth line there
# adds .venv's packages (torch, madmom, numpy 1.26.4, ...) after its own, so nothing is installed twice.
set -euo pipefail
cd "$(dirname "$0")/.."

BPY5=5.0.1
VENV=${BLENDER5_VENV:-.venv-blender5}
PYTHON=${PYTHON:-python3.11}
if [[ ! -f "$VENV/.bpy-$BPY5" ]]; then
    echo "test-blender5: creating $VENV with bpy $BPY5 (other packages come from .venv)"
    "$PYTHON" -m venv "$VENV"
    "$VENV/bin/python" -m pip install -q --disable-pip-version-check --no-deps "bpy==$BPY5" 2>&1 \
        | grep -v "is ignored: it is neither" || true
    MAIN_SITE=$(.venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
    OWN_SITE=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
    # addsitedir, not a bare path: .venv's own .pth files (the editable dancenet install) must run too.
    echo "import site; site.addsitedir('$MAIN_SITE')" >"$OWN_SITE/zz_dancenet_main_venv.pth"
    touch "$VENV/.bpy-$BPY5"
fi

SCRATCH=$(mktemp -d -t dancenet-test5-XXXXXX)
trap 'rm -rf "$SCRATCH"' EXIT
export HOME="$SCRATCH/home" BLENDER_USER_RESOURCES="$SCRATCH/blender" MPLBACKEND=Agg
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
mkdir -p "$HOME"
"$VENV/bin/python" -c "import bpy; print('test-blender5: bpy', bpy.app.version_string, 'from', bpy.__file__)"
exec "$VENV/bin/python" -m pytest -q -p no:cacheprovider "$@" tests/addon

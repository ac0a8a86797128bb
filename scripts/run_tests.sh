#!/usr/bin/env bash
# Run the test-suite inside the venv (bpy 4.5 LTS, Python 3.11), then the add-on's tests again in the second venv
# (bpy 5.2 LTS, Python 3.13, numpy 2, no torch) with the evaluation's metrics (scipy 1.18), with Blender's user folders in a scratch directory.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup_blender52.sh  # first: a missing Python 3.13 is said before the long run, not after
# pip's cache stays the user's (the fresh-venv install test and the extension's wheels use it), not the scratch HOME.
export PIP_CACHE_DIR=${PIP_CACHE_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/pip}
SCRATCH=$(mktemp -d -t dancenet-test-XXXXXX)
trap 'rm -rf "$SCRATCH"' EXIT
export HOME="$SCRATCH/home" BLENDER_USER_RESOURCES="$SCRATCH/blender" MPLBACKEND=Agg
# Tests run many small tensor ops: one thread each avoids oversubscribing a 2-core machine.
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
# numba's compiled code kept across runs (the scratch HOME above would lose it): .cache/ is gitignored.
export NUMBA_CACHE_DIR=${NUMBA_CACHE_DIR:-$PWD/.cache/numba}
mkdir -p "$HOME"
.venv/bin/python -m pytest -q -p no:cacheprovider "$@" tests
.venv-blender52/bin/python -c "import bpy, numpy; print('tests: the add-on on bpy', bpy.app.version_string, \
'(Python 3.13, numpy', numpy.__version__ + ')')"
.venv-blender52/bin/python -m pytest -q -p no:cacheprovider "$@" tests/addon tests/test_install.py \
    tests/evaluation/test_metrics.py

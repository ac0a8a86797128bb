#!/usr/bin/env bash
# Run the test-suite inside the venv (bpy 4.5 LTS, Python 3.11), then the add-on's tests again in the second venv
# (bpy 5.2 LTS, Python 3.13, numpy 2, no torch) with the evaluation's metrics (scipy 1.18), with Blender's user
# folders in a scratch directory. `--data` (`make check-data`) runs instead the checks on the real data beyond
# seconds of it (pytest's `data` marker: the whole dataset, whole sequences fitted), which `make test` leaves out.
set -euo pipefail
cd "$(dirname "$0")/.."
DATA_ONLY=0
if [[ ${1:-} == --data ]]; then
    DATA_ONLY=1
    shift
    # The checks skip without the data: here that would pass without checking anything, so say it instead.
    export DANCENET_DATA=${DANCENET_DATA:-$(cd .. && pwd)/shared/data}
    if [[ ! -d "$DANCENET_DATA/dance_with_melody" ]]; then
        echo "check-data: no motion capture data at $DANCENET_DATA (put it at ../shared/data or set DANCENET_DATA)" >&2
        exit 1
    fi
else
    bash scripts/setup_blender52.sh  # first: a missing Python 3.13 is said before the long run, not after
fi
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
# Two workers (pytest-xdist; each its own scratch folders: tests/conftest.py), the tests that build the extension's
# zips on one of them (their xdist_group), and the 15 slowest tests named at the end.
PYTEST=(-q -p no:cacheprovider -n "${DANCENET_TEST_WORKERS:-2}" --dist loadgroup --durations=15)
if ((DATA_ONLY)); then
    .venv/bin/python -m pytest "${PYTEST[@]}" -m data "$@" tests
    exit
fi
.venv/bin/python -m pytest "${PYTEST[@]}" -m "not data" "$@" tests
.venv-blender52/bin/python -c "import bpy, numpy; print('tests: the add-on on bpy', bpy.app.version_string, \
'(Python 3.13, numpy', numpy.__version__ + ')')"
.venv-blender52/bin/python -m pytest "${PYTEST[@]}" -m "not data" "$@" tests/addon tests/test_install.py \
    tests/evaluation/test_metrics.py

#!/usr/bin/env bash
# Run the test-suite inside the venv, with Blender's user folders in a scratch directory.
set -euo pipefail
cd "$(dirname "$0")/.."
SCRATCH=$(mktemp -d -t dancenet-test-XXXXXX)
trap 'rm -rf "$SCRATCH"' EXIT
export HOME="$SCRATCH/home" BLENDER_USER_RESOURCES="$SCRATCH/blender" MPLBACKEND=Agg
# Tests run many small tensor ops: one thread each avoids oversubscribing a 2-core machine.
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
mkdir -p "$HOME"
exec .venv/bin/python -m pytest -q -p no:cacheprovider "$@" tests

#!/usr/bin/env bash
# One-time setup: Debian packages, a Python 3.11 venv with the pinned stack (constraints.txt), and the project
# itself with its train, blender, cluster (Ray) and dev extras.
# A second run with nothing to do only compares a stamp and exits (seconds).
set -euo pipefail
cd "$(dirname "$0")/.."

VENV=.venv
STAMP_INPUTS=(constraints.txt scripts/setup.sh scripts/apt-packages.txt pyproject.toml)
STAMP_HASH=$(cat "${STAMP_INPUTS[@]}" | sha256sum | cut -c1-16)
STAMP="$VENV/.setup-$STAMP_HASH"

if [[ -f "$STAMP" ]]; then
    exit 0
fi

# Debian packages (only the missing ones; apt-get needs root or sudo).
mapfile -t APT_PKGS < <(grep -vE '^\s*(#|$)' scripts/apt-packages.txt || true)
MISSING=()
for p in "${APT_PKGS[@]}"; do
    dpkg -s "$p" >/dev/null 2>&1 || MISSING+=("$p")
done
if ((${#MISSING[@]})); then
    echo "setup: installing Debian packages: ${MISSING[*]}"
    SUDO=""; [[ $(id -u) -ne 0 ]] && SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${MISSING[@]}" >/dev/null
fi

PYTHON=${PYTHON:-python3.11}
if ! command -v "$PYTHON" >/dev/null; then
    echo "setup: Python 3.11 is required (set PYTHON=/path/to/python3.11)." >&2
    exit 1
fi
if [[ ! -x "$VENV/bin/python" ]]; then
    echo "setup: creating $VENV with $PYTHON"
    "$PYTHON" -m venv "$VENV"
fi
PIP=("$VENV/bin/python" -m pip install -q --disable-pip-version-check -c constraints.txt)

# torch alone and first, the CPU build: otherwise pip resolves the CUDA build (several GB).
if ! "$VENV/bin/python" -c "import torch, sys; sys.exit(torch.__version__.split('+')[0] != '2.13.0')" 2>/dev/null; then
    echo "setup: installing torch 2.13.0 (CPU)"
    "${PIP[@]}" torch==2.13.0 2>&1 | grep -v "is ignored: it is neither" || true
fi
echo "setup: installing the pinned stack"
# pyrender pins an old PyOpenGL; we use PyOpenGL 3.1.10, so pyrender goes in without its dependencies and
# what it imports is listed here.
"${PIP[@]}" -e ".[train,blender,cluster,dev]" trimesh PyOpenGL six networkx Pillow imageio pyglet freetype-py 2>&1 \
    | grep -v "is ignored: it is neither" || true
"${PIP[@]}" --no-deps pyrender==0.1.45 2>&1 | grep -v "is ignored: it is neither" || true

rm -f "$VENV"/.setup-*
touch "$STAMP"
echo "setup: done ($(du -sh "$VENV" | cut -f1) in $VENV)"

#!/usr/bin/env bash
# The second venv `make test` needs: Python 3.13 (Blender 5.x's), bpy 5.2.3 LTS, numpy 2 and the rest of the
# generation stack (constraints.txt), pytest and pytest-xdist, Pillow (the panel pictures), and this project; no
# torch.
# A second run with nothing to do only compares a stamp and exits.
set -euo pipefail
cd "$(dirname "$0")/.."

VENV=${BLENDER52_VENV:-.venv-blender52}
STAMP="$VENV/.setup-$(cat constraints.txt scripts/setup_blender52.sh pyproject.toml | sha256sum | cut -c1-16)"
[[ -f "$STAMP" ]] && exit 0

is_313() { "$1" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 13))' 2>/dev/null; }
PYTHON313=${PYTHON313:-}
if [[ -z "$PYTHON313" ]]; then
    for candidate in python3.13 "$HOME"/.pyenv/versions/3.13*/bin/python3.13 /usr/local/bin/python3.13; do
        if is_313 "$candidate"; then PYTHON313=$candidate; break; fi
    done
fi
if [[ -z "$PYTHON313" ]] || ! is_313 "$PYTHON313"; then
    cat >&2 <<'MSG'
setup: the Blender 5.2 tests need Python 3.13 (Blender 5.x's Python), and none was found.
Install it (Debian/Ubuntu: `apt-get install python3.13 python3.13-venv` where your release has it, or
`pyenv install 3.13`), or point PYTHON313=/path/to/python3.13 at one, then run `make test` again.
MSG
    exit 1
fi
if [[ ! -x "$VENV/bin/python" ]]; then
    echo "setup: creating $VENV with $PYTHON313 (bpy 5.2.3, numpy 2, no torch)"
    "$PYTHON313" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install -q --disable-pip-version-check -c constraints.txt -e ".[blender]" pytest pytest-xdist \
    Pillow 2>&1 | grep -v "is ignored: it is neither" || true
rm -f "$VENV"/.setup-*
touch "$STAMP"
echo "setup: done ($(du -sh "$VENV" | cut -f1) in $VENV)"

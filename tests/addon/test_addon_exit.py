"""A script that loads the add-on ends when it ends, however the add-on was loaded: registered by the script from
the checkout, or installed as the extension and enabled (by Blender's preferences, or registered by the script),
with the warm-up still under way or done. `make test` runs this file on bpy 4.5 LTS and on bpy 5.2 LTS."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

import build_addon

ROOT = Path(__file__).resolve().parents[2]
bpy = pytest.importorskip("bpy")
ENDS_WITHIN_S = 120  # a process that hangs never ends; a busy machine may take tens of seconds to load bpy

FROM_CHECKOUT = """
import sys
sys.path.insert(0, sys.argv[1])
import bpy
import blender_addon
blender_addon.register()
if sys.argv[2] == "done":
    blender_addon.warming.wait()
print("LOADED", flush=True)
"""

INSTALLED = """
import sys
sys.path.insert(0, sys.argv[1])  # the fresh bpy: this interpreter runs with -I -S, so nothing else is importable
import bpy
import addon_utils  # on the path once bpy is imported
on_install = sys.argv[3] == "on install"
assert bpy.ops.extensions.package_install_files(filepath=sys.argv[2], repo="user_default",
                                                enable_on_install=on_install) == {"FINISHED"}
if not on_install:
    assert addon_utils.enable("bl_ext.user_default.dancenet", default_set=True) is not None
assert "bl_ext.user_default.dancenet" in bpy.context.preferences.addons
print("LOADED", flush=True)
"""


def _ends(args: list[str], tmp_path: Path, kept: tuple[str, ...] = ()) -> None:
    """Runs the script with Blender's user folders in `tmp_path` (and the caller's environment variables named in
    `kept`); fails if the process outlives ENDS_WITHIN_S, or if it ends with an error (an add-on unregistered twice,
    say)."""
    env = {k: v for k, v in os.environ.items()
           if k in kept or not k.startswith(("BLENDER_USER_", "DANCENET_", "NUMBA_"))}  # fmt: skip
    env.update(HOME=str(tmp_path / "home"), BLENDER_USER_RESOURCES=str(tmp_path / "blender"))
    start = time.perf_counter()
    try:
        run = subprocess.run(args, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=ENDS_WITHIN_S)
    except subprocess.TimeoutExpired as e:
        pytest.fail(f"still running after {ENDS_WITHIN_S} s; its output: {e.stdout!r} {e.stderr!r}")
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    assert "LOADED" in run.stdout
    assert "Traceback" not in run.stderr, run.stderr[-3000:]
    print(f"ended in {time.perf_counter() - start:.1f} s")


@pytest.mark.parametrize("warm_up", ["under way", "done"])
def test_a_script_that_registers_the_checkout_ends(warm_up: str, tmp_path: Path) -> None:
    """numba's cache kept (as the suite's): the warm-up loads its kernels rather than compiling them."""
    _ends([sys.executable, "-c", FROM_CHECKOUT, str(ROOT), warm_up], tmp_path, kept=("NUMBA_CACHE_DIR",))


@pytest.mark.xdist_group("build")  # with the other tests that build the project (tests/addon/conftest.py)
@pytest.mark.parametrize("enabled", ["on install", "by a script"])
def test_a_script_that_installs_the_extension_ends(enabled: str, zips: dict[str, Path], tmp_path: Path) -> None:
    fresh = build_addon.fresh_bpy(tmp_path / "fresh")
    _ends([sys.executable, "-I", "-S", "-c", INSTALLED, str(fresh), str(zips["linux-x64"]), enabled], tmp_path)

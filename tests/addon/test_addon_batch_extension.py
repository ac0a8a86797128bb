"""Batch mode run from a checkout (the README's `python blender_addon/batch.py -- SONG --out DIR`)
beside the installed extension, the linux-x64 zip as `python build_addon.py` builds it: the batch dances, and the
extension stays installed as it was (its wheels' site-packages, its enabled state). Resetting the preferences for an
empty scene (`read_factory_settings`) must not disable it: Blender then removes the wheels of the extensions no
longer enabled, the core's weights among them, in the middle of the batch."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SONG = ROOT / "examples" / "example_song.ogg"
PACKAGE = "bl_ext.user_default.dancenet"

INSTALL = """
import sys, bpy
assert bpy.ops.extensions.package_install_files(filepath=sys.argv[1], repo="user_default",
                                                enable_on_install=True) == {"FINISHED"}
if sys.argv[2] == "saved":  # what Blender's auto-saved preferences do after an install
    bpy.ops.wm.save_userpref()
"""
# pip's bpy starts with the factory preferences; these scripts read the saved ones, as `blender --background` does.
PREFERENCES = """
import os, bpy
if os.path.isfile(bpy.utils.user_resource("CONFIG", path="userpref.blend")):
    bpy.ops.wm.read_userpref()
"""
ENABLED = f"{PREFERENCES}print('ENABLED', {PACKAGE!r} in bpy.context.preferences.addons)"
BATCH = f"""{PREFERENCES}
import runpy, sys
sys.argv = [sys.argv[1], "--", *sys.argv[2:]]
try:
    runpy.run_path(sys.argv[0], run_name="__main__")
finally:
    print('ENABLED', {PACKAGE!r} in bpy.context.preferences.addons)
"""


pytestmark = pytest.mark.xdist_group("build")  # with the other tests that build the project (tests/addon/conftest.py)


@pytest.fixture
def linux_zip(zips: dict[str, Path]) -> Path:
    return zips["linux-x64"]


def _files(folder: Path) -> dict[str, int]:
    return {str(p.relative_to(folder)): p.stat().st_size for p in folder.rglob("*") if p.is_file()}


@pytest.mark.parametrize("preferences", ["saved", "unsaved"])
def test_batch_from_a_checkout_leaves_the_installed_extension_alone(linux_zip: Path, tmp_path: Path,
                                                                    preferences: str) -> None:
    user = tmp_path / "blender"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("BLENDER_USER_", "DANCENET_"))}
    env.update(HOME=str(tmp_path / "home"), BLENDER_USER_RESOURCES=str(user), PWD=str(tmp_path))  # Blender reads $PWD

    def python(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, *args], cwd=tmp_path, env=env, capture_output=True, text=True,
                              timeout=600)  # fmt: skip

    installed = python("-c", INSTALL, str(linux_zip), preferences)
    assert installed.returncode == 0, installed.stdout[-2000:] + installed.stderr[-2000:]
    site = user / "extensions" / ".local" / "lib" / f"python{sys.version_info[0]}.{sys.version_info[1]}"
    before = _files(site)
    assert any(name.endswith("dancenet_core/weights/dancenet.npz") for name in before)
    enabled = f"ENABLED {preferences == 'saved'}"
    assert enabled in python("-c", ENABLED).stdout.splitlines()

    args = (str(ROOT / "blender_addon" / "batch.py"), str(SONG), "--out", "out", "--bvh", "--end", "8")
    batch = python("-c", BATCH, *args) if preferences == "saved" else python(args[0], "--", *args[1:])  # the README's
    assert batch.returncode == 0, batch.stdout[-2000:] + batch.stderr[-2000:]
    assert "1 of 1 songs done" in batch.stdout.splitlines(), batch.stdout
    assert preferences == "unsaved" or "ENABLED True" in batch.stdout.splitlines(), batch.stdout
    assert (tmp_path / "out" / "example_song" / "example_song.bvh").is_file()
    assert _files(site) == before
    assert enabled in python("-c", ENABLED).stdout.splitlines()

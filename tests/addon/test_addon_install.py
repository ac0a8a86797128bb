"""The built extension zip installs into a fresh Blender (pip bpy, scratch user folders), enables, and
generates a dance with its bundled core (the generator is the test double until the model ships)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytest.importorskip("bpy")

INSTALL_AND_GENERATE = """
import sys
from pathlib import Path
import bpy
import addon_utils

zip_path, song = sys.argv[1], sys.argv[2]
assert bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                                enable_on_install=True) == {"FINISHED"}
package = "bl_ext.user_default.dancenet"
assert package in bpy.context.preferences.addons, list(bpy.context.preferences.addons.keys())
import dancenet_core
print("CORE", dancenet_core.__file__)

from doubles import make_fake_generator
sys.modules[package + ".pipeline"].load_generator = make_fake_generator
props = bpy.context.scene.dancenet
props.music_file = song
print("RESULT", bpy.ops.dancenet.generate())
rig = bpy.data.objects["DanceNet Dancer"]
print("ACTION", rig.animation_data.action.name, len(rig.data.bones))
addon_utils.disable(package)
print("DISABLED", hasattr(bpy.types.Scene, "dancenet"))
print("SITE", sys.modules[package + ".deps"].site_dir())

# Batch mode from the installed copy: it imports the add-on under its folder name.
import importlib.util
installed = Path(sys.modules[package].__file__).parent
spec = importlib.util.spec_from_file_location("installed_batch", installed / "batch.py")
batch = importlib.util.module_from_spec(spec)
spec.loader.exec_module(batch)
print("BATCH", batch.main([song, "--out", str(Path(song).parent / "out")], generator=make_fake_generator()))
print("BATCH SITE", sys.modules["dancenet.deps"].site_dir())
"""


def test_built_zip_installs_enables_and_generates(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT))
    from doubles import write_song

    import build_addon

    zip_path = build_addon.build(tmp_path / "dist")
    assert zip_path.name == "dancenet-0.1.0.zip"
    song = write_song(tmp_path / "song.wav", 1.0)
    user = tmp_path / "blender"
    env = {
        **os.environ,
        "HOME": str(tmp_path / "home"),
        "BLENDER_USER_RESOURCES": str(user),
        "BLENDER_USER_CONFIG": str(user / "config"),
        "BLENDER_USER_SCRIPTS": str(user / "scripts"),
        "BLENDER_USER_EXTENSIONS": str(user / "extensions"),
        "PYTHONPATH": str(ROOT / "tests" / "addon"),
    }
    run = subprocess.run(
        [sys.executable, "-c", INSTALL_AND_GENERATE, str(zip_path), str(song)],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert run.returncode == 0, run.stdout + run.stderr
    out = run.stdout
    installed = user / "extensions" / "user_default" / "dancenet"
    assert f"CORE {installed / 'vendor' / 'dancenet_core' / '__init__.py'}" in out
    assert "RESULT {'FINISHED'}" in out
    assert "ACTION song · hiphop · seed 0 55" in out
    assert "DISABLED False" in out
    site = user / "extensions" / ".user" / "user_default" / "dancenet" / "site-packages"
    assert f"SITE {site}" in out
    assert f"BATCH SITE {site}" in out
    assert "OK      song.wav: hiphop, 1.0 s, 1 take" in out
    assert "BATCH 0" in out
    assert (tmp_path / "out" / "song" / "song.blend").is_file()
    assert (installed / "requirements.txt").read_text().count("torch==") == 1

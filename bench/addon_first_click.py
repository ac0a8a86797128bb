"""The extension as a new user meets it: its size per platform, and the first Generate Dance
after installing it into a fresh Blender.

    .venv/bin/python bench/addon_first_click.py [--dist DIR] [--pythons .venv/bin/python .venv-blender52/bin/python]
        [--repeats N]

Builds the zips as `python build_addon.py` does (or reads them from --dist) and reports, per platform, the zip,
what Blender unpacks and keeps (the add-on and every wheel) and what it installs from the wheels for each
Python, unpacked. Then, for each interpreter given (a venv with bpy), installs the linux-x64 zip into a fresh bpy
(only bpy and what bpy requires; Blender's user folders, HOME and the caches in a scratch folder), enables it and
times the first Generate Dance of a 12-s sound strip of the example song from scratch: clicked at once (the
warm-up thread the add-on starts when enabled still running) and clicked once the warm-up has finished, each
onto a new rig and onto a Rigify rig generated from the human metarig (its controls keyed, `rigcontrols`; the
rig is made before the clock starts); --repeats N clicks at once on the Rigify rig N times, each in a new
Blender, with the 1-minute load average after each (the machine's other work slows a click). The installed size
there is measured on disk. Prints JSON.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SONG = REPO / "examples" / "example_song.ogg"
STRIP_S = 12
MB = 1e6

# Run as `python -I -S -c CHILD FRESH_BPY ZIP SONG WAIT RIG` in a scratch HOME; prints one JSON line. RIG: "new"
# (Generate Dance builds our rig) or "rigify" (onto a Rigify rig made from the human metarig first).
CHILD = """
import json, os, sys, threading, time
sys.path.insert(0, sys.argv[1])  # the fresh bpy: -I -S, so nothing else is importable
zip_path, song, wait, rig = sys.argv[2], sys.argv[3], sys.argv[4] == "1", sys.argv[5]
import bpy
if rig == "rigify":
    import addon_utils  # Blender's, on the path once bpy is imported

    addon_utils.enable("rigify", default_set=True)
    bpy.ops.object.armature_human_metarig_add()
    metarig = bpy.context.object
    bpy.ops.pose.rigify_generate()
    target = bpy.context.object
    bpy.data.objects.remove(metarig)
t = time.perf_counter()
assert bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                                enable_on_install=True) == {"FINISHED"}
enabled = time.perf_counter()
warm = next(th for th in threading.enumerate() if th.name == "dancenet-warm-up")
if wait:
    warm.join()
warm_s = time.perf_counter() - enabled
scene = bpy.context.scene
scene.sequence_editor_create()
strip = scene.sequence_editor.strips.new_sound("song", song, 2, 1)
strip.frame_final_duration = STRIP_S * scene.render.fps
scene.sequence_editor.active_strip = strip
scene.dancenet.music_source = "STRIP"
if rig == "rigify":
    scene.dancenet.target, scene.dancenet.armature = "EXISTING", target
click = time.perf_counter()
result = bpy.ops.dancenet.generate()
first = time.perf_counter() - click
warm_alive_after = warm.is_alive()
warm.join()
print(json.dumps({"bpy": bpy.app.version_string, "result": sorted(result), "install_and_enable_s": enabled - t,
                  "waited_for_warm_up_s": warm_s if wait else None, "first_generate_s": first,
                  "warm_up_still_running_after_click": warm_alive_after}), flush=True)
os._exit(0)  # a Rigify rig's UI script keeps bpy alive, and bpy 4.5's exit then waits for ever on its audio thread
""".replace("STRIP_S", str(STRIP_S))


def _folder_mb(path: Path) -> float:
    return round(sum(f.stat().st_size for f in path.rglob("*") if f.is_file() and not f.is_symlink()) / MB, 1)


def _unpacked_mb(archive: Path) -> float:
    with zipfile.ZipFile(archive) as z:
        return round(sum(i.file_size for i in z.infolist()) / MB, 1)


def _build_addon():
    spec = importlib.util.spec_from_file_location("build_addon", REPO / "build_addon.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def sizes(dist: Path) -> dict:
    """Per platform: the zip, the extension folder Blender keeps (the zip unpacked, wheels included), and per
    Python the packages installed from the wheels that serve it, unpacked (.pyc written later not counted)."""
    build_addon = _build_addon()
    out = {}
    for platform_name in build_addon.PLATFORMS:
        archive = next(dist.glob(f"dancenet-*-{platform_name.replace('-', '_')}.zip"))
        with zipfile.ZipFile(archive) as z:
            own = sum(i.file_size for i in z.infolist() if re.match(r"wheels/dancenet-.*\.whl$", i.filename))
            with tempfile.TemporaryDirectory() as tmp:
                name = next(n for n in z.namelist() if re.match(r"wheels/dancenet-.*\.whl$", n))
                own_unpacked = _unpacked_mb(Path(z.extract(name, tmp)))
        installed = {}
        for python in build_addon.PYTHONS:
            wheels = build_addon.dependency_wheels(platform_name, python)
            installed[python] = round(own_unpacked + sum(_unpacked_mb(w) for w in wheels), 1)
        kept = _unpacked_mb(archive)
        out[platform_name] = {
            "zip_mb": round(archive.stat().st_size / MB, 1),
            "dancenet_wheel_mb": round(own / MB, 1),
            "extension_folder_mb": kept,
            "installed_packages_mb": installed,
            "total_on_disk_mb": {py: round(kept + mb, 1) for py, mb in installed.items()},
            "pt_files_in_zip": _pt_files(archive),
        }
    return out


def _pt_files(archive: Path) -> list[str]:
    """`.pt` checkpoints anywhere in the zip, inside its wheels included (the runtime reads none)."""
    found = []
    with zipfile.ZipFile(archive) as z, tempfile.TemporaryDirectory() as tmp:
        for name in z.namelist():
            if name.endswith(".whl"):
                with zipfile.ZipFile(z.extract(name, tmp)) as wheel:
                    found += [f"{name}!{n}" for n in wheel.namelist() if n.endswith(".pt")]
            elif name.endswith(".pt"):
                found.append(name)
    return found


def _click(tmp: Path, fresh: Path, archive: Path, case: str, wait: str, rig: str) -> dict:
    """One first Generate Dance in a scratch Blender of its own (HOME, user folders, caches: all new)."""
    scratch = Path(tmp) / case
    user = scratch / "blender"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("BLENDER_USER_", "DANCENET_", "NUMBA_"))}
    env |= {"HOME": str(scratch / "home"), "BLENDER_USER_RESOURCES": str(user)}
    (scratch / "home").mkdir(parents=True)
    run = subprocess.run([sys.executable, "-I", "-S", "-c", CHILD, str(fresh), str(archive), str(SONG), wait, rig],
                         cwd=scratch, env=env, capture_output=True, text=True, timeout=900)  # fmt: skip
    if run.returncode:
        raise SystemExit(f"{case}: {run.stderr.strip().splitlines()[-1:]}")
    line = next(x for x in run.stdout.splitlines() if x.startswith("{"))
    out = {k: round(v, 2) if isinstance(v, float) else v for k, v in json.loads(line).items()}
    ext = user / "extensions"
    out["on_disk_mb"] = {
        "extension_folder": _folder_mb(ext / "user_default" / "dancenet"),
        "installed_packages": _folder_mb(ext / ".local"),
        "caches": _folder_mb(ext / ".user"),
    }
    out["load_average_1min"] = round(os.getloadavg()[0], 2)
    return out


def first_clicks(archive: Path, repeats: int) -> dict:
    """This interpreter's bpy: the first Generate Dance after a fresh install, clicked at once and after the
    warm-up, each in its own scratch Blender; and what the install put on disk. The Rigify rig clicked at once
    `repeats` times in all (each in a new scratch Blender), since that is the case a busy machine varies most."""
    out: dict = {"python": platform.python_version()}
    with tempfile.TemporaryDirectory(prefix="dancenet-first-click-") as tmp:
        fresh = _build_addon().fresh_bpy(Path(tmp) / "fresh")
        cases = (("clicked_at_once", "0", "new"), ("clicked_after_warm_up", "1", "new"),
                 ("rigify_clicked_at_once", "0", "rigify"), ("rigify_clicked_after_warm_up", "1", "rigify"))
        for case, wait, rig in cases:
            out[case] = _click(Path(tmp), fresh, archive, case, wait, rig)
        again = [_click(Path(tmp), fresh, archive, f"rigify_again_{i}", "0", "rigify") for i in range(repeats - 1)]
        out["rigify_clicked_at_once_all_s"] = [c["first_generate_s"] for c in (out["rigify_clicked_at_once"], *again)]
        out["rigify_clicked_at_once_load_averages"] = [
            c["load_average_1min"] for c in (out["rigify_clicked_at_once"], *again)]
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--dist", type=Path, help="folder with the zips already built (default: build them now)")
    p.add_argument("--pythons", nargs="+", default=[str(REPO / ".venv/bin/python")],
                   help="interpreters of venvs with bpy, one first click each (default: .venv)")
    p.add_argument("--repeats", type=int, default=1,
                   help="first clicks at once on the Rigify rig per interpreter, each in a new Blender (default 1)")
    p.add_argument("--one", type=Path, help=argparse.SUPPRESS)  # internal: first clicks in this interpreter
    args = p.parse_args()
    if args.one:
        print(json.dumps(first_clicks(args.one, args.repeats)))
        return 0
    t = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="dancenet-dist-") as tmp:
        dist = args.dist or Path(tmp)
        if args.dist is None:
            _build_addon().build(dist)
        archive = next(dist.glob("dancenet-*-linux_x64.zip"))
        result: dict = {"sizes": sizes(dist), "strip_s": STRIP_S, "first_click": {}}
        for python in args.pythons:
            run = subprocess.run([python, __file__, "--one", str(archive), "--repeats", str(args.repeats)],
                                 capture_output=True, text=True)
            if run.returncode:
                raise SystemExit(f"{python}: {run.stderr.strip()[-2000:]}")
            one = json.loads(run.stdout.strip().splitlines()[-1])
            result["first_click"][f"bpy {one['clicked_at_once']['bpy']}"] = one
    result |= {"wall_s": round(time.perf_counter() - t, 1), "cpu_count": os.cpu_count(),
               "load_average": [round(x, 2) for x in os.getloadavg()], "machine": platform.machine()}
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

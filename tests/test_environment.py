"""Where things live and how many workers run, as the environment says."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from dancenet_core import environment


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

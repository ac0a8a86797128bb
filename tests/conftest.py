"""Shared test fixtures: where the real data lives (skipped cleanly when it is absent)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def data_root() -> Path:
    return Path(os.environ.get("DANCENET_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def shared_data() -> Path:
    root = data_root()
    if not (root / "dance_with_melody").is_dir():
        pytest.skip(f"real data not found at {root} (set DANCENET_DATA)")
    return root

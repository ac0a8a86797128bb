"""Shared test fixtures: where the real data lives (skipped cleanly when it is absent)."""

from __future__ import annotations

from pathlib import Path

import pytest
from made_up import data_root


@pytest.fixture(scope="session")
def shared_data() -> Path:
    root = data_root()
    if not (root / "dance_with_melody").is_dir():
        pytest.skip(f"real data not found at {root} (set DANCENET_DATA)")
    return root


@pytest.fixture
def one_torch_thread() -> object:
    """Two OpenMP threads on a busy two-core machine are many times slower than one (torch imported here: the
    add-on's tests also run where torch is not installed)."""
    import torch

    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)

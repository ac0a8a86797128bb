"""Shared test fixtures: where the real data lives (skipped cleanly when it is absent), and a suite that runs the
same whatever the caller's environment says about caches and workers."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# Where caches go and how many workers run are the user's settings, not the suite's: a desktop's XDG_CACHE_HOME
# or a developer's DANCENET_CACHE must not change what a test sees. Left out before dancenet_core is imported
# (it reads them on import); DANCENET_DATA stays, it says where the real data is, and NUMBA_CACHE_DIR only
# where compiled code is kept.
CALLER_SETTINGS = ("XDG_CACHE_HOME", "LOCALAPPDATA", "DANCENET_CACHE", "DANCENET_WORKERS")
for _name in CALLER_SETTINGS:
    os.environ.pop(_name, None)
# Run in parallel (pytest-xdist, as scripts/run_tests.sh does), each worker has scratch folders of its own under
# the run's: the default music cache under HOME, and Blender's user folders.
if _worker := os.environ.get("PYTEST_XDIST_WORKER"):
    for _name in ("HOME", "BLENDER_USER_RESOURCES"):
        if os.environ.get(_name):
            os.environ[_name] = os.path.join(os.environ[_name], _worker)
            os.makedirs(os.environ[_name], exist_ok=True)

from made_up import data_root  # noqa: E402  (after the settings above are left out)


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

"""Weights files: written as plain data (tensors, lists, dicts, numbers, strings) and read with
`torch.load(weights_only=True)`, so a crafted file cannot run code; every failure is one line a user can act on.
Files from before this format are converted once with `dancenet weights upgrade FILE...` (same numbers),
which allows only the classes that format held (numpy arrays and numbers, paths), so it runs no code either."""

from __future__ import annotations

import pickle
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import torch

from .atomic import atomic_path
from .errors import DanceNetError, first_line

UPGRADE_HINT = "dancenet weights upgrade"


def to_plain(obj: Any) -> Any:
    """`obj` with numpy arrays as tensors (same dtype and numbers), numpy scalars as numbers, paths as strings
    and tuples as lists: what `weights_only=True` reads back."""
    if isinstance(obj, np.ndarray):
        return torch.from_numpy(np.ascontiguousarray(obj))
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, dict):
        return {k: to_plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [to_plain(v) for v in obj]
    return obj


def save_weights(obj: dict, path: str | Path) -> None:
    """Write `obj` as plain data, atomically."""
    with atomic_path(path) as tmp:
        torch.save(to_plain(obj), tmp)


def load_weights(path: str | Path, what: str, hint: str) -> dict:
    """The dict in the weights file at `path`, read without unpickling arbitrary objects."""
    path = Path(path)
    if not path.is_file():
        raise DanceNetError(f"{what} not found: {path}; {hint}")
    try:
        d = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as e:
        if "Unsupported global" in str(e) and zipfile.is_zipfile(path):
            raise DanceNetError(f"{path} holds objects other than plain weights; if it is DanceNet weights of an "
                                f"older version, convert it with `{UPGRADE_HINT} {path}`") from e
        raise DanceNetError(f"cannot read the {what} {path}: {first_line(e)}") from e
    except (RuntimeError, OSError, EOFError, ValueError, AttributeError, IndexError) as e:
        raise DanceNetError(f"cannot read the {what} {path}: {first_line(e)}") from e
    if not isinstance(d, dict):
        raise DanceNetError(f"{path} is not a {what} file (holds a {type(d).__name__}, not a dict)")
    return d


def read_checkpoint(path: str | Path, fmt: str, what: str, train_hint: str) -> dict:
    """The checkpoint dict at `path` if it exists, loads safely (weights only) and has format `fmt`."""
    ckpt = load_weights(path, what, f"reinstall dancenet or train one with `{train_hint}`")
    if ckpt.get("format") != fmt:
        raise DanceNetError(f"{path} is not a dancenet {what} ({fmt})")
    return ckpt


def _legacy_globals() -> list:
    """What weights files of the old pickled format hold besides tensors and plain data: numpy arrays (with
    their dtypes) and numbers, and paths. Named as those files name them (numpy 1's module paths)."""
    import pathlib

    import numpy.dtypes

    try:
        from numpy._core.multiarray import _reconstruct, scalar
    except ImportError:  # numpy 1
        from numpy.core.multiarray import _reconstruct, scalar
    dtypes = [c for c in vars(numpy.dtypes).values() if isinstance(c, type) and issubclass(c, np.dtype)]
    return [(_reconstruct, "numpy.core.multiarray._reconstruct"), (scalar, "numpy.core.multiarray.scalar"),
            np.ndarray, np.dtype, *dtypes, pathlib.PosixPath, pathlib.WindowsPath]


def upgrade(path: Path) -> None:
    """Re-save a weights file of the old pickled format as plain data (numbers unchanged). Read with only the
    old format's classes allowed, so a crafted file is refused instead of running its code."""
    try:
        with torch.serialization.safe_globals(_legacy_globals()):
            d = torch.load(path, map_location="cpu", weights_only=True)
    except (pickle.UnpicklingError, RuntimeError, OSError, EOFError, ValueError, AttributeError, IndexError) as e:
        raise DanceNetError(f"{path} is not a DanceNet weights file of the old format; not converted "
                            f"({first_line(e, 120)})") from e
    if not isinstance(d, dict):
        raise DanceNetError(f"{path} is not a DanceNet weights file (holds a {type(d).__name__}); not converted")
    save_weights(d, path)

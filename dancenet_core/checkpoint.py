"""Reading the small classifiers' checkpoints with one-line errors a user can act on."""

from __future__ import annotations

import pickle
from pathlib import Path

import torch

from .errors import DanceNetError


def read_checkpoint(path: str | Path, fmt: str, what: str, train_hint: str) -> dict:
    """The checkpoint dict at `path` if it exists, loads safely (weights only) and has format `fmt`."""
    path = Path(path)
    if not path.is_file():
        raise DanceNetError(f"{what} not found: {path}; reinstall dancenet or train one with `{train_hint}`")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except (RuntimeError, OSError, EOFError, pickle.UnpicklingError) as e:
        raise DanceNetError(f"cannot read the {what} {path}: {e}".splitlines()[0]) from e
    if not isinstance(ckpt, dict) or ckpt.get("format") != fmt:
        raise DanceNetError(f"{path} is not a dancenet {what} ({fmt})")
    return ckpt

"""Reading the Dance with Melody set (Tang et al. 2018): 23 marker-derived points, 25 fps, and its songs.

The stored frame is a mirror image; `load_positions` negates x so that the data is right-handed, Y up,
with the joint names' sides true (see the data README).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DanceNetError

POINT_NAMES: tuple[str, ...] = (
    "head_l", "head_r", "pelvis", "l_shoulder", "l_elbow", "l_forearm", "l_wrist", "l_hip", "l_knee",
    "l_ankle", "l_heel", "l_toe", "r_shoulder", "r_elbow", "r_forearm", "r_wrist", "r_hip", "r_knee",
    "r_ankle", "r_heel", "r_toe", "r_forearm_extra", "l_hand_extra",
)  # fmt: skip
P = {n: i for i, n in enumerate(POINT_NAMES)}

STYLE_NAMES = {"C": "cha-cha", "R": "rumba", "T": "tango", "W": "waltz"}


@dataclass(frozen=True)
class Sequence:
    """One row of the manifest: a dance and where it sits in its song."""

    seq: str
    style: str
    frames: int
    fps: float
    music_offset_s: float
    npz: Path
    audio: Path


def dataset_dir(root: str | Path) -> Path:
    root = Path(root)
    d = root / "dance_with_melody" if (root / "dance_with_melody").is_dir() else root
    if not (d / "manifest.csv").is_file():
        raise DanceNetError(
            f"no Dance with Melody manifest.csv under {root}; pass the data folder with --data"
        )
    return d


def read_manifest(root: str | Path) -> list[Sequence]:
    d = dataset_dir(root)
    with open(d / "manifest.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return [
        Sequence(
            seq=r["seq"],
            style=r["style"],
            frames=int(r["frames"]),
            fps=25.0,
            music_offset_s=float(r["music_offset_s"]),
            npz=d / f"{r['seq']}.npz",
            audio=d / f"{r['seq']}.ogg",
        )
        for r in rows
    ]


def load_positions(seq: Sequence) -> np.ndarray:
    """Marker positions [T, 23, 3] in metres, right-handed Y-up (x negated from the stored mirror)."""
    z = np.load(seq.npz)
    pos = z["positions"].astype(np.float64)
    pos[..., 0] *= -1.0
    return pos

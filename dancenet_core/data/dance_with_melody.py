"""Reading the Dance with Melody set (Tang et al. 2018): 23 marker-derived points, 25 fps, and its songs.

Two folders: `dance_with_melody/` (the authors' alignment) and, when present beside it,
`dance_with_melody_extra/` (13 more sequences, tango among them, re-timed from an older export: their
alignment is approximate, about 0.23 s RMS at the end; see that folder's README).

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


@dataclass(frozen=True)
class Recording:
    """One row of the manifest: a dance and where it sits in its song."""

    seq: str
    style: str
    frames: int
    fps: float
    music_offset_s: float
    npz: Path
    audio: Path
    alignment: str = "exact"  # "approximate" for the re-timed extra sequences
    song_s: float = 0.0
    song: str = ""  # the song's identity: sequences danced to the same song share it (split by song)


EXTRA_FOLDER = "dance_with_melody_extra"


def dataset_dir(root: str | Path) -> Path:
    root = Path(root)
    d = root / "dance_with_melody" if (root / "dance_with_melody").is_dir() else root
    if not (d / "manifest.csv").is_file():
        raise DanceNetError(
            f"no Dance with Melody manifest.csv under {root}; pass the data folder with --data"
        )
    return d


def read_manifest(root: str | Path) -> list[Recording]:
    """Every sequence of the set: the main folder's, then the extra folder's when it sits beside it."""
    d = dataset_dir(root)
    folders = [d] + [e for e in (d.parent / EXTRA_FOLDER,) if (e / "manifest.csv").is_file()]
    seqs = []
    for folder in folders:
        with open(folder / "manifest.csv", newline="") as f:
            rows = list(csv.DictReader(f))
        seqs += [
            Recording(
                seq=r["seq"],
                style=r["style"],
                frames=int(r["frames"]),
                fps=25.0,
                music_offset_s=float(r["music_offset_s"]),
                npz=folder / f"{r['seq']}.npz",
                audio=folder / f"{r['seq']}.ogg",
                alignment=r.get("alignment", "exact"),
                song_s=float(r.get("song_s") or 0.0),
                song=f"{r.get('song_s')}:{r.get('cfg_start')}:{r.get('cfg_end')}",
            )
            for r in rows
        ]
    return seqs


def load_positions(seq: Recording) -> np.ndarray:
    """Marker positions [T, 23, 3] in metres, right-handed Y-up (x negated from the stored mirror)."""
    z = np.load(seq.npz)
    pos = z["positions"].astype(np.float64)
    pos[..., 0] *= -1.0
    return pos

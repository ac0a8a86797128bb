"""A training pack: the paired features of the training and validation songs in one compact file.

Why: a lent GPU machine has torch but no madmom, no data folder and room for 64 MiB of carried files; the
built dataset (skeleton fits, both mirror images in float32, joint positions) is several times that. The pack
keeps what training reads (features and mirror images in float16, music, skeleton offsets) and leaves out the
test songs, so `dancenet train dancenet --pack FILE` runs anywhere torch does. float16 keeps 3 significant digits
of each channel: well inside the 0.04 noise training adds to its normalised inputs.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..atomic import atomic_open
from ..errors import DanceNetError
from .build import PairedSequence

PACK_VERSION = "pack-1"


def save_pack(pairs: list[PairedSequence], path: Path, beats_s: dict[str, np.ndarray] | None = None) -> None:
    """Write `pairs` (features in float16) as one compressed file, with the music beats (s, dance time) of
    the sequences in `beats_s` (the validation songs: `dancenet validate --pack` scores rhythm with them)."""
    arrays: dict[str, np.ndarray] = {"version": np.array(PACK_VERSION),
                                     "seqs": np.array([p.seq for p in pairs]),
                                     "styles": np.array([p.style for p in pairs])}
    arrays |= {f"beats_{seq}": np.asarray(b, np.float64) for seq, b in (beats_s or {}).items()}
    for i, p in enumerate(pairs):
        arrays |= {f"{i}_motion": p.motion.astype(np.float16), f"{i}_mirrored": p.mirrored.astype(np.float16),
                   f"{i}_music": p.music.astype(np.float16), f"{i}_offsets": p.offsets,
                   f"{i}_fit": np.array([p.fit_mean_cm, p.fit_p95_cm])}
    with atomic_open(path, "wb") as f:
        np.savez_compressed(f, **arrays)


def load_pack(path: Path) -> list[PairedSequence]:
    """The pairs of a pack (float32 again; no joint positions: training does not read them)."""
    return read_pack(path)[0]


def read_pack(path: Path) -> tuple[list[PairedSequence], dict[str, np.ndarray]]:
    """The pairs of a pack and the beats it holds, by sequence."""
    try:
        z = np.load(path)
        if str(z["version"]) != PACK_VERSION:
            raise DanceNetError(f"{path} is a training pack of another version: make it again with "
                                "`dancenet data pack`")
        pairs = []
        for i, (seq, style) in enumerate(zip(z["seqs"], z["styles"], strict=True)):
            fit = z[f"{i}_fit"]
            pairs.append(PairedSequence(str(seq), str(style), z[f"{i}_motion"].astype(np.float32),
                                        z[f"{i}_mirrored"].astype(np.float32), z[f"{i}_music"].astype(np.float32),
                                        np.zeros((0, 0, 3), np.float32), z[f"{i}_offsets"], float(fit[0]),
                                        float(fit[1])))
        beats = {k.removeprefix("beats_"): z[k] for k in z.files if k.startswith("beats_")}
    except (OSError, KeyError, ValueError) as e:
        raise DanceNetError(f"{path} is not a training pack: make one with `dancenet data pack`") from e
    return pairs, beats

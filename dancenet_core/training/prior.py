"""The motion prior: DanceNet first trained on all the motion there is, without music, then
fine-tuned on the paired dances with `--init`.

Why: the paired data is 71 minutes of four ballroom styles and a continued run trades style for energy within a
few thousand steps; motion without music (the CMU dance clips, 21.5 minutes, beside the training songs' dances)
teaches the body's dynamics before the music's. Every window of the prior reads silence (music features all
zero) and one style, `PRIOR_STYLE`; the fine-tune's styles start from that style's embedding (`warm_start`).
Validation and test songs stay out of the prior as they stay out of training."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ..data.build import PairedSequence, dataset_cache_dir, fitted_clip
from ..data.cmu_dance import read_cmu_manifest

PRIOR_STYLE = "any"


def silent(pairs: list[PairedSequence]) -> list[PairedSequence]:
    """The dances as motion only: music features zero, every one in `PRIOR_STYLE`."""
    return [replace(p, style=PRIOR_STYLE, music=np.zeros_like(p.music)) for p in pairs]


def cmu_motion(data_dir: Path, music_width: int) -> list[PairedSequence]:
    """The CMU dance clips as silent sequences (retargeted once by `dancenet data build`, cached), with music
    features as wide as the dances' so that windows of both stack."""
    out = []
    for clip in read_cmu_manifest(data_dir):
        motion, err, _ = fitted_clip(clip, dataset_cache_dir())
        music = np.zeros((motion.num_frames, music_width), np.float32)
        out.append(PairedSequence.from_motion(f"CMU_{clip.clip}", PRIOR_STYLE, motion, music, err))
    return out


def prior_sequences(train_pairs: list[PairedSequence], data_dir: Path) -> list[PairedSequence]:
    """The prior's sequences: the training songs' dances and every CMU clip, all silent."""
    return silent(train_pairs) + cmu_motion(data_dir, train_pairs[0].music.shape[1])

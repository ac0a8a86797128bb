"""The motion-library engine's row of `dancenet evaluate --library`: the training split's real dances as the library
(cut on the beats of the music they were danced to), dancing to the test-split songs' spans.

Besides the table's columns it measures what issue 25 asks of the engine: the copied runs (share of frames from
runs of one clip longer than `LONG_RUN_BARS` bars, longest run) per dance, and at every cut the largest step of any
joint over the frames the cut blends, against that joint's 99th percentile of frame-to-frame motion in the capture.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..continuation import BLEND_S
from ..data.build import PairedSequence
from ..data.dance_with_melody import read_manifest
from ..library.analysis import analyze_clip
from ..library.choreography import LONG_RUN_BARS, choreograph
from ..library.store import MotionLibrary
from ..music.features import analyze_music
from ..representation import decode
from ..skeleton import BODY_JOINTS, Skeleton


def training_library(pairs: list[PairedSequence], data_dir: Path, skeleton: Skeleton, fps: float) -> MotionLibrary:
    """The training dances (as the table's real rows decode them) cut on their songs' beats and downbeats."""
    seqs = {s.seq: s for s in read_manifest(data_dir)}
    clips = []
    for p in pairs:
        motion = decode(p.motion, fps, skeleton)
        music = analyze_music(seqs[p.seq].audio)
        offset = seqs[p.seq].music_offset_s
        clips.append((p.seq, p.style, motion, analyze_clip(motion, p.style, music.beat_times - offset,
                                                             music.downbeat_times - offset)))
    return MotionLibrary.from_clips(clips)


def step_p99(library: MotionLibrary) -> np.ndarray:
    """Each body joint's 99th percentile of frame-to-frame motion (m) over the library's clips."""
    steps = []
    for c in range(library.num_clips):
        pos = library.clip(c).positions()[:, :BODY_JOINTS]
        steps.append(np.linalg.norm(np.diff(pos, axis=0), axis=-1))
    return np.percentile(np.concatenate(steps), 99, axis=0)


def library_row(train: list[PairedSequence], test: list[PairedSequence], data_dir: Path, skeleton: Skeleton,
                fps: float, takes: int) -> tuple[list, list[str], list[np.ndarray], dict]:
    """Dances (take k with seed k) to every test sequence's song span, their styles and beats (dance time), and the
    engine's own figures: per dance and over all."""
    library = training_library(train, data_dir, skeleton, fps)
    p99 = step_p99(library)
    seqs = {s.seq: s for s in read_manifest(data_dir)}
    blend = int(round(BLEND_S * fps)) + 1
    dances, styles, beats, per_dance = [], [], [], []
    for p in test:
        music = analyze_music(seqs[p.seq].audio)
        start = seqs[p.seq].music_offset_s
        for take in range(takes):
            d = choreograph(library, music, take, start, start + len(p.motion) / fps, style=p.style)[0]
            pos = d.motion.positions()[:, :BODY_JOINTS]
            step = np.linalg.norm(np.diff(pos, axis=0), axis=-1)
            ratio = max((float((step[max(c - 1, 0) : c + blend] / p99).max()) for c in d.report.cuts), default=0.0)
            dances.append(d.motion)
            styles.append(p.style)
            beats.append(music.beat_times - start)
            per_dance.append({"seq": p.seq, "take": take, **d.report.summary(), "transition_step_over_p99": ratio})
    info = {"library_min": round(library.duration_s / 60, 1), "long_run_bars": LONG_RUN_BARS,
            "long_run_share": float(np.mean([r["long_run_share"] for r in per_dance])),
            "longest_run_s": float(max(r["longest_run_s"] for r in per_dance)),
            "max_transition_step_over_p99": float(max(r["transition_step_over_p99"] for r in per_dance)),
            "max_warp": float(max(r["max_warp"] for r in per_dance)), "per_dance": per_dance}
    return dances, styles, beats, info

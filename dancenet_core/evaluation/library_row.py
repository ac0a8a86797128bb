"""The motion-library engine's row of `dancenet evaluate --library`: the training split's real dances as the library
(cut on the beats of the music they were danced to), dancing to the test-split songs' spans.

Besides the table's columns it measures the engine's copying and its cuts: the copied runs (share of frames from
runs of one clip longer than `LONG_RUN_BARS` bars, longest run) per dance, and at every cut the largest step of any
joint over the frames the cut blends (`transitions.cut_window`), against that joint's 99th percentile of
frame-to-frame motion in the capture: the step the cut made (`transitions.cut_steps`: where the source clip itself
steps further than the percentile, over its own step) and, raw, the largest step in the window whatever made it.
The capture itself passes that percentile in about 7% of its frames (some joint of 22), up to about 2.2x, so the
row also gives the share of the frames the cuts blend with a joint over it, next to the capture's own share and
largest step.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..data.build import PairedSequence
from ..data.dance_with_melody import read_manifest
from ..library.analysis import analyze_clip
from ..library.choreography import LONG_RUN_BARS, choreograph
from ..library.store import MotionLibrary
from ..library.transitions import cut_window
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


def library_row(train: list[PairedSequence], test: list[PairedSequence], data_dir: Path, skeleton: Skeleton,
                fps: float, takes: int) -> tuple[list, list[str], list[np.ndarray], dict]:
    """Dances (take k with seed k) to every test sequence's song span, their styles and beats (dance time), and the
    engine's own figures: per dance and over all."""
    library = training_library(train, data_dir, skeleton, fps)
    p99 = library.step_p99
    own = np.delete(library.step_ratios, library.clip_starts[:-1])
    seqs = {s.seq: s for s in read_manifest(data_dir)}
    dances, styles, beats, per_dance, blended = [], [], [], [], []
    for p in test:
        music = analyze_music(seqs[p.seq].audio)
        start = seqs[p.seq].music_offset_s
        for take in range(takes):
            d = choreograph(library, music, take, start, start + len(p.motion) / fps, style=p.style)[0]
            pos = d.motion.positions()[:, :BODY_JOINTS]
            step = (np.linalg.norm(np.diff(pos, axis=0), axis=-1) / p99).max(axis=1)
            near = np.zeros(len(step), bool)
            for c, m in zip(d.report.cuts, d.report.blends, strict=True):
                near[cut_window(c, m, fps)] = True
            blended.append(step[near])
            ratio = float(step[near].max()) if near.any() else 0.0
            dances.append(d.motion)
            styles.append(p.style)
            beats.append(music.beat_times - start)
            per_dance.append({"seq": p.seq, "take": take, **d.report.summary(), "window_step_over_p99": ratio,
                              "cuts_over": int(sum(r > 1.0 for r in d.report.cut_steps))})
    blended = np.concatenate(blended)
    info = {"library_min": round(library.duration_s / 60, 1), "long_run_bars": LONG_RUN_BARS,
            "long_run_share": float(np.mean([r["long_run_share"] for r in per_dance])),
            "longest_run_s": float(max(r["longest_run_s"] for r in per_dance)),
            "max_cut_step": float(max(r["max_cut_step"] for r in per_dance)),
            "cuts": int(sum(r["cuts"] for r in per_dance)), "cuts_over": int(sum(r["cuts_over"] for r in per_dance)),
            "max_window_step_over_p99": float(max(r["window_step_over_p99"] for r in per_dance)),
            "transition_frames_over_p99": float(np.mean(blended > 1.0)) if len(blended) else 0.0,
            "capture_frames_over_p99": float(np.mean(own > 1.0)), "capture_max_step_over_p99": float(own.max()),
            "max_warp": float(max(r["max_warp"] for r in per_dance)), "per_dance": per_dance}
    return dances, styles, beats, info

"""Does a library without style labels dance the song's style? The library's clips with their styles hidden dance
each test song (the library engine's Auto with no labels); the score is the share of the dance's frames from clips
of the song's own style, with the learned match of music and movement (`library/match.py`) and without it (energy
matching alone). Chance is the share of the library's frames of that style."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ..data.build import PairedSequence
from ..data.dance_with_melody import read_manifest
from ..library.choreography import DEFAULT_SETTINGS, Settings, choreograph
from ..library.match import MatchModel
from ..library.store import MotionLibrary
from ..music.features import analyze_music
from ..skeleton import BODY_JOINTS
from .metrics import beat_align_score


def hidden(library: MotionLibrary) -> MotionLibrary:
    """The library with every clip's style label removed (a folder of unsorted downloads)."""
    return dataclasses.replace(library, styles=[""] * library.num_clips)


def own_style_seconds(figures: list[dict], style_of: dict[str, str], style: str) -> tuple[float, float]:
    """Seconds of a dance's figures (its report's rows) from clips of `style`, and of all its figures."""
    spans = [(f["song_s"][1] - f["song_s"][0], style_of[f["clip"]]) for f in figures]
    return sum(s for s, st in spans if st == style), sum(s for s, _ in spans)


def own_style_share(library: MotionLibrary, test: list[PairedSequence], data_dir: Path, fps: float, takes: int,
                    match: MatchModel | None, settings: Settings = DEFAULT_SETTINGS) -> dict:
    """Dances (take k with seed k) from `library` with its labels hidden to each test sequence's song span: the share
    of their frames from clips of the song's style, over all frames, per style (mean of its dances) and per
    dance; `chance`: each style's share of the library's frames; their mean Beat Align Score and share of frames
    from runs of one clip longer than LONG_RUN_BARS bars (the choice of settings weighs these too)."""
    style_of = dict(zip(library.names, library.styles, strict=True))
    frames = np.diff(library.clip_starts)
    chance = {s: float(frames[[t == s for t in library.styles]].sum() / frames.sum()) for s in set(library.styles)}
    unlabelled = hidden(library)
    seqs = {s.seq: s for s in read_manifest(data_dir)}
    per_dance, own_s, total_s = [], 0.0, 0.0
    for p in test:
        music = analyze_music(seqs[p.seq].audio)
        start = seqs[p.seq].music_offset_s
        for take in range(takes):
            d = choreograph(unlabelled, music, take, start, start + len(p.motion) / fps, settings=settings,
                            match=match)[0]
            own, total = own_style_seconds(d.report.figures, style_of, p.style)
            bas = beat_align_score(d.motion.positions()[:, :BODY_JOINTS], fps, music.beat_times - start)
            own_s, total_s = own_s + own, total_s + total
            per_dance.append({"seq": p.seq, "style": p.style, "take": take, "share": round(own / total, 4),
                              "bas": round(bas, 4), "long_run_share": d.report.long_run_share})
    styles = sorted({r["style"] for r in per_dance})
    per_style = {s: round(float(np.mean([r["share"] for r in per_dance if r["style"] == s])), 4) for s in styles}
    return {"share": round(own_s / total_s, 4), "bas": round(float(np.mean([r["bas"] for r in per_dance])), 4),
            "long_run_share": round(float(np.mean([r["long_run_share"] for r in per_dance])), 4),
            "style_mean": round(float(np.mean(list(per_style.values()))), 4),
            "per_style": per_style, "chance": {s: round(chance.get(s, 0.0), 4) for s in styles},
            "per_dance": per_dance}

"""The motion-library engine's rows of `dancenet evaluate --library`, dancing to the test-split songs' spans:

- the users' path: the training split's real dances written as BVH files of our skeleton, one folder per style and
  no music, built as `dancenet library build` builds a user's folder (each clip's beats, tempo and bars read from
  its motion, its style's meter assumed);
- the upper bound: the same dances cut on the beats and downbeats of the music they were danced to, which no
  user's clip has.

Besides the table's columns it measures what the engine is held to: the copied runs (share of frames from runs of
one clip longer than `LONG_RUN_BARS` bars, longest run) per dance, the largest real-time warp played (how much
faster or slower than captured any beat plays), and at every cut the largest step of any joint over the frames the
cut blends (`transitions.cut_window`), against that joint's 99th percentile of frame-to-frame motion in the
capture: the step the cut made (`transitions.cut_steps`: where the source clip itself steps further than the
percentile, over its own step) and, raw, the largest step in the window whatever made it. The capture itself passes
that percentile in about 7% of its frames (some joint of 22), up to about 2.2x, so the row also gives the share of
the frames the cuts blend with a joint over it, next to the capture's own share and largest step.

`clip_analysis` reads every Dance with Melody dance's tempo and meter from its motion (with and without its style)
and scores them against its song's beats: the meter right, the tempo within 8% of the song's or of its half or
double (an octave off the plan dances at speed; anything else it cannot lay on the beats).
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ..bvh import write_bvh
from ..data.build import PairedSequence
from ..data.dance_with_melody import read_manifest
from ..library.analysis import UNSURE, analyze_clip
from ..library.build import build_library
from ..library.choreography import DEFAULT_SETTINGS, LONG_RUN_BARS, Settings, choreograph
from ..library.match import MatchModel
from ..library.store import MotionLibrary
from ..library.transitions import cut_window
from ..motion import Motion
from ..music.features import MusicAnalysis, analyze_music
from ..representation import decode
from ..skeleton import BODY_JOINTS, Skeleton
from .style_share import hidden, own_style_seconds

TEMPO_TOLERANCE = 0.08


def music_library(pairs: list[PairedSequence], data_dir: Path, skeleton: Skeleton, fps: float) -> MotionLibrary:
    """The training dances (as the table's real rows decode them) cut on their songs' beats and downbeats: the
    engine's upper bound."""
    return MotionLibrary.from_clips([
        (p.seq, p.style, motion, analyze_clip(motion, p.style, music.beat_times - offset,
                                              music.downbeat_times - offset))
        for p, motion, music, offset in _with_songs(pairs, data_dir, skeleton, fps)])


def _with_songs(pairs: list[PairedSequence], data_dir: Path, skeleton: Skeleton,
                fps: float) -> Iterator[tuple[PairedSequence, Motion, MusicAnalysis, float]]:
    """Each sequence, its dance decoded as the table's real rows decode it, its song's analysis and where in the
    song the dance starts."""
    seqs = {s.seq: s for s in read_manifest(data_dir)}
    for p in pairs:
        yield p, decode(p.motion, fps, skeleton), analyze_music(seqs[p.seq].audio), seqs[p.seq].music_offset_s


def users_library(pairs: list[PairedSequence], skeleton: Skeleton, fps: float) -> MotionLibrary:
    """The training dances as a user's folder holds clips: BVH files, a folder per style, no music; built by
    `library.build.build_library` (cached by the folder's content, as a user's)."""
    with tempfile.TemporaryDirectory() as tmp:
        for p in pairs:
            (Path(tmp) / p.style).mkdir(exist_ok=True)
            write_bvh(Path(tmp) / p.style / f"{p.seq}.bvh", decode(p.motion, fps, skeleton))
        library, _ = build_library(tmp, report=lambda _line: None)
    return library


def library_row(library: MotionLibrary, test: list[PairedSequence], data_dir: Path, fps: float, takes: int,
                hide_styles: bool = False, match: MatchModel | None = None, settings: Settings = DEFAULT_SETTINGS,
                first_seed: int = 0) -> tuple[list, list[str], list[np.ndarray], dict]:
    """Dances from `library` (take k with seed first_seed + k) to every test sequence's song span, their styles and
    beats (dance time), and the engine's own figures: per dance and over all. `hide_styles`: the library's clips
    danced without their style labels (a folder of unsorted clips), `match` the plan's learned match of music and
    movement; the share of frames from clips of the song's style is measured either way."""
    style_of = dict(zip(library.names, library.styles, strict=True))
    if hide_styles:
        library = hidden(library)
    p99 = library.step_p99
    own = np.delete(library.step_ratios, library.clip_starts[:-1])
    seqs = {s.seq: s for s in read_manifest(data_dir)}
    dances, styles, beats, per_dance, blended = [], [], [], [], []
    for p in test:
        music = analyze_music(seqs[p.seq].audio)
        start = seqs[p.seq].music_offset_s
        for take in range(takes):
            d = choreograph(library, music, first_seed + take, start, start + len(p.motion) / fps, style=p.style,
                            match=match, settings=settings)[0]
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
            figures = d.report.figures
            per_dance.append({"seq": p.seq, "take": take, **d.report.summary(), "window_step_over_p99": ratio,
                              "cuts_over": int(sum(r > 1.0 for r in d.report.cut_steps)),
                              "mean_figure_s": float(np.mean([f["song_s"][1] - f["song_s"][0] for f in figures])),
                              "ratios": sorted({f["ratio"] for f in figures}),
                              "own_style_s": own_style_seconds(figures, style_of, p.style)})
    blended = np.concatenate(blended)
    info = {"library_min": round(library.duration_s / 60, 1), "long_run_bars": LONG_RUN_BARS,
            "long_run_share": float(np.mean([r["long_run_share"] for r in per_dance])),
            "longest_run_s": float(max(r["longest_run_s"] for r in per_dance)),
            "max_cut_step": float(max(r["max_cut_step"] for r in per_dance)),
            "cuts": int(sum(r["cuts"] for r in per_dance)), "cuts_over": int(sum(r["cuts_over"] for r in per_dance)),
            "max_window_step_over_p99": float(max(r["window_step_over_p99"] for r in per_dance)),
            "transition_frames_over_p99": float(np.mean(blended > 1.0)) if len(blended) else 0.0,
            "capture_frames_over_p99": float(np.mean(own > 1.0)), "capture_max_step_over_p99": float(own.max()),
            "max_warp": float(max(r["max_warp"] for r in per_dance)),
            "mean_figure_s": float(np.mean([r["mean_figure_s"] for r in per_dance])),
            "clip_tempo_bpm": [round(float(t), 1) for t in library.tempo_bpm],
            "clip_meter": library.meter.tolist(), "styles_hidden": hide_styles, "match": match is not None,
            "own_style_share": float(sum(r["own_style_s"][0] for r in per_dance)
                                     / sum(r["own_style_s"][1] for r in per_dance)), "per_dance": per_dance}
    return dances, styles, beats, info


def same_tempo(read: float, song: float) -> bool:
    """Within TEMPO_TOLERANCE of the song's tempo, its half or its double."""
    return bool(min(abs(np.log(read / song * k)) for k in (0.5, 1.0, 2.0)) <= np.log1p(TEMPO_TOLERANCE))


def clip_analysis(pairs: list[PairedSequence], data_dir: Path, skeleton: Skeleton, fps: float,
                  test: set[str]) -> dict:
    """Every dance's tempo and meter read from its motion, without and with its style's meter, against its song's
    beats over the part danced (tempo: the median beat interval; meter: the median number of beats between
    downbeats): shares right over all and over the `test` split, and per clip."""
    clips = []
    for p, motion, music, offset in _with_songs(pairs, data_dir, skeleton, fps):
        beats = music.beat_times - offset
        span = (beats >= 0) & (beats <= motion.duration)
        song_bpm = 60.0 / float(np.median(np.diff(beats[span])))
        downs = np.flatnonzero(np.isin(beats[span], music.downbeat_times - offset))
        song_meter = int(np.median(np.diff(downs))) if len(downs) > 1 else 0
        row = {"seq": p.seq, "style": p.style, "song_bpm": round(song_bpm, 1), "song_meter": song_meter}
        for hint, style in (("from_motion", ""), ("with_style", p.style)):
            a = analyze_clip(motion, style)
            row[hint] = {"bpm": round(a.tempo_bpm, 1), "meter": a.meter, "confidence": round(a.confidence, 3),
                         "meter_right": bool(a.meter == song_meter),
                         "tempo_right": bool(same_tempo(a.tempo_bpm, song_bpm))}
        clips.append(row)

    def shares(rows: list[dict]) -> dict:
        return {hint: {"meter_right": float(np.mean([r[hint]["meter_right"] for r in rows])),
                       "tempo_right": float(np.mean([r[hint]["tempo_right"] for r in rows])),
                       "both_right": float(np.mean([r[hint]["meter_right"] and r[hint]["tempo_right"]
                                                    for r in rows]))} for hint in ("from_motion", "with_style")}

    wrong = [r["from_motion"] for r in clips if not (r["from_motion"]["meter_right"]
                                                       and r["from_motion"]["tempo_right"])]
    return {"clips": len(clips), "all": shares(clips), "test_clips": sum(r["seq"] in test for r in clips),
            "unsure_of_wrong": float(np.mean([w["confidence"] < UNSURE for w in wrong])) if wrong else 0.0,
            "test": shares([r for r in clips if r["seq"] in test]), "per_clip": clips}


def library_note(table: dict[str, dict]) -> str:
    """The library rows' own figures under the table (markdown)."""
    out = ""
    for name, what in (("library", "users' path: the training dances as BVH clips without music"),
                       ("library_music", "upper bound: the same dances cut on their music's beats")):
        if name not in table:
            continue
        lib = table[name]
        out += (f"\nMotion library engine ({what}): a library of {lib['library_min']} min; share of frames from runs "
                f"of one clip longer than {lib['long_run_bars']} bars {lib['long_run_share']:.3f} (mean per dance), "
                f"longest run {lib['longest_run_s']:.1f} s; mean figure {lib['mean_figure_s']:.2f} s; largest joint "
                f"step a cut made {lib['max_cut_step']:.2f}x the capture's 99th percentile or its source clip's own "
                f"step there ({lib['cuts_over']} of {lib['cuts']} cuts over 1x; counting the clips' own steps too "
                f"{lib['max_window_step_over_p99']:.2f}x; the capture's own largest: "
                f"{lib['capture_max_step_over_p99']:.2f}x), frames blended at cuts with a joint over it "
                f"{lib['transition_frames_over_p99']:.1%} (the capture's own frames: "
                f"{lib['capture_frames_over_p99']:.1%}); largest real-time warp {lib['max_warp']:.1%}.\n")
    hidden_rows = {name: table[name] for name in ("library_unsorted", "library_unsorted_match") if name in table}
    if hidden_rows:
        out += ("\nThe users' library with its clips' styles hidden (a folder of unsorted clips): share of the dances' "
                "frames from clips of the song's own style, " + "; ".join(
                    f"{'learned match' if name.endswith('match') else 'energy matching alone'} "
                    f"{row['own_style_share']:.1%}" for name, row in hidden_rows.items())
                + (f" (with the labels and the song's style: {table['library']['own_style_share']:.1%})"
                   if "library" in table else "") + ".\n")
    analysis = table.get("library", {}).get("clip_analysis")
    if analysis:
        a, t = analysis["all"], analysis["test"]
        m, w = "from_motion", "with_style"
        out += (f"\nClip analysis from the motion alone ({analysis['clips']} Dance with Melody dances against their "
                f"songs' beats; test split's {analysis['test_clips']} in brackets): meter right "
                f"{a[m]['meter_right']:.0%} ({t[m]['meter_right']:.0%}), tempo within "
                f"{TEMPO_TOLERANCE:.0%} of the song's or its half or double {a[m]['tempo_right']:.0%} "
                f"({t[m]['tempo_right']:.0%}); with the style's meter: meter {a[w]['meter_right']:.0%} "
                f"({t[w]['meter_right']:.0%}), tempo {a[w]['tempo_right']:.0%} ({t[w]['tempo_right']:.0%}); of the "
                f"clips read wrong from the motion alone, {analysis['unsure_of_wrong']:.0%} are named unsure by "
                f"`library build` (confidence under {UNSURE:g}). Per clip and per dance in comparison.json.\n")
    return out

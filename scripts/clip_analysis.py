"""How well `library build` reads a clip's tempo and meter from its motion alone: every Dance with Melody dance
(written as a user's clip, no music) against the beats of the song it was danced to, as `dancenet evaluate
--library` scores it (`evaluation.library_row.clip_analysis`): the meter right, the tempo within 8% of the song's or
of its half or double; from the motion alone and with the style's meter; over all dances, the training split's
(where the reading's weights are chosen) and the test split's. `--without` gives the same shares with some dances
left out as well (dances whose capture's timing against their song is in doubt), never instead of them.

For each dance it also gives how many of its song's beats pass before the dancers come back to a pose, near two of
the song's bars (`two_bar_beats`: the best lag within 30% of two bars, over the whole dance and each half): dancers
who keep to the song's beat come back after two bars, 8 beats (6 in a waltz), their figures being a bar or two
long; a dance that comes back elsewhere through the whole take cannot be read at its song's tempo from its motion.

Whether a dance's capture keeps time with its song at all (`timing`): its two-bar return in 24-s windows every 6 s
along the take, over two of the song's bars there (`two_bar_windows`: median and quartiles over the windows; the
same ratio in every window is a capture time-scaled against its song, a wandering one a dance or beats that drift),
and, for the 43 dances of the data's section 1, the tempo read again with the dance re-timed to the length the
authors' older export of it had
(`older_export`: dance_with_melody_extra/time_mapping_fit.csv's `lenB` frames at 25 fps, where the stored dance was
stretched to `lenA`, its config's music span). `--retime` gives the shares with the named dances so re-timed, beside
the shares as stored, never instead of them: a figure on data mended by hand, not on what a user has.

    .venv/bin/python scripts/clip_analysis.py --without DANCE_C_7 DANCE_C_8 DANCE_C_9 DANCE_T_5 \
        --retime DANCE_C_7 DANCE_C_8 DANCE_C_9 DANCE_T_5

Prints JSON: the shares, the share of wrongly read dances that `library build` names unsure, and each dance read
wrong, with `song_tempo_peak`: the best peak of the reading's score within 8% of its song's tempo, half or double,
over the best score (null: the motion holds no reading of its song's tempo). About 20 s once the dataset and its
songs' analyses are cached.
"""

from __future__ import annotations

import argparse
import csv
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.signal import find_peaks

from dancenet_core.data.build import MODEL_FPS, build_dataset, mean_skeleton
from dancenet_core.data.dance_with_melody import read_manifest
from dancenet_core.data.split import load_split
from dancenet_core.environment import default_data_dir
from dancenet_core.evaluation.library_row import clip_analysis, same_tempo
from dancenet_core.library.analysis import (
    POSE_DIM,
    UNSURE,
    analyze_clip,
    frame_features,
    pose_return,
    rhythm_signals,
    tempo_scores,
)
from dancenet_core.motion import Motion
from dancenet_core.music.features import analyze_music
from dancenet_core.representation import decode
from dancenet_core.skeleton import BODY_JOINTS

HINTS = ("from_motion", "with_style")
OLDER_EXPORT = Path("dance_with_melody_extra") / "time_mapping_fit.csv"  # per dance: lenA (stored), lenB (older)
WINDOW_S, HOP_S = 24.0, 6.0  # the two-bar return along the take


def shares(rows: list[dict]) -> dict:
    """Dances counted right of those in `rows`, per hint: meter, tempo, both (counts and shares)."""
    out: dict = {"dances": len(rows)}
    for hint in HINTS:
        meter = sum(r[hint]["meter_right"] for r in rows)
        tempo = sum(r[hint]["tempo_right"] for r in rows)
        both = sum(r[hint]["meter_right"] and r[hint]["tempo_right"] for r in rows)
        out[hint] = {"meter_right": f"{meter}/{len(rows)} ({meter / max(len(rows), 1):.1%})",
                     "tempo_right": f"{tempo}/{len(rows)} ({tempo / max(len(rows), 1):.1%})",
                     "both_right": f"{both}/{len(rows)} ({both / max(len(rows), 1):.1%})"}
    return out


def two_bar_beats(pose: np.ndarray, beat: float, meter: int) -> float:
    """Song beats between the dancers' returns to a pose near two of the song's bars: the lag, within 30% of two bars
    (`meter` beats of `beat` frames each), at which the whole body's pose comes back best, over `beat`."""
    lo, hi = int(0.7 * 2 * meter * beat), int(np.ceil(1.3 * 2 * meter * beat))
    back, _ = pose_return(pose, min(len(pose), hi + 1), joints=range(BODY_JOINTS))
    return float((lo + int(np.argmax(back[lo : hi + 1]))) / beat) if len(back) > lo else float("nan")


def two_bar_windows(pose: np.ndarray, song_beats: np.ndarray, meter: int, fps: float) -> list[float]:
    """`two_bar_beats` over two of the song's bars in each window of `WINDOW_S` every `HOP_S` along the take, the
    song's beat (`song_beats`: seconds into the dance) taken in that window: 1 where the dancers keep its tempo."""
    win, out = int(WINDOW_S * fps), []
    for start in range(0, max(len(pose) - win, 0) + 1, int(HOP_S * fps)):
        here = song_beats[(song_beats >= start / fps) & (song_beats <= (start + win) / fps)]
        if len(here) > 3:
            out.append(round(two_bar_beats(pose[start : start + win], float(np.median(np.diff(here))) * fps, meter)
                             / (2 * meter), 3))
    return out


def song_tempo_peak(motion: Motion, song_bpm: float, meter: int) -> float | None:
    """The best local maximum of the analysis's score (`tempo_scores`, the song's meter) within 8% of the song's
    tempo, its half or double, over the best score: whether the motion holds a reading of the song's tempo at all
    (None: no such peak)."""
    feats, speed, feet, height = frame_features(motion)
    periods, scores = tempo_scores(feats[:, :POSE_DIM], rhythm_signals(speed, feet, height, motion.fps), motion.fps)
    score = scores[meter if meter in scores else 4]
    near = [k for k in find_peaks(score)[0] if same_tempo(motion.fps * 60.0 / periods[k], song_bpm)]
    return round(float(score[near].max() / score.max()), 3) if near else None


def retimed(motion: Motion, scale: float) -> Motion:
    """`motion` played `scale` times as long, at its own frame rate."""
    return replace(motion, fps=motion.fps / scale).resampled(motion.fps)


def reading(motion: Motion, style: str, song_bpm: float, song_meter: int) -> dict:
    """One reading of `motion`'s tempo and meter scored as `clip_analysis` scores it."""
    a = analyze_clip(motion, style)
    return {"bpm": round(a.tempo_bpm, 1), "meter": a.meter, "confidence": round(a.confidence, 3),
            "meter_right": bool(a.meter == song_meter), "tempo_right": bool(same_tempo(a.tempo_bpm, song_bpm))}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--without", nargs="*", default=[], help="dances to leave out of a second set of shares")
    p.add_argument("--retime", nargs="*", default=[],
                   help="dances read again at their older export's timing for a third set of shares")
    args = p.parse_args()
    data = default_data_dir()
    split = load_split()
    pairs = build_dataset(data, progress=False)
    older = {r["seq"]: int(r["lenB"]) for r in csv.DictReader((data / OLDER_EXPORT).open())}
    unknown = sorted((set(args.without) | set(args.retime)) - {q.seq for q in pairs})
    if unknown:
        raise SystemExit(f"no dance {', '.join(unknown)} in {data}; name dances as DANCE_C_8")
    if set(args.retime) - set(older):
        raise SystemExit(f"no older export of {', '.join(sorted(set(args.retime) - set(older)))} in "
                         f"{OLDER_EXPORT}: --retime takes the data's section 1 dances")
    result = clip_analysis(pairs, data, mean_skeleton(pairs), MODEL_FPS, set(split["test"]))
    clips = result["per_clip"]
    parts = {"all": clips, "train": [r for r in clips if r["seq"] in set(split["train"])],
             "test": [r for r in clips if r["seq"] in set(split["test"])]}
    out = {name: shares(rows) for name, rows in parts.items()}
    if args.without:
        out[f"all without {', '.join(args.without)}"] = shares([r for r in clips if r["seq"] not in args.without])
    skeleton = mean_skeleton(pairs)
    songs = {s.seq: s for s in read_manifest(data)}
    mended = []
    for q, r in zip(pairs, clips, strict=True):
        motion = decode(q.motion, MODEL_FPS, skeleton)
        pose = frame_features(motion)[0][:, :POSE_DIM]
        beat = MODEL_FPS * 60.0 / r["song_bpm"]
        meter = r["song_meter"] or 4
        half = len(pose) // 2
        r["two_bar_beats"] = [round(two_bar_beats(x, beat, meter), 2) for x in (pose, pose[:half], pose[half:])]
        song_beats = analyze_music(songs[q.seq].audio).beat_times - songs[q.seq].music_offset_s
        r["two_bar_windows"] = two_bar_windows(pose, song_beats, meter, MODEL_FPS)
        if not all(r[h]["meter_right"] and r[h]["tempo_right"] for h in HINTS):
            r["song_tempo_peak"] = song_tempo_peak(motion, r["song_bpm"], meter)
        if q.seq in older:
            scale = older[q.seq] / len(pose)
            slow = retimed(motion, scale)
            here = song_beats[(song_beats >= 0) & (song_beats <= slow.duration)]
            bpm = 60.0 / float(np.median(np.diff(here)))
            again = {h: reading(slow, style, bpm, r["song_meter"])
                     for h, style in zip(HINTS, ("", q.style), strict=True)}
            r["older_export"] = {"length_over_stored": round(scale, 3), "song_bpm": round(bpm, 1),
                                 "bpm": again["from_motion"]["bpm"],
                                 "ratio": round(again["from_motion"]["bpm"] / bpm, 3),
                                 "tempo_right": again["from_motion"]["tempo_right"]}
            if q.seq in args.retime:
                mended.append({**r, **again})
                continue
        mended.append(r)
    if args.retime:
        out[f"all with {', '.join(args.retime)} at their older export's timing"] = shares(mended)
    out["timing"] = {r["seq"]: {"two_bar_windows": "{:.3f} ({:.3f}-{:.3f})".format(
                                    *np.percentile(r["two_bar_windows"], [50, 25, 75])),
                                **({"older_export": r["older_export"]} if "older_export" in r else {})}
                     for r in clips if r["two_bar_windows"]}
    out["two_bar_beats"] = {st: {r["seq"]: r["two_bar_beats"] for r in clips if r["style"] == st}
                            for st in sorted({r["style"] for r in clips})}
    wrong = [r for r in clips if not all(r[h]["meter_right"] and r[h]["tempo_right"] for h in HINTS)]
    free_wrong = [r for r in clips if not (r["from_motion"]["meter_right"] and r["from_motion"]["tempo_right"])]
    out["unsure_of_wrong_from_motion"] = (f"{sum(r['from_motion']['confidence'] < UNSURE for r in free_wrong)}"
                                          f"/{len(free_wrong)}")
    out["read_wrong"] = [{"seq": r["seq"], "style": r["style"], "song_bpm": r["song_bpm"],
                          "song_meter": r["song_meter"], "song_tempo_peak": r["song_tempo_peak"],
                          **{h: {"bpm": r[h]["bpm"], "meter": r[h]["meter"], "confidence": r[h]["confidence"],
                                 "ratio": round(float(np.float64(r[h]["bpm"]) / r["song_bpm"]), 3)}
                             for h in HINTS}} for r in wrong]
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()

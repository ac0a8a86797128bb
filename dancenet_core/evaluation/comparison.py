"""`dancenet evaluate`: the paper's comparison (Tables 3 and 4) on the test split, from this command's own runs.

1. Train every model of `nets/variants.py` on the training split with the same windows and the same
   number of steps (each in its own process, `--jobs` at a time; a finished run with the same settings is
   reused, so a second call only measures).
2. Each model dances to the music spans of the test-split sequences (`--takes` seeds each, from the real
   dance's first frame, in its style), as do the shipped DanceNet weights, with and without the foot clean-up.
3. Every dance is cut into 10-s segments. Realism: FID of their kinetic and geometric features (AIST++) and
   of the motion-style classifier's features (the paper's FID) against the real dances of the training
   split; diversity: mean distance between segments in the same spaces; rhythm: Beat Align Score and the
   paper's hit rate; feet: PFC and the sliding ratio; style consistency: the classifier's accuracy on the
   requested style. The real test dances are measured the same way (the first row).

Writes `comparison.md`, `comparison.json`, `figure_3b.png` (the music's onset envelope over the dance's
kinematic velocity, as the paper's Figure 3b) and `contact_sheet.png` (the same 20 s of a test waltz, the real
dance above the shipped model's with the foot clean-up below) into `--out`.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass, field
from itertools import product
from pathlib import Path

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..atomic import write_text
from ..beats import BAS_SMOOTH_S, kinematic_velocity, motion_beats
from ..checkpoint import load_weights
from ..constants import DEFAULT_TEMPERATURE
from ..data.build import with_mel_music
from ..engines.dancenet import FOOT_CLEANUP
from ..environment import default_data_dir
from ..errors import DanceNetError
from ..library.match import MatchModel
from ..motion import Motion
from ..nets.bundle import DEFAULT_BUNDLE, DanceNetBundle
from ..nets.variants import VARIANTS, music_features
from ..plotting import pyplot
from ..render import contact_sheet
from ..representation import decode
from ..skeleton import BODY_JOINTS
from . import drift
from .dance_features import geometric_features, kinetic_features, smpl24_positions
from .form import danced_again, mean_likeness, song_forms
from .library_row import clip_analysis, library_note, library_row, music_library, users_library
from .metrics import (
    body_relative_segments,
    diversity,
    fid,
    nearest_segment_distance,
    own_song_bas_ratio,
    physical_foot_contact,
)
from .motion_style import MotionStyleModel
from .test_split import dance_metrics, generate_for_pair, split_with_beats

SEGMENT_S = 10.0
COLUMNS: dict[str, str] = {
    "fid_k": "FID_k", "fid_g": "FID_g", "fid_style": "FID (style net)", "div_k": "Div_k", "div_g": "Div_g",
    "div_style": "Div (style net)", "beat_align_score": "BAS", "bas_own_ratio": "BAS own/other songs",
    "rhythm_hit_rate": "Rhythm hit",
    "pfc": "PFC", "foot_slide_ratio": "Foot slide", "jitter_m_s2": "Jitter (m/s²)",
    "longest_freeze_s": "Longest freeze (s)", "style_consistency": "Style consistency",
    "root_extent_m": "Root extent (m)", "joint_speed_m_s": "Joint speed (m/s)", "floor_reach": "Floor reach",
    "replay_m": "To nearest training 5 s (m)",
}  # fmt: skip
LOWER_IS_BETTER = {"fid_k", "fid_g", "fid_style", "pfc", "foot_slide_ratio", "longest_freeze_s"}


@dataclass
class DanceSet:
    """One row of the table: dances with the style asked for and the beats of the music each was danced to."""

    name: str
    label: str
    dances: list[Motion] = field(default_factory=list)
    styles: list[str] = field(default_factory=list)
    beats_s: list[np.ndarray] = field(default_factory=list)
    info: dict = field(default_factory=dict)
    songs: list[str] = field(default_factory=list)  # the sequence whose song each dance was danced to

    def only(self, keep: list[int], name: str | None = None) -> DanceSet:
        """The row of the dances at `keep` alone (a pair of takes, for the take-to-take spread)."""
        return DanceSet(name or self.name, self.label, [self.dances[i] for i in keep],
                        [self.styles[i] for i in keep], [self.beats_s[i] for i in keep], {},
                        [self.songs[i] for i in keep] if self.songs else [])


def segments(positions: np.ndarray, fps: float, seconds: float = SEGMENT_S) -> list[np.ndarray]:
    """Non-overlapping segments of `seconds` (a shorter tail is dropped)."""
    n = int(round(seconds * fps))
    return [positions[s : s + n] for s in range(0, len(positions) - n + 1, n)]


def segment_features(dances: list[np.ndarray], styles: list[str], fps: float, style_net: MotionStyleModel) -> dict:
    """Per-segment kinetic, geometric and style-net features, and whether the net names the segment's style."""

    kin, geo, emb, hit = [], [], [], []
    for pos, style in zip(dances, styles, strict=True):
        for seg in segments(pos, fps):
            p24 = smpl24_positions(seg)
            kin.append(kinetic_features(p24, fps))
            geo.append(geometric_features(p24, fps))
            e, probs = style_net.describe(seg, fps)
            emb.append(e)
            hit.append(style_net.styles[int(np.argmax(probs))] == style)
    return {"k": np.stack(kin), "g": np.stack(geo), "style": np.stack(emb), "hit": np.array(hit)}


def measure(rows: list[DanceSet], reference: dict, fps: float, style_net: MotionStyleModel,
            forms: dict | None = None) -> dict[str, dict]:
    """Every column of the table for every row; FIDs and diversities in the reference set's normalisation;
    `reference["library"]` (body-relative 5-s segments of the training dances) gives the replay column; `forms`
    (each song's form and the dance's start in it) the return likeness of the rows that name their songs."""

    table = {}
    for row in rows:
        positions = [m.positions() for m in row.dances]
        feats = segment_features(positions, row.styles, fps, style_net)
        per_dance = [dance_metrics(m, b) | {"pfc": physical_foot_contact(p, fps)}
                     for m, p, b in zip(row.dances, positions, row.beats_s, strict=True)]
        r = {k: float(np.mean([d[k] for d in per_dance])) for k in per_dance[0]}
        for key in ("k", "g", "style"):
            # A feature constant over the reference (some geometric relations never hold in ballroom) has
            # std 0 and would blow Bailando's normalisation up to ~1e20: such features are left out.
            keep = reference[key].std(axis=0) > 1e-6
            r[f"fid_{key}"] = fid(reference[key][:, keep], feats[key][:, keep])
            r[f"div_{key}"] = diversity(feats[key][:, keep], reference=reference[key][:, keep])
        r["style_consistency"] = float(feats["hit"].mean())
        r["bas_own_ratio"] = own_song_bas_ratio(positions, fps, row.beats_s)
        r["floor_reach_by_style"] = {s: float(np.mean([d["floor_reach"] for d, ds in zip(per_dance, row.styles,
                                                                                             strict=True) if ds == s]))
                                     for s in sorted(set(row.styles))}
        segs = np.concatenate([body_relative_segments(p[:, :BODY_JOINTS], fps, hop_s=2.0) for p in positions])
        r["replay_m"] = float(np.median(nearest_segment_distance(segs, reference["library"])))
        r["segments"] = int(len(feats["hit"]))
        if forms and row.songs:
            r["return_likeness"] = mean_likeness(row.dances, positions, row.songs, forms)
        table[row.name] = r | {"label": row.label, **row.info}
    return table


def reference_features(train_dances: list[np.ndarray], fps: float, style_net: MotionStyleModel) -> dict:
    """What every row is measured against: the training dances' segment features and their 5-s library."""

    feats = segment_features(train_dances, ["?"] * len(train_dances), fps, style_net)
    feats["library"] = np.concatenate([body_relative_segments(p[:, :BODY_JOINTS], fps, hop_s=0.4)
                                       for p in train_dances])
    return feats


# ------------------------------------------------------------------------------------------ training


def run_dir(runs: Path, variant: str) -> Path:
    return runs / variant


def trained(runs: Path, variant: str, steps: int, seed: int) -> bool:
    """A finished run of `variant` with these settings exists (so it is measured, not retrained)."""
    path = run_dir(runs, variant) / "dancenet.pt"
    if not path.is_file():
        return False

    info = load_weights(path, "DanceNet weights", "train it again")["info"]
    return info.get("steps") == steps and info["settings"]["seed"] == seed and info.get("variant") == variant


POLL_S = 5.0  # how often the training processes are looked at


def train_variants(variants: list[str], runs: Path, steps: int, seed: int, jobs: int, data: Path | None) -> None:
    """Train the missing runs, `jobs` processes at a time (one thread each), logs next to the runs. When one
    fails (or this process is interrupted) the others are stopped: their runs resume from their checkpoints."""
    todo = [v for v in variants if not trained(runs, v, steps, seed)]
    for v in variants:
        if v not in todo:
            print(f"  {v}: trained run found in {run_dir(runs, v)}, reused")
    env = os.environ | {"OMP_NUM_THREADS": "1"}
    running: list[tuple[str, subprocess.Popen]] = []
    try:
        while todo or running:
            while todo and len(running) < jobs:
                v = todo.pop(0)
                out = run_dir(runs, v)
                out.mkdir(parents=True, exist_ok=True)
                cmd = [sys.executable, "-m", "dancenet_core.cli", "train", "dancenet", "--variant", v, "--steps",
                       str(steps), "--minutes", "1e9", "--seed", str(seed), "--out", str(out), "--resume"]
                if data:
                    cmd += ["--data", str(data)]
                print(f"  {v}: training {steps} steps -> {out} (log {out}.log)")
                with open(f"{out}.log", "a") as log:  # the process has its own copy
                    running.append((v, subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)))
            time.sleep(POLL_S)
            for v, proc in list(running):
                if proc.poll() is not None:
                    running.remove((v, proc))
                    if proc.returncode:
                        raise DanceNetError(f"training {v} failed (exit {proc.returncode}); see {run_dir(runs, v)}.log")
                    print(f"  {v}: trained")
    finally:
        for _v, proc in running:
            proc.kill()
            proc.wait()


# ------------------------------------------------------------------------------------------ dancing


def dance_row(name: str, label: str, bundle: DanceNetBundle, test_pairs: list, beats: dict, takes: int,
              temperature: float, footfix: bool = False, smoothing: float | None = None,
              footfix_weights: Path | None = None, cleanup: str = FOOT_CLEANUP, beat_lock: bool = False) -> DanceSet:
    """`takes` dances per test sequence by the model in `bundle` (take k samples with seed k), locked to their
    song's beats when `beat_lock`, feet cleaned by `cleanup` when `footfix`."""
    row = DanceSet(name, label, info={"steps": bundle.info.get("steps"),
                                      "train_minutes": round(bundle.info.get("train_seconds", 0) / 60, 1)})
    for pair in test_pairs:
        for take in range(takes):
            row.dances.append(generate_for_pair(bundle, pair, take, temperature, footfix, smoothing,
                                                footfix_weights, cleanup, beats[pair.seq] if beat_lock else None)[0])
            row.styles.append(pair.style)
            row.beats_s.append(beats[pair.seq])
    return row


def figure_3b(path: Path, music: np.ndarray, beats_s: np.ndarray, real: np.ndarray, generated: np.ndarray,
              fps: float, title: str, seconds: float = 20.0) -> None:
    """The music's onset envelope and beats over the kinematic velocity of the real and the generated dance."""
    plt = pyplot()
    n = min(int(seconds * fps), len(real), len(generated))
    t = np.arange(n) / fps
    fig, axes = plt.subplots(2, 1, figsize=(10, 4.5), sharex=True)
    for ax, pos, name in ((axes[0], real, "real dance"), (axes[1], generated, "DanceNet")):
        v = gaussian_filter1d(kinematic_velocity(pos[:n, :BODY_JOINTS]) * fps, BAS_SMOOTH_S * fps)
        onset = music[:n, 14]
        ax.plot(t, onset / max(onset.max(), 1e-9), color="tab:orange", lw=1, label="music onset strength")
        ax.plot(t, v / max(v.max(), 1e-9), color="tab:blue", lw=1.5, label=f"{name}: kinematic velocity")
        for b in motion_beats(pos[:n, :BODY_JOINTS], fps):
            ax.axvline(b / fps, color="tab:blue", alpha=0.25, lw=0.8)
        beats = beats_s[(beats_s >= 0) & (beats_s < n / fps)]
        ax.plot(beats, np.full(len(beats), 1.05), "v", color="tab:orange", ms=4, label="music beats")
        ax.set_ylabel("normalised")
        ax.legend(loc="upper right", fontsize=8)
    axes[0].set_title(title)
    axes[1].set_xlabel("seconds (vertical lines: dance beats = velocity minima; triangles: music beats)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def markdown(table: dict[str, dict], seconds: float, steps: int, takes: int, segments_ref: int) -> str:
    lines = [
        "| model | " + " | ".join(COLUMNS.values()) + " | steps | train min |",
        "|---|" + "---|" * (len(COLUMNS) + 2),
    ]
    for r in table.values():
        cells = [f"{r[k]:.3f}" if abs(r[k]) < 10 else f"{r[k]:.1f}" for k in COLUMNS]
        lines.append(f"| {r['label']} | " + " | ".join(cells)
                     + f" | {r.get('steps') or '-'} | {r.get('train_minutes') or '-'} |")
    styles = sorted({s for r in table.values() for s in r["floor_reach_by_style"]})
    lines += ["", "Floor reach by style (share of 2-s windows whose lowest toe end comes within 1.5 cm of the floor):",
              "", "| model | " + " | ".join(styles) + " |", "|---|" + "---|" * len(styles)]
    lines += [f"| {r['label']} | " + " | ".join(f"{r['floor_reach_by_style'][s]:.2f}" if s in r["floor_reach_by_style"]
                                                else "-" for s in styles) + " |" for r in table.values()]
    alike = [r for r in table.values() if r.get("return_likeness") is not None]
    if alike:
        lines += ["", "Where the music returns: the pose distance between occurrences of a section of the song's "
                  "form over that between different sections (0: danced again exactly; about 1: no more alike "
                  "than different sections):", "", "| model | return likeness |", "|---|---|"]
        lines += [f"| {r['label']} | {r['return_likeness']:.2f} |" for r in alike]
    lines += [
        "",
        "BAS own/other songs: each dance's Beat Align Score against its own song's beats over its score against "
        "the other songs' beats of the set (a dance that ignores its song scores about 1).",
        "",
        f"Lower is better for {', '.join(COLUMNS[k] for k in sorted(LOWER_IS_BETTER))}; higher for the rest "
        "(Jitter: closest to the real dances). FIDs and diversities are computed on 10-s segments against the "
        f"{segments_ref} segments of the training split's real dances; {takes} take(s) per test sequence; "
        f"every compared model trained {steps} steps on the same windows. Produced by `dancenet evaluate` in "
        f"{seconds / 60:.1f} minutes.",
    ]
    return "\n".join(lines) + "\n"


def _variants(args: argparse.Namespace) -> list[str]:
    """The compared models the command line asks for (none with --library-only), checked by name."""
    variants = [] if args.library_only else list(VARIANTS) if args.variants is None else args.variants
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown:
        raise DanceNetError(f"unknown model(s) {', '.join(unknown)}; choose from {', '.join(VARIANTS)}")
    return variants


def _dancenet_rows(args: argparse.Namespace, variants: list[str], test_pairs: list, data: Path, beats: dict,
                   shipped: DanceNetBundle, temperature: float) -> list[DanceSet]:
    """The trained models' dances, then the shipped weights' as generation dances (locked to the beats) with and
    without the foot clean-up, and with the clean-up but not the beat lock."""
    rows = []
    mel_pairs = None
    for v in variants:
        bundle = DanceNetBundle.load(run_dir(args.runs, v) / "dancenet.pt")
        tp = test_pairs
        if music_features(v) == "mel":
            mel_pairs = mel_pairs or {p.seq: p for p in with_mel_music(test_pairs, data)}
            tp = [mel_pairs[p.seq] for p in test_pairs]
        rows.append(dance_row(v, VARIANTS[v], bundle, tp, beats, args.takes, temperature))
        print(f"  {v}: {len(rows[-1].dances)} dances")
    if not args.library_only:
        rows.append(dance_row("dancenet_shipped", "DanceNet, shipped weights", shipped, test_pairs, beats,
                              args.takes, temperature, beat_lock=True))
        rows.append(dance_row("dancenet_shipped_footfix", f"DanceNet, shipped weights + foot clean-up ({FOOT_CLEANUP})",
                              shipped, test_pairs, beats, args.takes, temperature, footfix=True, beat_lock=True))
        rows.append(dance_row("dancenet_shipped_footfix_unlocked", f"DanceNet, shipped weights + foot clean-up "
                              f"({FOOT_CLEANUP}), no beat lock", shipped, test_pairs, beats, args.takes, temperature,
                              footfix=True))
    return rows


def _library_rows(args: argparse.Namespace, pairs: dict, split: dict, test_pairs: list, data: Path,
                  shipped: DanceNetBundle, fps: float) -> list[DanceSet]:
    """The motion library engine's dances: the users' path, clips cut on their music's beats, and the clips'
    styles hidden (energy alone, the learned match); the users' row carries the clip analysis' check."""
    rows = []
    train_pairs = [p for p in pairs.values() if p.seq in set(split["train"])]
    users = users_library(train_pairs, shipped.skeleton, fps)
    for name, label, library, hide, match in (
            ("library", "Motion library engine (users' path: training dances as BVH, no music)", users, False,
             None),
            ("library_music", "Motion library engine, clips cut on their music's beats (upper bound)",
             music_library(train_pairs, data, shipped.skeleton, fps), False, None),
            ("library_unsorted", "Motion library engine, users' path, clips' styles hidden: energy alone", users,
             True, None),
            ("library_unsorted_match", "Motion library engine, users' path, clips' styles hidden: learned match",
             users, True, MatchModel.load())):
        row = DanceSet(name, label)
        row.dances, row.styles, row.beats_s, row.info = library_row(library, test_pairs, data, fps, args.takes,
                                                                    hide, match)
        rows.append(row)
        print(f"  {name}: {len(row.dances)} dances", flush=True)
    rows[0].info["clip_analysis"] = clip_analysis(list(pairs.values()), data, shipped.skeleton, fps,
                                                  set(split["test"]))
    return rows


def _with_returns(rows: list[DanceSet], test_pairs: list, data: Path, takes: int) -> dict:
    """Each row told its songs, and the default rows again with their returning sections danced again; the
    songs' forms."""
    forms = song_forms(test_pairs, data)
    rows[0].songs = [p.seq for p in test_pairs]
    for row in rows[1:]:
        row.songs = [p.seq for p in test_pairs for _ in range(takes)]
    for name in ("dancenet_shipped_footfix", "library"):  # the defaults: returning sections danced again
        row = next((r for r in rows if r.name == name), None)
        if row is not None:
            rows.append(DanceSet(f"{name}_returns", f"{row.label}, returns danced again (the default)",
                                 danced_again(row.dances, row.songs, forms), row.styles, row.beats_s, {}, row.songs))
    return forms


def _pictures(out: Path, test_pairs: list, rows: list[DanceSet], takes: int, fps: float) -> None:
    """Figure 3b and the contact sheet on the first test waltz (else the first test sequence)."""
    real = rows[0]
    i = next((i for i, p in enumerate(test_pairs) if p.style == "waltz"), 0)
    gen_row = next(r for r in rows if r.name == "dancenet_shipped")
    figure_3b(out / "figure_3b.png", test_pairs[i].music, real.beats_s[i], real.dances[i].positions(),
              gen_row.dances[i * takes].positions(), fps, f"{test_pairs[i].seq} ({test_pairs[i].style})")
    foot_row = next(r for r in rows if r.name == "dancenet_shipped_footfix")
    first_20s = slice(0, int(20 * fps))
    contact_sheet([(f"real {test_pairs[i].seq}", real.dances[i][first_20s]),
                   ("DanceNet", foot_row.dances[i * takes][first_20s])],
                  out / "contact_sheet.png", cols=6, rows=2, width=240, height=200)


def compare(args: argparse.Namespace) -> int:
    """`dancenet evaluate` (this module's docstring): train what is missing, dance, measure, write the table."""
    t0 = time.perf_counter()
    data = args.data or default_data_dir()
    if not data.is_dir():
        raise DanceNetError(f"no dataset at {data}; pass --data DIR (the shared data folder)")
    variants = _variants(args)
    temperature = DEFAULT_TEMPERATURE if args.temperature is None else args.temperature
    if variants:
        print(f"training {len(variants)} models ({args.steps} steps each, {args.jobs} at a time)")
        train_variants(variants, args.runs, args.steps, args.seed, args.jobs, args.data)

    print("dancing to the test songs and measuring")
    split, pairs, beats = split_with_beats(data)
    style_net = MotionStyleModel.load()
    test_pairs = [pairs[s] for s in split["test"] if pairs[s].style in style_net.styles]
    fps = 25.0
    shipped = DanceNetBundle.load(DEFAULT_BUNDLE)
    real = DanceSet("real", "Real dances (test split)")
    real.dances = [decode(p.motion, fps, shipped.skeleton) for p in test_pairs]
    real.styles = [p.style for p in test_pairs]
    real.beats_s = [beats[p.seq] for p in test_pairs]
    train_dances = [decode(p.motion, fps, shipped.skeleton).positions()
                    for p in pairs.values() if p.seq in set(split["train"]) and p.style in style_net.styles]
    ref_feats = reference_features(train_dances, fps, style_net)

    rows = [real, *_dancenet_rows(args, variants, test_pairs, data, beats, shipped, temperature)]
    if args.library or args.library_only:
        rows += _library_rows(args, pairs, split, test_pairs, data, shipped, fps)
    forms = _with_returns(rows, test_pairs, data, args.takes)
    table = measure(rows, ref_feats, fps, style_net, forms)

    args.out.mkdir(parents=True, exist_ok=True)
    seconds = time.perf_counter() - t0
    md = markdown(table, seconds, args.steps, args.takes, len(ref_feats["hit"]))
    md += library_note(table)
    write_text(args.out / "comparison.md", md)
    write_text(args.out / "comparison.json", json.dumps(
        {"seconds": seconds, "steps": args.steps, "takes": args.takes, "temperature": temperature,
         "seed": args.seed, "test_sequences": [p.seq for p in test_pairs], "reference_segments":
         len(ref_feats["hit"]), "rows": table}, indent=1) + "\n")
    print(md)
    if args.library_only:
        return 0
    _pictures(args.out, test_pairs, rows, args.takes, fps)
    print(f"wrote {args.out / 'comparison.md'}, comparison.json, figure_3b.png, contact_sheet.png "
          f"({seconds / 60:.1f} min)")
    return 0


def validate(args: argparse.Namespace) -> int:
    """`dancenet validate`: DanceNet's sampling settings scored on the split's validation songs (training songs
    that `train --validation` leaves out), never on the test songs: every weights file x temperature x output
    smoothing dances to them (foot clean-up and beat lock on, as shipped; `--beat-lock on off`: both) and is
    measured as `evaluate` measures, against the real validation dances and the dances the models trained on."""
    t0 = time.perf_counter()
    if not args.weights and not args.curve:
        raise DanceNetError("give the DanceNet weights files to compare, or --curve RUN for a run's learning curve")
    data = args.data or default_data_dir()
    split, pairs, beats = split_with_beats(data, part="validation", pack=args.pack)
    if not split.get("validation"):
        raise DanceNetError("the song split names no validation songs (weights/song_split.json)")
    style_net = MotionStyleModel.load()
    val = [pairs[s] for s in split["validation"]]
    first = DanceNetBundle.load(args.weights[0] if args.weights else DEFAULT_BUNDLE)
    fps = first.model.cfg.fps
    real = DanceSet("real", "Real dances (validation songs)", [decode(p.motion, fps, first.skeleton) for p in val],
                    [p.style for p in val], [beats[p.seq] for p in val])
    trained_on = set(split["train"]) - set(split["validation"])
    ref = reference_features([decode(p.motion, fps, first.skeleton).positions()
                              for p in pairs.values() if p.seq in trained_on], fps, style_net)
    rows = [real]
    if args.curve:
        return learning_curve(args.curve, val, beats, ref, style_net, real, args)
    for path in args.weights:
        bundle = DanceNetBundle.load(path)
        k = bundle.model.cfg.mixtures
        for temperature, smoothing, cleanup, lock in product(args.temperatures, args.smoothing, args.cleanup,
                                                             args.beat_lock):
            name = (f"{path} T={temperature} smooth={smoothing}" + ("" if cleanup == FOOT_CLEANUP else f" {cleanup}")
                    + ("" if lock == "on" else " unlocked"))
            rows.append(dance_row(name, f"{run_label(Path(path), bundle)} (K={k}), T {temperature}, "
                                  f"smoothing {smoothing}, feet: {cleanup}, beat lock {lock}", bundle, val, beats,
                                  args.takes, temperature, footfix=cleanup != "none", smoothing=smoothing,
                                  footfix_weights=args.footfix, cleanup=cleanup, beat_lock=lock == "on"))
            print(f"  {name}: {len(rows[-1].dances)} dances", flush=True)
    table = measure(rows, ref, fps, style_net)
    if args.drift:
        free_running_levels(args, val)
    seconds = time.perf_counter() - t0
    md = markdown(table, seconds, 0, args.takes, len(ref["hit"])).replace(
        "every compared model trained 0 steps on the same windows. Produced by `dancenet evaluate`",
        f"validation songs {', '.join(p.seq for p in val)}. Produced by `dancenet validate`")
    args.out.mkdir(parents=True, exist_ok=True)
    write_text(args.out / "validation.md", md)
    write_text(args.out / "validation.json", json.dumps({"seconds": seconds, "rows": table}, indent=1) + "\n")
    print(md)
    return 0


def free_running_levels(args: argparse.Namespace, val: list) -> None:
    """Each weights file's free-running dances of `args.drift` seconds against the capture's level and root
    speed (`evaluation/drift.py`): drift.png and drift.json in `args.out`."""
    curves, figures, real = {}, {}, None
    for path in args.weights:
        bundle = DanceNetBundle.load(path)
        name = run_label(Path(path), bundle)
        gen, real = drift.free_running(bundle, val, args.drift, args.takes, args.temperatures[-1])
        curves[name], figures[name] = gen, drift.summary(gen, real)
        print(f"  {name}: free-running level {figures[name]['level_first']:.2f} -> "
              f"{figures[name]['level_last']:.2f} of the capture's", flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    drift.plot(curves, real, args.out / "drift.png")
    write_text(args.out / "drift.json", json.dumps(figures, indent=1) + "\n")


def run_label(path: Path, bundle: DanceNetBundle) -> str:
    """A weights file's name in a table: its run folder, and the step for a run's snapshot."""
    if path.parent.name == "snapshots":
        return f"{path.parent.parent.name}, step {bundle.info.get('steps')}"
    return path.parent.name or str(path)


def learning_curve(run: Path, val: list, beats: dict, ref: dict, style_net: MotionStyleModel, real: DanceSet,
                   args: argparse.Namespace) -> int:
    """Validation loss (from the run's log) and FID_k on the validation songs (one take each, at the first
    temperature asked for, foot clean-up on) of every snapshot a training run kept, against training time."""
    plt = pyplot()
    log = [json.loads(line) for line in (run / "log.jsonl").read_text().splitlines()]
    val_loss = {r["step"]: r["val_loss"] for r in log if "val_loss" in r}
    points = []
    for path in sorted((run / "snapshots").glob("step*.pt")) + [run / "dancenet.pt"]:
        if not path.is_file():
            continue
        bundle = DanceNetBundle.load(path)
        step = bundle.info["steps"]
        row = dance_row(path.stem, path.stem, bundle, val, beats, 1, args.temperatures[0], footfix=True,
                        footfix_weights=args.footfix)
        r = measure([row], ref, bundle.model.cfg.fps, style_net)[path.stem]
        near = [s for s in val_loss if s <= step]
        points.append({"step": step, "minutes": round(bundle.info["train_seconds"] / 60, 1),
                       "val_loss": val_loss[max(near)] if near else None, "fid_k": r["fid_k"],
                       "joint_speed_m_s": r["joint_speed_m_s"], "root_extent_m": r["root_extent_m"]})
        print(f"  {path.name}: {points[-1]}", flush=True)
    real_row = measure([real], ref, real.dances[0].fps, style_net)["real"]
    args.out.mkdir(parents=True, exist_ok=True)
    write_text(args.out / "learning_curve.json", json.dumps(
        {"run": str(run), "temperature": args.temperatures[0], "real_fid_k": real_row["fid_k"], "points": points},
        indent=1) + "\n")
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.5))
    minutes = [p["minutes"] for p in points]
    ax[0].plot(minutes, [p["val_loss"] for p in points], "o-")
    ax[0].set(xlabel="training minutes (this run)", ylabel="validation loss", title="held-out loss")
    ax[1].plot(minutes, [p["fid_k"] for p in points], "o-", label="generated")
    ax[1].axhline(real_row["fid_k"], color="gray", ls="--", label="real validation dances")
    ax[1].set(xlabel="training minutes (this run)", ylabel="FID_k", title="FID_k on the validation songs")
    ax[1].legend()
    fig.tight_layout()
    fig.savefig(args.out / "learning_curve.png", dpi=100)
    plt.close(fig)
    print(f"wrote {args.out / 'learning_curve.json'} and learning_curve.png")
    return 0

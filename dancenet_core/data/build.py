"""`dancenet data build`: the paired dataset of motion features and music, cached on disk.

For each Dance with Melody sequence: fit our skeleton to its markers, put its feet on the floor, encode
the paper's representation at the model's frame rate, and sample the song's music features at the
times of the motion frames (song time = music_offset_s + t / fps, as the data README says).
The CMU dance clips (no music) are retargeted onto our skeleton and cached the same way.

Frame rate: 25 fps, the capture's own. Resampling up to 30 or 60 fps would invent frames, make the
dilated stack's 125-frame receptive field cover less time (5 s at 25 fps), and cost more to train.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.ndimage import gaussian_filter1d, minimum_filter1d

from ..atomic import atomic_open
from ..bvh import read_bvh
from ..errors import DanceNetError
from ..motion import Motion
from ..representation import encode
from ..retarget import CMU, Retargeted, SourcePose, fit_targets, retarget, source_pose
from ..skeleton import TOE_ENDS, Skeleton
from .cmu_dance import Clip, read_cmu_manifest
from .dance_with_melody import P, Sequence, load_positions, read_manifest
from .fit import fit_errors, fit_sequence, performer_skeleton, stretch_errors

MODEL_FPS = 25.0
BUILD_VERSION = "dataset-2"  # the skeleton fits (slow); paired files carry their own version
PAIR_VERSION = "pair-3"
SPLIT_FILE = Path(__file__).resolve().parents[1] / "weights" / "song_split.json"


def default_data_dir() -> Path:
    """`$DANCENET_DATA`, else the shared data folder next to the repository."""
    env = os.environ.get("DANCENET_DATA")
    return Path(env) if env else Path(__file__).resolve().parents[3] / "shared" / "data"


def dataset_cache_dir() -> Path:
    env = os.environ.get("DANCENET_CACHE")
    base = Path(env).expanduser() if env else Path.home() / ".cache" / "dancenet"
    return base / BUILD_VERSION


def music_at_frames(features: np.ndarray, feature_fps: float, times: np.ndarray) -> np.ndarray:
    """Music features [T_music, F] (frame j centred at j / feature_fps) sampled at `times` (seconds)."""
    pos = times * feature_fps
    src = np.arange(len(features))
    return np.stack([np.interp(pos, src, features[:, k]) for k in range(features.shape[1])], -1).astype(
        np.float32
    )


def floor_offset(motion: Motion) -> float:
    """Height of the floor under this clip: a low percentile of the lower toe end."""
    toes = motion.end_effectors()[:, list(TOE_ENDS), 1].min(axis=1)
    return float(np.percentile(toes, 2))


def floor_track(motion: Motion, window_s: float = 2.0, smooth_s: float = 0.5) -> np.ndarray:
    """The floor's height under the dancer, frame by frame [T].

    Most captures drift upward by 0.2-0.5 m over a minute (the toes of a waltz end up 0.4 m above where
    they started). A ballroom dancer has a foot on the floor within any two seconds, so the lowest toe
    end over a 2-s window, smoothed, follows the floor; subtracting it removes the drift.
    """
    toes = motion.end_effectors()[:, list(TOE_ENDS), 1].min(axis=1)
    low = minimum_filter1d(toes, size=max(1, int(window_s * motion.fps)), mode="nearest")
    return gaussian_filter1d(low, smooth_s * motion.fps, mode="nearest")


@dataclass
class PairedSequence:
    """One dance with its music, ready for training windows."""

    seq: str
    style: str
    motion: np.ndarray  # [T, D] encoded motion features
    mirrored: np.ndarray  # [T, D] the left/right mirror image, same music
    music: np.ndarray  # [T, 15] music features at the motion frames
    positions: np.ndarray  # [T, 22, 3] world positions of the body joints (for metrics)
    offsets: np.ndarray  # performer skeleton offsets
    fit_mean_cm: float
    fit_p95_cm: float

    def save(self, path: Path) -> None:
        with atomic_open(path, "wb") as f:
            np.savez_compressed(f, seq=self.seq, style=self.style, motion=self.motion, mirrored=self.mirrored,
                                music=self.music, positions=self.positions, offsets=self.offsets,
                                fit=np.array([self.fit_mean_cm, self.fit_p95_cm]))

    @classmethod
    def load(cls, path: Path) -> PairedSequence:
        z = np.load(path)
        return cls(str(z["seq"]), str(z["style"]), z["motion"], z["mirrored"], z["music"], z["positions"],
                   z["offsets"], float(z["fit"][0]), float(z["fit"][1]))


def fitted_motion(seq: Sequence, out_dir: Path, fit_steps: int = 200) -> tuple[Motion, np.ndarray]:
    """The fitted motion (feet on the floor, model rate; cached) and its fit errors [T, K] on the joints."""
    motion_path = out_dir / f"{seq.seq}.motion.npz"
    pos = load_positions(seq)
    if motion_path.is_file():
        motion = Motion.load(motion_path)
    else:
        motion, _ = fit_sequence(pos, seq.fps, steps=fit_steps)
        motion.root_positions[:, 1] -= floor_offset(motion)
        motion.save(motion_path)
    return motion, fit_report(motion, pos)[0]


def fit_report(motion: Motion, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fit errors and the marker stretch of each joint's own bone (error a rigid skeleton cannot avoid
    even with its parent joint in place), [T, K] each, in metres.

    Both are measured against the markers where they were captured: the floor shift (a constant
    height, `floor_offset`) is undone first.
    """
    _, targets = performer_skeleton(pos)
    placed = Motion(motion.rotations, motion.root_positions.copy(), motion.fps, motion.skeleton)
    placed.root_positions[:, 1] += np.median(pos[:, P["pelvis"], 1] - placed.root_positions[:, 1])
    return fit_errors(placed, pos, targets), stretch_errors(placed, pos, targets, along_chain=False)


def fitted_clip(clip: Clip, out_dir: Path, fit_steps: int = 200) -> tuple[Motion, np.ndarray, SourcePose]:
    """A CMU clip retargeted onto our skeleton (feet on the floor, model rate; cached), its fit errors [T, K]
    on the mapped joints, and the source pose it was fitted to (metres, Y up, model rate)."""
    motion_path = out_dir / f"CMU_{clip.clip}.motion.npz"
    data = read_bvh(clip.bvh)
    if motion_path.is_file():
        motion = Motion.load(motion_path)
        source = source_pose(data, CMU, MODEL_FPS, str(clip.bvh))
        targets = fit_targets(source)
    else:
        fit = retarget(data, CMU, MODEL_FPS, steps=fit_steps, path=str(clip.bvh))
        motion, source, targets = fit.motion, fit.source, fit.targets
        motion.root_positions[:, 1] -= floor_offset(motion)
        motion.save(motion_path)
    # Measured where the source is: undo the floor shift (a constant height) first.
    shift = np.median(source.positions[:, 0, 1] - motion.root_positions[:, 1])
    placed = Motion(motion.rotations, motion.root_positions + [0.0, shift, 0.0], motion.fps, motion.skeleton)
    return motion, Retargeted(placed, source, targets).errors(), source


def build_sequence(seq: Sequence, out_dir: Path) -> PairedSequence:
    from ..features import FPS as MUSIC_FPS
    from ..features import analyze_music

    motion, err = fitted_motion(seq, out_dir)
    motion.root_positions[:, 1] -= floor_track(motion)
    analysis = analyze_music(seq.audio)
    times = seq.music_offset_s + np.arange(motion.num_frames) / MODEL_FPS
    music = music_at_frames(analysis.features, MUSIC_FPS, times)
    paired = PairedSequence(
        seq=seq.seq,
        style=seq.style,
        motion=encode(motion, floor=0.0),
        mirrored=encode(motion.mirrored(), floor=0.0),
        music=music,
        positions=motion.positions()[:, :22].astype(np.float32),
        offsets=motion.skeleton.offsets,
        fit_mean_cm=float(err.mean() * 100),
        fit_p95_cm=float(np.percentile(err, 95) * 100),
    )
    return paired


def load_split(path: Path = SPLIT_FILE) -> dict:
    if not path.is_file():
        raise DanceNetError(f"song split {path} is missing; it ships with the package (reinstall)")
    return json.loads(path.read_text())


def with_mel_music(pairs: list[PairedSequence], data_dir: Path) -> list[PairedSequence]:
    """The same pairs with the song's log-mel spectrum in place of the 15 music features (the paper's ablation)."""
    from ..features import FPS as MUSIC_FPS
    from ..features import analyze_music

    seqs = {s.seq: s for s in read_manifest(data_dir)}
    out = []
    for p in pairs:
        seq = seqs[p.seq]
        times = seq.music_offset_s + np.arange(len(p.motion)) / MODEL_FPS
        mel = analyze_music(seq.audio, with_mel=True).mel
        out.append(replace(p, music=music_at_frames(mel, MUSIC_FPS, times).astype(np.float32)))
    return out


def build_dataset(data_dir: Path, out_dir: Path | None = None, progress: bool = True) -> list[PairedSequence]:
    """Build (or reuse) every sequence's paired file; returns them all."""
    from tqdm import tqdm

    out_dir = out_dir or dataset_cache_dir()
    out_dir.mkdir(parents=True, exist_ok=True)
    seqs = read_manifest(data_dir)
    result = []
    bar = tqdm(seqs, desc="dataset", unit="seq", disable=not progress)
    for seq in bar:
        path = out_dir / f"{seq.seq}.{PAIR_VERSION}.npz"
        if path.is_file():
            result.append(PairedSequence.load(path))
            continue
        bar.set_postfix_str(seq.seq)
        paired = build_sequence(seq, out_dir)
        paired.save(path)
        result.append(paired)
    return result


def mean_skeleton(pairs: list[PairedSequence]) -> Skeleton:
    """The skeleton generated dances use: the performers' average."""
    return Skeleton(np.mean([p.offsets for p in pairs], axis=0))


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("data", help="build or inspect the training dataset")
    dsub = p.add_subparsers(dest="data_command", required=True)
    b = dsub.add_parser("build", help="fit skeletons, pair motion with music, cache on disk")
    b.add_argument("--data", type=Path, default=None, help="the shared data folder (default: ../shared/data)")
    b.add_argument("--out", type=Path, default=None, help="cache folder (default: ~/.cache/dancenet)")
    b.set_defaults(handler=_cmd_build)
    s = dsub.add_parser("show", help="draw a source frame and our fitted skeleton side by side")
    s.add_argument("seq", help="sequence id, e.g. DANCE_W_1, or CMU clip, e.g. 60_01")
    s.add_argument("--frame", type=int, default=None, help="frame index (default: the middle)")
    s.add_argument("--data", type=Path, default=None)
    s.add_argument("--out", type=Path, default=Path("frame.png"))
    s.set_defaults(handler=_cmd_show)
    a = dsub.add_parser("alignment", help="Beat Align Score of the real dances against their songs, by folder")
    a.add_argument("--data", type=Path, default=None, help="the shared data folder (default: ../shared/data)")
    a.set_defaults(handler=_cmd_alignment)


def _cmd_build(args: argparse.Namespace) -> int:
    pairs = build_dataset(args.data or default_data_dir(), args.out)
    split = load_split()
    for name in ("train", "test"):
        mins: dict[str, float] = {}
        for p in pairs:
            if p.seq in split[name]:
                mins[p.style] = mins.get(p.style, 0.0) + len(p.motion) / MODEL_FPS / 60
        print(f"{name}: " + ", ".join(f"{k} {v:.1f} min" for k, v in sorted(mins.items())))
    data_dir = args.data or default_data_dir()
    out_dir = args.out or dataset_cache_dir()
    rows = []
    for seq in read_manifest(data_dir):
        motion, _ = fitted_motion(seq, out_dir)
        err, stretch = fit_report(motion, load_positions(seq))
        rows.append([err.mean(), np.percentile(err, 95), stretch.mean()])
    f = np.array(rows) * 100
    print(f"fit error on the matched joints over {len(f)} sequences: mean {f[:, 0].mean():.2f} cm "
          f"(worst {f[:, 0].max():.2f}), p95 {f[:, 1].mean():.2f} cm (worst {f[:, 1].max():.2f}); the markers' "
          f"own-bone stretch is {f[:, 2].mean():.2f} cm, {100 * f[:, 2].mean() / f[:, 0].mean():.0f}% of it")
    _build_cmu(data_dir, out_dir)
    return 0


def _build_cmu(data_dir: Path, out_dir: Path) -> None:
    """Retarget every CMU clip once (cached) and print the fit error per clip and over all frames."""
    from tqdm import tqdm

    clips = read_cmu_manifest(data_dir)
    if not clips:
        print(f"no CMU clips under {data_dir} (cmu_dance/manifest.csv): skipped")
        return
    out_dir.mkdir(parents=True, exist_ok=True)
    errs, seconds, start = [], 0.0, time.perf_counter()
    for clip in tqdm(clips, desc="CMU retarget", unit="clip"):
        motion, err, _ = fitted_clip(clip, out_dir)
        errs.append(err)
        seconds += motion.duration
        tqdm.write(f"  CMU {clip.clip} ({clip.description}): mean {err.mean() * 100:.2f} cm, "
                   f"p95 {np.percentile(err, 95) * 100:.2f} cm, {motion.duration:.0f} s")
    every = np.concatenate(errs) * 100
    worst = int(np.argmax([np.percentile(e, 95) for e in errs]))
    print(f"CMU retarget error on the mapped joints over {len(clips)} clips ({seconds / 60:.1f} min): "
          f"mean {every.mean():.2f} cm, p95 {np.percentile(every, 95):.2f} cm; worst clip {clips[worst].clip} "
          f"(p95 {np.percentile(errs[worst], 95) * 100:.2f} cm); {time.perf_counter() - start:.0f} s")


def _cmd_alignment(args: argparse.Namespace) -> int:
    from .alignment import alignment_table, report

    print(report(alignment_table(args.data or default_data_dir())))
    return 0


def _cmd_show(args: argparse.Namespace) -> int:
    from .show import draw_fit

    draw_fit(args.data or default_data_dir(), args.seq, args.frame, args.out)
    print(f"wrote {args.out}")
    return 0

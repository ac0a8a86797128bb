"""`dancenet data build`: the paired dataset of motion features and music, cached on disk.

For each Dance with Melody sequence: fit our skeleton to its markers, put its feet on the floor, encode
the paper's representation at the model's frame rate, and sample the song's music features at the
times of the motion frames (song time = music_offset_s + t / fps, as the data README says).

The floor is tracked frame by frame (the capture drifts upward by up to 0.5 m within a sequence) on the
skeleton the dances are decoded on, the performers' average, not on each performer's own: the features keep
the pelvis' height, so a dancer with longer legs than the average, decoded on the average skeleton, hovered
(cha-cha DANCE_C_2: 1.6 cm at its lowest in most 2-s windows) and a shorter one sank (rumba R_2 and R_8:
4.5 cm under the floor), and the model learnt each style's hovering or sinking with its steps.
The CMU dance clips (no music) are retargeted onto our skeleton and cached the same way.

Frame rate: 25 fps, the capture's own. Resampling up to 30 or 60 fps would invent frames, make the
dilated stack's 125-frame receptive field cover less time (5 s at 25 fps), and cost more to train.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..atomic import atomic_open
from ..bvh import read_bvh
from ..environment import cache_root
from ..jointmap import CMU, SourcePose, source_pose
from ..motion import Motion
from ..music.features import FPS as MUSIC_FPS
from ..music.features import analyze_music, music_at_frames
from ..representation import encode
from ..shaping.floor import floor_offset, floor_track
from ..skeleton import BODY_JOINTS, Skeleton
from .cmu_dance import Clip
from .dance_with_melody import P, Recording, load_positions, read_manifest
from .fit import fit_errors, fit_sequence, performer_skeleton, stretch_errors
from .retarget import Retargeted, fit_targets, retarget

MODEL_FPS = 25.0
BUILD_VERSION = "dataset-2"  # the skeleton fits (slow); paired files carry their own version
PAIR_VERSION = "pair-4"


def dataset_cache_dir() -> Path:
    """Where the fits and paired files are cached (inside the one cache folder, by build version)."""
    return cache_root() / BUILD_VERSION


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
    def from_motion(cls, seq: str, style: str, motion: Motion, music: np.ndarray, err: np.ndarray) -> PairedSequence:
        """A dance on the floor (y = 0) with its music at its frames, encoded as training reads it (and mirrored);
        `err` [T, K]: its fit errors (m)."""
        return cls(seq=seq, style=style, motion=encode(motion, floor=0.0),
                   mirrored=encode(motion.mirrored(), floor=0.0), music=music,
                   positions=motion.positions()[:, :BODY_JOINTS].astype(np.float32), offsets=motion.skeleton.offsets,
                   fit_mean_cm=float(err.mean() * 100), fit_p95_cm=float(np.percentile(err, 95) * 100))

    @classmethod
    def load(cls, path: Path) -> PairedSequence:
        z = np.load(path)
        return cls(str(z["seq"]), str(z["style"]), z["motion"], z["mirrored"], z["music"], z["positions"],
                   z["offsets"], float(z["fit"][0]), float(z["fit"][1]))


def fitted_motion(seq: Recording, out_dir: Path, fit_steps: int = 200) -> tuple[Motion, np.ndarray]:
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


def floor_skeleton(seqs: list[Recording], out_dir: Path) -> Skeleton:
    """The skeleton the floor is tracked on: the average of every sequence's fitted performer (what
    `mean_skeleton` gives training, within millimetres); fits what is not fitted yet."""
    offsets = []
    for seq in seqs:
        path = out_dir / f"{seq.seq}.motion.npz"
        if not path.is_file():
            fitted_motion(seq, out_dir)
        offsets.append(np.load(path)["offsets"])
    return Skeleton(np.mean(offsets, axis=0))


def build_sequence(seq: Recording, out_dir: Path, floor_on: Skeleton | None = None) -> PairedSequence:
    """One sequence paired with its music, its feet on the floor frame by frame when decoded on `floor_on`
    (default: its own performer's skeleton)."""
    motion, err = fitted_motion(seq, out_dir)
    skeleton = floor_on or motion.skeleton
    motion.root_positions[:, 1] -= floor_track(Motion(motion.rotations, motion.root_positions, motion.fps, skeleton))
    analysis = analyze_music(seq.audio)
    times = seq.music_offset_s + np.arange(motion.num_frames) / MODEL_FPS
    music = music_at_frames(analysis.features, MUSIC_FPS, times)
    return PairedSequence.from_motion(seq.seq, seq.style, motion, music, err)


def with_mel_music(pairs: list[PairedSequence], data_dir: Path) -> list[PairedSequence]:
    """The same pairs with the song's log-mel spectrum in place of the 15 music features (the paper's ablation)."""
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
    out_dir = out_dir or dataset_cache_dir()
    out_dir.mkdir(parents=True, exist_ok=True)
    seqs = read_manifest(data_dir)
    skeleton = floor_skeleton(seqs, out_dir)
    # The floor depends on every performer (their average skeleton): the files name the skeleton they used.
    tag = hashlib.sha1(np.round(skeleton.offsets, 6).tobytes()).hexdigest()[:8]
    result = []
    bar = tqdm(seqs, desc="dataset", unit="seq", disable=not progress)
    for seq in bar:
        path = out_dir / f"{seq.seq}.{PAIR_VERSION}.{tag}.npz"
        if path.is_file():
            result.append(PairedSequence.load(path))
            continue
        bar.set_postfix_str(seq.seq)
        paired = build_sequence(seq, out_dir, skeleton)
        paired.save(path)
        result.append(paired)
    return result


def mean_skeleton(pairs: list[PairedSequence]) -> Skeleton:
    """The skeleton generated dances use: the performers' average."""
    return Skeleton(np.mean([p.offsets for p in pairs], axis=0))



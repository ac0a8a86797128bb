"""A built motion library: every clip end to end at one frame rate, with each clip's beats, bars and the boundary
features at each beat; saved as plain arrays (`.npz`, read with allow_pickle=False) under the cache folder, keyed by
the content of the folder it was built from. This module is what generation reads: it imports no building code.
"""

from __future__ import annotations

import hashlib
import json
import os
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from ..atomic import atomic_open
from ..environment import WEIGHTS_DIR, cache_root
from ..errors import DanceNetError
from ..motion import Motion
from ..skeleton import BODY_JOINTS, Skeleton
from .analysis import FEATURE_DIM, ClipAnalysis, with_assumed_tempi
from .loops import danced_around

LIBRARY_VERSION = "motion-library-8"  # change whenever what a build computes changes
LIBRARY_FPS = 25.0
CLIP_SUFFIXES = (".bvh", ".fbx")  # FBX files only Blender reads (the add-on's Build Library)
# A joint's steps are bounded by at least this much a frame (m): a joint a hand-keyed clip never moves (feet planted to
# the last digit) bounds no step.
MIN_STEP_M = 1e-3
# A clip whose root stays within this much on the floor (each way) is danced as exported "in place": its standing
# feet slide by the travel taken out of it, and the dance gives it back (`transitions.hold_stance`).
IN_PLACE_M = 0.5
# The library used when a user names none: CMU's dance clips (scripts/build_default_library.py builds it).
DEFAULT_LIBRARY = WEIGHTS_DIR / "cmu_dance_library.npz"


@dataclass
class MotionLibrary:
    """rotations [N, 55, 3] and root_positions [N, 3] of all clips end to end (clip c: frames clip_starts[c] to
    clip_starts[c + 1]); per beat (all clips, in order): its frame (sub-frame, counted from the clip's start plus
    clip_starts), clip, downbeat flag, boundary features [B, FEATURE_DIM] and energy (mean joint speed to the
    next beat, m/s); per clip: name, style, tempo and meter, how sure the analysis is of them (`confidence`, 0-1)
    and what they were read from (`source`: the motion, the style's meter, the manifest...), and the convention of
    the skeleton it was read from (`skeletons`: the bone map that read it, "Mixamo", "VRM + shape"...; empty for a
    library built without them); offsets: the skeleton every dance is built on."""

    rotations: np.ndarray
    root_positions: np.ndarray
    offsets: np.ndarray
    clip_starts: np.ndarray
    names: list[str]
    styles: list[str]
    tempo_bpm: np.ndarray
    meter: np.ndarray
    beats: np.ndarray
    beat_clip: np.ndarray
    downbeat: np.ndarray
    features: np.ndarray
    energy: np.ndarray
    confidence: np.ndarray
    source: list[str]
    fps: float = LIBRARY_FPS
    notes: tuple[str, ...] = ()  # what the build left out, one line each
    # [N, match.FRAME_DIM] the learned match's motion features of every frame, a forward kinematics pass over the
    # whole library: the build computes them for a library whose clips name no style (the libraries the match
    # dances), so that its first dance reads them (`match.frames_of`)
    match_frames: np.ndarray | None = None
    skeletons: list[str] = field(default_factory=list)

    @property
    def num_clips(self) -> int:
        return len(self.names)

    @property
    def unlabelled(self) -> bool:
        """No clip names a style (a folder of downloads): the learned match of music and movement keeps its dances
        to the song's style, and its build stores the match's motion features."""
        return not any(self.styles)

    @property
    def duration_s(self) -> float:
        return len(self.rotations) / self.fps

    @property
    def skeleton(self) -> Skeleton:
        return Skeleton(self.offsets)

    def clip(self, c: int) -> Motion:
        a, b = self.clip_starts[c], self.clip_starts[c + 1]
        return Motion(self.rotations[a:b], self.root_positions[a:b], self.fps, self.skeleton)

    @cached_property
    def joint_motion(self) -> tuple[np.ndarray, np.ndarray]:
        """How each body joint moved since the frame before, 0 at a clip's first frame, from one forward-kinematics
        pass: its step (m, [N, body joints]) and its squared speed over the floor, then up and down ((m/s)^2,
        float32, [N, 2 x body joints])."""
        steps, power = [], []
        for c in range(self.num_clips):
            move = np.diff(self.clip(c).positions()[:, :BODY_JOINTS], axis=0)
            speed2 = (move * self.fps) ** 2
            steps += [np.zeros((1, BODY_JOINTS)), np.linalg.norm(move, axis=-1)]
            power += [np.zeros((1, 2 * BODY_JOINTS), np.float32),
                      np.concatenate([speed2[..., 0] + speed2[..., 2], speed2[..., 1]], axis=1).astype(np.float32)]
        return np.concatenate(steps), np.concatenate(power)

    @property
    def joint_steps(self) -> np.ndarray:
        """[N, body joints]: how far (m) each body joint moved since the frame before, 0 at a clip's first frame:
        how fast the library's own dancers move, which its cuts are held to (choreography, evaluation)."""
        return self.joint_motion[0]

    def _step_percentile(self, q: float) -> np.ndarray:
        """[body joints]: each joint's q-th percentile of its steps (frames with one before them in their clip), at
        least `MIN_STEP_M`."""
        moved = np.ones(len(self.rotations), bool)
        moved[self.clip_starts[:-1]] = False
        return np.maximum(np.percentile(self.joint_steps[moved], q, axis=0), MIN_STEP_M)

    @cached_property
    def step_p99(self) -> np.ndarray:
        """[body joints]: each joint's 99th percentile of its steps (`_step_percentile`)."""
        return self._step_percentile(99)

    @cached_property
    def peak_ratios(self) -> np.ndarray:
        """[N]: each frame's largest body-joint step over that joint's 99.9th percentile in the library: where a
        clip moves faster than its dancers ever do elsewhere (a leap, or a capture's glitch)."""
        return (self.joint_steps / self._step_percentile(99.9)).max(axis=1)

    @cached_property
    def in_place(self) -> np.ndarray:
        """[clips]: whether each clip's root stays over one spot (within `IN_PLACE_M` on the floor each way)."""
        floor = self.root_positions[:, [0, 2]]
        return np.array([np.ptp(floor[a:b], axis=0).max() <= IN_PLACE_M
                         for a, b in zip(self.clip_starts[:-1], self.clip_starts[1:], strict=True)])

    @cached_property
    def step_ratios(self) -> np.ndarray:
        """[N]: each frame's largest body-joint step over that joint's 99th percentile (`step_p99`)."""
        return (self.joint_steps / self.step_p99).max(axis=1)

    @classmethod
    def from_clips(cls, clips: list[tuple[str, str, Motion, ClipAnalysis]], notes: tuple[str, ...] = (),
                   skeletons: Sequence[str] = ()) -> MotionLibrary:
        """A library of (name, style, motion at LIBRARY_FPS, its analysis) clips; the skeleton is their mean. A clip
        that loops is laid end to end (`loops.danced_around`); one too short for its tempo to be read takes the
        library's (`analysis.with_assumed_tempi`)."""
        if not clips:
            raise DanceNetError("no clip to build a library from")
        clips = with_assumed_tempi([danced_around(c) for c in clips])
        starts = np.cumsum([0] + [m.num_frames for _, _, m, _ in clips])
        return cls(
            rotations=np.concatenate([m.rotations for _, _, m, _ in clips]).astype(np.float32),
            root_positions=np.concatenate([m.root_positions for _, _, m, _ in clips]).astype(np.float32),
            offsets=np.mean([m.skeleton.offsets for _, _, m, _ in clips], axis=0),
            clip_starts=starts,
            names=[n for n, _, _, _ in clips],
            styles=[s for _, s, _, _ in clips],
            tempo_bpm=np.array([a.tempo_bpm for *_, a in clips]),
            meter=np.array([a.meter for *_, a in clips], dtype=np.int64),
            beats=np.concatenate([a.beats + s for (*_, a), s in zip(clips, starts, strict=False)]),
            beat_clip=np.concatenate([np.full(len(a.beats), c) for c, (*_, a) in enumerate(clips)]).astype(np.int64),
            downbeat=np.concatenate([a.downbeat for *_, a in clips]).astype(bool),
            features=np.concatenate([a.features for *_, a in clips]).astype(np.float32).reshape(-1, FEATURE_DIM),
            energy=np.concatenate([a.energy for *_, a in clips]).astype(np.float32),
            confidence=np.array([a.confidence for *_, a in clips], dtype=np.float64),
            source=[a.source for *_, a in clips],
            notes=notes,
            skeletons=list(skeletons),
        )

    def save(self, path: str | Path, compact: bool = False) -> None:
        """The arrays as an .npz; `compact` (a library that ships) stores the joint rotations as float16
        (0.002 rad apart at most) and compresses, for about a third of the bytes; `load` reads either."""
        meta = {"version": LIBRARY_VERSION, "fps": self.fps, "names": self.names, "styles": self.styles,
                "source": self.source, "notes": list(self.notes), "skeletons": self.skeletons}
        unsorted = {} if self.match_frames is None else {"match_frames": self.match_frames}
        with atomic_open(path, "wb") as f:
            (np.savez_compressed if compact else np.savez)(
                f, rotations=self.rotations.astype(np.float16) if compact else self.rotations,
                root_positions=self.root_positions, offsets=self.offsets, clip_starts=self.clip_starts,
                tempo_bpm=self.tempo_bpm, meter=self.meter, beats=self.beats, beat_clip=self.beat_clip,
                downbeat=self.downbeat, features=self.features, energy=self.energy, confidence=self.confidence,
                step_p99=self.step_p99, step_ratios=self.step_ratios, meta=np.array(json.dumps(meta)), **unsorted)

    @classmethod
    def load(cls, path: str | Path) -> MotionLibrary:
        """A library written by `save`; ValueError for anything else (damaged, of another version)."""
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                if meta.get("version") != LIBRARY_VERSION:
                    raise ValueError(f"a library of version {meta.get('version')}")
                lib = cls(z["rotations"].astype(np.float32), z["root_positions"], z["offsets"], z["clip_starts"],
                          list(meta["names"]), list(meta["styles"]), z["tempo_bpm"], z["meter"], z["beats"],
                          z["beat_clip"], z["downbeat"], z["features"], z["energy"], z["confidence"],
                          list(meta["source"]), float(meta["fps"]), tuple(meta["notes"]))
                # how far the dancers step, measured once at the build (a forward kinematics pass over every frame)
                lib.__dict__["step_p99"], lib.__dict__["step_ratios"] = z["step_p99"], z["step_ratios"]
                lib.skeletons = [str(k) for k in meta.get("skeletons", [])]
                if "match_frames" in z:
                    lib.match_frames = z["match_frames"]
        except (OSError, KeyError, ValueError, TypeError, EOFError, zipfile.BadZipFile) as e:
            raise ValueError(f"{path}: not a motion library ({e})") from e
        n, b = len(lib.rotations), len(lib.beats)
        if (lib.rotations.shape[1:] != (lib.offsets.shape[0], 3) or lib.root_positions.shape != (n, 3)
                or lib.clip_starts[-1] != n or len(lib.names) + 1 != len(lib.clip_starts)
                or not len(lib.names) == len(lib.confidence) == len(lib.source)
                or len(lib.skeletons) not in (0, len(lib.names))
                or lib.step_ratios.shape != (n,) or lib.step_p99.shape != (BODY_JOINTS,)
                or lib.features.shape != (b, FEATURE_DIM) or not len(lib.beat_clip) == len(lib.downbeat) == b
                or (lib.match_frames is not None and len(lib.match_frames) != n)):
            raise ValueError(f"{path}: a motion library whose arrays do not fit each other")
        return lib


def clip_files(folder: Path) -> list[Path]:
    """The clips of a library folder (BVH and FBX files, any depth), in a fixed order."""
    return sorted(p for p in folder.rglob("*") if p.suffix.lower() in CLIP_SUFFIXES and p.is_file())


def file_sha256(path: Path) -> bytes:
    """The sha256 digest of a file's bytes."""
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").digest()


def folder_key(folder: str | Path, digest: Callable[[Path], bytes] = file_sha256) -> str:
    """A digest of the folder's clips (names relative to it and bytes) and of its manifest: a changed, added or
    removed clip builds a new library, any other file is not the library's. `digest` hashes one file (a song
    catalog's remembers the digests of files unchanged since)."""
    folder = Path(folder)
    h = hashlib.sha256(LIBRARY_VERSION.encode())
    for p in [*clip_files(folder), folder / "manifest.csv"]:
        if p.is_file():
            h.update(os.fsencode(p.relative_to(folder)) + b"\0")  # bytes: a name need not be UTF-8
            h.update(digest(p))
    return h.hexdigest()[:32]


def built_path(key: str) -> Path:
    """Where the library of content `key` is cached."""
    return cache_root() / LIBRARY_VERSION / f"{key}.npz"


def library_path(folder: str | Path) -> Path:
    """Where the library built from `folder` is cached."""
    return built_path(folder_key(folder))


def load_built(folder: str | Path) -> MotionLibrary:
    """The library built from `folder` (by `dancenet library build`), or a one-line error saying to build it. A
    built library's own file (.npz, as the add-on's library of the actions in a .blend is given) is read as is."""
    folder = Path(folder)
    if folder.suffix == ".npz" and folder.is_file():
        try:
            return MotionLibrary.load(folder)
        except ValueError as e:
            raise DanceNetError(f"{e}; build the library again") from e
    if not folder.is_dir():
        raise DanceNetError(f"motion library folder not found: {folder} (give a folder of BVH clips)")
    path = library_path(folder)
    if not path.is_file():
        raise DanceNetError(f"the library in {folder} is not built (or changed since): run `dancenet library build "
                            f"{folder}` first")
    try:
        return MotionLibrary.load(path)
    except ValueError as e:
        raise DanceNetError(f"{e}; run `dancenet library build {folder}` again") from e


def load_default() -> MotionLibrary:
    """The shipped library (`DEFAULT_LIBRARY`), or a one-line error when the install lacks it or it is damaged."""
    try:
        return MotionLibrary.load(DEFAULT_LIBRARY)
    except ValueError as e:
        raise DanceNetError(f"{e}; reinstall DanceNet, or give a library folder (--library FOLDER)") from e

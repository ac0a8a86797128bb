"""Motion: what every stage hands on. Local joint rotations plus the root's path, at a frame rate."""

from __future__ import annotations

import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from .atomic import atomic_open
from .kinematics import fk_numpy
from .skeleton import DEFAULT_SKELETON, JOINT_NAMES, MIRROR_INDEX, PARENTS, EndSite, Skeleton


@dataclass
class Motion:
    """A clip of skeletal motion.

    rotations: [T, J, 3] rotation vectors of each joint relative to its parent (joint 0: world).
    root_positions: [T, 3] world position of joint 0, metres, Y up.
    """

    rotations: np.ndarray
    root_positions: np.ndarray
    fps: float
    skeleton: Skeleton = field(default_factory=lambda: DEFAULT_SKELETON)

    def __post_init__(self) -> None:
        self.rotations = np.asarray(self.rotations, dtype=np.float64)
        self.root_positions = np.asarray(self.root_positions, dtype=np.float64)
        t, j = self.rotations.shape[:2]
        if self.rotations.shape != (t, self.skeleton.num_joints, 3):
            raise ValueError(
                f"rotations must be [T, {self.skeleton.num_joints}, 3], got {self.rotations.shape}"
            )
        if self.root_positions.shape != (t, 3):
            raise ValueError(f"root_positions must be [{t}, 3], got {self.root_positions.shape}")
        if not self.fps > 0:
            raise ValueError(f"fps must be positive, got {self.fps}")

    @property
    def num_frames(self) -> int:
        return len(self.rotations)

    @property
    def duration(self) -> float:
        return self.num_frames / self.fps

    def positions(self) -> np.ndarray:
        """World joint positions [T, J, 3]."""
        return fk_numpy(self.skeleton, self.rotations, self.root_positions)[0]

    def end_effectors(self) -> np.ndarray:
        """World positions of the skeleton's end sites [T, E, 3]."""
        return fk_numpy(self.skeleton, self.rotations, self.root_positions, with_end_sites=True)[2]

    def __getitem__(self, frames: slice) -> Motion:
        if not isinstance(frames, slice):
            raise TypeError("Motion supports slicing by frames only")
        return Motion(self.rotations[frames], self.root_positions[frames], self.fps, self.skeleton)

    def resampled(self, fps: float) -> Motion:
        """The same motion at another frame rate (slerp for rotations, linear for the root)."""
        if abs(fps - self.fps) < 1e-9:
            return self
        n = max(1, int(round(self.duration * fps)))
        t_old = np.arange(self.num_frames) / self.fps
        t_new = np.clip(np.arange(n) / fps, 0.0, t_old[-1])
        if self.num_frames == 1:
            return Motion(np.repeat(self.rotations, n, 0), np.repeat(self.root_positions, n, 0), fps,
                          self.skeleton)
        rots = np.empty((n, self.skeleton.num_joints, 3))
        for j in range(self.skeleton.num_joints):
            rots[:, j] = Slerp(t_old, Rotation.from_rotvec(self.rotations[:, j]))(t_new).as_rotvec()
        root = np.stack([np.interp(t_new, t_old, self.root_positions[:, k]) for k in range(3)], -1)
        return Motion(rots, root, fps, self.skeleton)

    def mirrored(self) -> Motion:
        """Left/right mirror image (x -> -x); the skeleton must be left/right symmetric."""
        if self.skeleton.names != JOINT_NAMES:
            raise ValueError("mirroring needs the 55-joint skeleton")
        rots = self.rotations[:, list(MIRROR_INDEX)] * np.array([1.0, -1.0, -1.0])
        root = self.root_positions * np.array([-1.0, 1.0, 1.0])
        return Motion(rots, root, self.fps, self.skeleton)

    def save(self, path: str | Path) -> None:
        """Write an .npz that `Motion.load` reads back exactly (whole or not at all)."""
        s = self.skeleton
        with atomic_open(path, "wb") as f:
            np.savez_compressed(
                f,
                rotations=self.rotations.astype(np.float32),
                root_positions=self.root_positions.astype(np.float32),
                fps=np.float64(self.fps),
                joint_names=np.array(s.names),
                parents=np.array(s.parents),
                offsets=s.offsets,
                end_site_names=np.array([e.name for e in s.end_sites]),
                end_site_parents=s.end_site_parents(),
                end_site_offsets=s.end_site_offsets(),
            )

    @classmethod
    def load(cls, path: str | Path) -> Motion:
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"motion file not found: {path}")
        try:
            z = np.load(path, allow_pickle=False)
            names = tuple(str(n) for n in z["joint_names"])
            ends = tuple(
                EndSite(str(n), int(p), tuple(float(v) for v in o))
                for n, p, o in zip(z["end_site_names"], z["end_site_parents"], z["end_site_offsets"],
                                   strict=True)
            )
            parents = tuple(int(p) for p in z["parents"])
            skeleton = (
                DEFAULT_SKELETON
                if names == JOINT_NAMES and parents == PARENTS
                and np.allclose(z["offsets"], DEFAULT_SKELETON.offsets) and ends == DEFAULT_SKELETON.end_sites
                else Skeleton(z["offsets"], names, parents, ends)
            )
            return cls(z["rotations"], z["root_positions"], float(z["fps"]), skeleton)
        except (KeyError, ValueError, OSError, IndexError, TypeError, EOFError, zipfile.BadZipFile) as e:
            raise ValueError(
                f"{path} is not a DanceNet motion file (.npz from `dancenet generate`): {e}"
            ) from e

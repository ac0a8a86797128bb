"""The camera and what it frames: the figure's size, the floor's height, and a camera per frame that looks
from the front (+Z, where the rest pose faces) at the dancer's low-pass-filtered root, so steps do not shake it."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..kinematics import fk_numpy
from ..motion import Motion
from ..skeleton import Skeleton

YFOV = float(np.radians(40.0))
# Sizes below are in metres for a figure _FIGURE_HEIGHT tall; other skeletons (a BVH in centimetres,
# a child) scale them by their own height.
_FIGURE_HEIGHT = 1.70
_CAMERA_OFFSET = np.array([0.0, 0.6, 4.1])  # eye minus look-at point
_FOLLOW_SIGMA_S = 0.6  # Gaussian low-pass of the root path the camera follows, seconds
_CHUNK = 256  # frames of forward kinematics at a time, so long dances stay small in memory


def _look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Camera-to-world pose (OpenGL: the camera looks down its -Z, +Y up) from `eye` towards `target`."""
    z = eye - target
    z = z / np.linalg.norm(z)
    x = np.cross([0.0, 1.0, 0.0], z)
    x = x / np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, np.cross(z, x), z, eye
    return pose


@dataclass(frozen=True, eq=False)
class Camera:
    """A pinhole camera at `eye` looking at `target` (+Y up), exactly as the renderer draws with it."""

    eye: np.ndarray
    target: np.ndarray
    width: int
    height: int
    yfov: float = YFOV

    @property
    def pose(self) -> np.ndarray:
        """Camera-to-world 4x4 (OpenGL convention, as pyrender takes it)."""
        return _look_at(np.asarray(self.eye, float), np.asarray(self.target, float))

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel coordinates [..., 2] (x right, y down; pixel (i, j) covers [i, i+1) x [j, j+1)).

        Points behind the camera come out as NaN.
        """
        pts = np.asarray(points, dtype=np.float64)
        world_to_cam = np.linalg.inv(self.pose)
        cam = pts @ world_to_cam[:3, :3].T + world_to_cam[:3, 3]
        depth = np.where(cam[..., 2] < 0, -cam[..., 2], np.nan)
        f = 1.0 / np.tan(self.yfov / 2)
        ndc_x = f * (self.height / self.width) * cam[..., 0] / depth
        ndc_y = f * cam[..., 1] / depth
        return np.stack([(ndc_x + 1) / 2 * self.width, (1 - ndc_y) / 2 * self.height], axis=-1)


def figure_scale(skeleton: Skeleton) -> float:
    """The skeleton's rest height over a 1.70 m dancer's: sizes figure parts, floor grid and camera."""
    rest = skeleton.rest_positions()
    points = rest
    if skeleton.end_sites:
        points = np.concatenate([rest, rest[skeleton.end_site_parents()] + skeleton.end_site_offsets()])
    return max(float(np.ptp(points[:, 1])), 1e-6) / _FIGURE_HEIGHT


def _fk_chunks(motion: Motion, frames: np.ndarray) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(frame numbers, world positions [n, J, 3], world rotations [n, J, 3, 3]), a chunk at a time."""
    for start in range(0, len(frames), _CHUNK):
        chunk = frames[start:start + _CHUNK]
        pos, rot = fk_numpy(motion.skeleton, motion.rotations[chunk], motion.root_positions[chunk])
        yield chunk, pos, rot


def floor_height(motion: Motion) -> float:
    """Height of the floor: where the lowest point of the body (joints, end sites) mostly is.

    The 5th percentile over frames ignores brief dips below it (a badly fitted frame) and leaps.
    """
    skel = motion.skeleton
    lowest = []
    for _, pos, rot in _fk_chunks(motion, np.arange(motion.num_frames)):
        low = pos[..., 1].min(axis=-1)
        if skel.end_sites:
            parents = skel.end_site_parents()
            ends = pos[:, parents] + np.einsum("teij,ej->tei", rot[:, parents], skel.end_site_offsets())
            low = np.minimum(low, ends[..., 1].min(axis=-1))
        lowest.append(low)
    return float(np.percentile(np.concatenate(lowest), 5))


def camera_path(motion: Motion, width: int, height: int) -> list[Camera]:
    """One camera per frame, looking at the root's path low-pass filtered (zero-phase: no lag, no jitter).

    The camera keeps its direction and distance, so only the dancer's travel (and a slow rise or fall,
    as in a crouching dance) moves the picture; steps and bounces do not.
    """
    unit = figure_scale(motion.skeleton)
    root = motion.root_positions + motion.skeleton.offsets[0]
    targets = gaussian_filter1d(root, sigma=_FOLLOW_SIGMA_S * motion.fps, axis=0, mode="nearest")
    return [Camera(t + _CAMERA_OFFSET * unit, t, width, height) for t in targets]

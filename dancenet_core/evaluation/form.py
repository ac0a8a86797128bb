"""How alike a dance is where its song's music returns: the motion distance between the occurrences of one
section over the distance between different sections (0: a return danced exactly again; about 1: danced no more
alike than two different sections).

Sections are compared bar against bar over the shorter one's bars, at `POINTS_PER_BAR` points through each bar
(so a tempo drift between them does not count), as body poses: joint positions relative to the hips' place on
the floor, turned to face the same way (where on the floor and which way the dancer faces do not count).
"""

from __future__ import annotations

import itertools

import numpy as np

from ..music.form import SongForm

POINTS_PER_BAR = 8


def body_poses(positions: np.ndarray, headings: np.ndarray) -> np.ndarray:
    """Joint positions [T, J, 3] relative to the hips' point on the floor, turned by -heading [T] about +Y."""
    local = positions - positions[:, :1] * np.array([1.0, 0.0, 1.0])
    c, s = np.cos(-headings)[:, None], np.sin(-headings)[:, None]
    x, z = local[..., 0], local[..., 2]
    return np.stack([c * x + s * z, local[..., 1], -s * x + c * z], axis=-1)


def return_likeness(positions: np.ndarray, headings: np.ndarray, fps: float, form: SongForm,
                    start_s: float = 0.0) -> float | None:
    """Mean pose distance between occurrences of the same section over that between different sections, for a
    dance (positions [T, J, 3] and headings [T], from `start_s` seconds into the song); None when the song has
    no return, or no two different sections, within the dance."""
    poses = body_poses(positions, headings)
    edges = form.bar_starts - start_s
    inside = [s for s in form.sections if edges[s.first_bar] >= 0 and edges[s.first_bar + s.bars] * fps <= len(poses)]
    same, different = [], []
    for a, b in itertools.combinations(inside, 2):
        bars = min(a.bars, b.bars)
        d = _distance(poses, edges, fps, a.first_bar, b.first_bar, bars)
        (same if a.label == b.label else different).append(d)
    if not same or not different:
        return None
    return float(np.mean(same) / np.mean(different))


def _distance(poses: np.ndarray, edges: np.ndarray, fps: float, a: int, b: int, bars: int) -> float:
    """Mean joint distance (m) between bars a.. and b.., bar against bar at POINTS_PER_BAR points each."""
    fraction = (np.arange(POINTS_PER_BAR) + 0.5) / POINTS_PER_BAR

    def frames(first: int) -> np.ndarray:
        starts, ends = edges[first:first + bars], edges[first + 1:first + bars + 1]
        t = (starts[:, None] + fraction[None] * (ends - starts)[:, None]).ravel()
        return np.clip(np.round(t * fps).astype(int), 0, len(poses) - 1)

    return float(np.linalg.norm(poses[frames(a)] - poses[frames(b)], axis=-1).mean())

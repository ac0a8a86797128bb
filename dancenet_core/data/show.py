"""`dancenet data show SEQ`: a source frame (markers or CMU joints) beside our fitted 55-joint skeleton, as a PNG."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import DanceNetError
from ..jointmap import mapped_ancestor
from ..motion import Motion
from ..plotting import pyplot
from ..skeleton import DEFAULT_SKELETON
from .build import dataset_cache_dir, fitted_clip, fitted_motion
from .cmu_dance import read_cmu_manifest
from .dance_with_melody import P, load_positions, read_manifest

# The source viewer's lines (utils/draw.py), with mid-points written as pairs.
_SOURCE_LINES = [
    ("l_shoulder", "l_elbow"), ("l_elbow", "l_forearm"), ("l_forearm", "l_wrist"),
    ("r_shoulder", "r_elbow"), ("r_elbow", "r_forearm"), ("r_forearm", "r_wrist"),
    ("pelvis", "l_hip"), ("l_hip", "l_knee"), ("l_knee", "l_ankle"), ("l_heel", "l_toe"),
    ("pelvis", "r_hip"), ("r_hip", "r_knee"), ("r_knee", "r_ankle"), ("r_heel", "r_toe"),
    ("head_l", "head_r"),
]  # fmt: skip


def draw_fit(data_dir: Path, seq_id: str, frame: int | None, out: Path) -> None:
    """Draw a Dance with Melody sequence or a CMU clip (by its id, e.g. 60_01)."""
    cache = dataset_cache_dir()
    cache.mkdir(parents=True, exist_ok=True)
    clips = {c.clip: c for c in read_cmu_manifest(data_dir)}
    if seq_id in clips:
        motion, err, source = fitted_clip(clips[seq_id], cache)
        src = source.positions
        lines = [(k, source.joints.index(mapped_ancestor(j, source.joints)))
                 for k, j in enumerate(source.joints) if DEFAULT_SKELETON.parents[j] >= 0]
        title, centre = f"CMU {seq_id} source joints", 0
        # Where the error was measured: the floor shift undone (a constant height).
        lift = float(np.median(src[:, 0, 1] - motion.root_positions[:, 1]))
    else:
        seqs = {s.seq: s for s in read_manifest(data_dir)}
        if seq_id not in seqs:
            raise DanceNetError(f"no sequence {seq_id}; choose one of: {', '.join(sorted(seqs) + sorted(clips))}")
        motion, err = fitted_motion(seqs[seq_id], cache)
        src = load_positions(seqs[seq_id])
        lines = [(P[a], P[b]) for a, b in _SOURCE_LINES]
        title, centre, lift = "source markers (x un-mirrored)", P["pelvis"], None
    f = len(src) // 2 if frame is None else frame
    if not 0 <= f < min(len(src), motion.num_frames):
        raise DanceNetError(f"frame {f} is outside 0..{min(len(src), motion.num_frames) - 1}")
    caption = (f"{seq_id} frame {f}: fit error mean {err[f].mean() * 100:.1f} cm, max {err[f].max() * 100:.1f} cm "
               "(red = left, green = right)")
    _plot(src[f], lines, centre, motion[f : f + 1], lift, title, caption, out)


def _plot(src: np.ndarray, lines: list[tuple[int, int]], centre_point: int, motion: Motion, lift: float | None,
          src_title: str, title: str, out: Path) -> None:
    """The source points [N, 3] (joined by `lines`) beside our one-frame `motion`, raised by `lift`
    (default: onto the source's lowest point)."""
    plt = pyplot()
    fit = motion.positions()[0]
    ends = motion.end_effectors()[0]
    if lift is None:
        lift = src[:, 1].min() - min(fit[:, 1].min(), ends[:, 1].min())
    fit = fit + [0, lift, 0]
    ends = ends + [0, lift, 0]
    centre = src[centre_point]

    fig = plt.figure(figsize=(11, 6))
    for k, (sub_title, draw) in enumerate(((src_title, "src"), ("our fitted skeleton", "fit"))):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        if draw == "src":
            for a, b in lines:
                pa, pb = src[a] - centre, src[b] - centre
                ax.plot([pa[0], pb[0]], [pa[2], pb[2]], [pa[1], pb[1]], color="tab:blue")
            ax.scatter(*(src - centre)[:, [0, 2, 1]].T, s=8, color="tab:blue")
        else:
            for j, p in enumerate(motion.skeleton.parents):
                if p >= 0:
                    pa, pb = fit[p] - centre, fit[j] - centre
                    side = "tab:red" if "left" in motion.skeleton.names[j] else (
                        "tab:green" if "right" in motion.skeleton.names[j] else "k")
                    ax.plot([pa[0], pb[0]], [pa[2], pb[2]], [pa[1], pb[1]], color=side)
            for e, site in enumerate(motion.skeleton.end_sites):
                pa, pb = fit[site.parent] - centre, ends[e] - centre
                ax.plot([pa[0], pb[0]], [pa[2], pb[2]], [pa[1], pb[1]], color="gray")
            ax.scatter(*(src - centre)[:, [0, 2, 1]].T, s=6, color="tab:blue", alpha=0.4)
        ax.set_xlim(-0.9, 0.9)
        ax.set_ylim(-0.9, 0.9)
        ax.set_zlim(-1.1, 0.8)
        ax.set_xlabel("x (left +)")
        ax.set_ylabel("z (forward +)")
        ax.set_zlabel("y (up)")
        ax.view_init(elev=10, azim=-60)
        ax.set_title(sub_title)
    fig.suptitle(title)
    fig.savefig(out, dpi=90)
    plt.close(fig)

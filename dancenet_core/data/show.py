"""`dancenet data show SEQ`: a source frame's markers beside our fitted 55-joint skeleton, as a PNG."""

from __future__ import annotations

from pathlib import Path

from ..errors import DanceNetError
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
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .build import dataset_cache_dir, fitted_motion

    seqs = {s.seq: s for s in read_manifest(data_dir)}
    if seq_id not in seqs:
        raise DanceNetError(f"no sequence {seq_id}; choose one of: {', '.join(sorted(seqs))}")
    seq = seqs[seq_id]
    raw = load_positions(seq)
    cache = dataset_cache_dir()
    cache.mkdir(parents=True, exist_ok=True)
    motion, err = fitted_motion(seq, cache)
    f = len(raw) // 2 if frame is None else frame
    if not 0 <= f < min(len(raw), motion.num_frames):
        raise DanceNetError(f"frame {f} is outside 0..{len(raw) - 1}")
    src = raw[f]
    fit = motion.positions()[f]
    ends = motion.end_effectors()[f]
    floor_shift = src[:, 1].min() - min(fit[:, 1].min(), ends[:, 1].min())
    fit = fit + [0, floor_shift, 0]
    ends = ends + [0, floor_shift, 0]
    centre = src[P["pelvis"]]

    fig = plt.figure(figsize=(11, 6))
    for k, (title, draw) in enumerate((("source markers (x un-mirrored)", "src"), ("our fitted skeleton", "fit"))):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        if draw == "src":
            for a, b in _SOURCE_LINES:
                pa, pb = src[P[a]] - centre, src[P[b]] - centre
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
        ax.set_title(title)
    fig.suptitle(f"{seq_id} frame {f}: fit error mean {err[f].mean() * 100:.1f} cm, "
                 f"max {err[f].max() * 100:.1f} cm (red = left, green = right)")
    fig.savefig(out, dpi=90)
    plt.close(fig)

"""Does a free-running dance keep its level? The normalised level and root speed of DanceNet's dances against
time, beside the capture's on the same songs (exposure bias shows as a level that climbs or sinks).

The level of a frame is the mean absolute value of its modelled channels in the model's normalised units (the
capture's is about 0.3-0.4); the root speed is the root's horizontal step per frame, in m/s. Both are averaged
over the dances in bins of `BIN_S` seconds.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..data.build import PairedSequence
from ..nets.bundle import DanceNetBundle
from ..nets.variants import sample_normalized
from ..plotting import pyplot

BIN_S = 5.0


@dataclass
class LevelCurve:
    """Per bin of BIN_S seconds: normalised level and root speed (m/s), mean over dances."""

    level: np.ndarray
    root_speed: np.ndarray


def curve(frames: list[np.ndarray], bundle: DanceNetBundle) -> LevelCurve:
    """The level curve of normalised dances [T, D] (all cut to the shortest)."""
    fps = bundle.model.cfg.fps
    n = min(len(f) for f in frames)
    per_bin = int(BIN_S * fps)
    bins = n // per_bin
    modelled = ~bundle.normalizer.constant[: bundle.model.cfg.continuous_dim]
    cont = bundle.model.cfg.continuous_dim
    levels, speeds = [], []
    for f in frames:
        f = f[: bins * per_bin]
        levels.append(np.abs(f[:, :cont][:, modelled]).mean(1).reshape(bins, per_bin).mean(1))
        raw = bundle.normalizer.denormalize(f)
        speeds.append((np.hypot(raw[:, 0], raw[:, 2]) * fps).reshape(bins, per_bin).mean(1))
    return LevelCurve(np.mean(levels, 0), np.mean(speeds, 0))


def free_running(bundle: DanceNetBundle, pairs: list[PairedSequence], seconds: float = 60.0, takes: int = 1,
                 temperature: float = 1.0) -> tuple[LevelCurve, LevelCurve]:
    """The model's dances (from each real first frame, in its style, to the first `seconds` of the music) and
    the capture's, as level curves."""
    frames = int(seconds * bundle.model.cfg.fps)
    pairs = [p for p in pairs if len(p.motion) >= frames and p.style in bundle.styles]
    if not pairs:
        raise ValueError(f"no sequence of a style the model knows is {seconds:g} s long")
    norm = bundle.normalizer
    gen = [sample_normalized(bundle.model, p.music[:frames], bundle.styles.index(p.style),
                             norm.normalize(p.motion[:1])[0], temperature, np.random.default_rng(seed))
           for p in pairs for seed in range(takes)]
    real = [norm.normalize(p.motion[:frames]) for p in pairs]
    return curve(gen, bundle), curve(real, bundle)


def summary(gen: LevelCurve, real: LevelCurve) -> dict[str, float]:
    """The generated level against the capture's overall level: first and last bin, and the largest gap."""
    ref_level, ref_speed = float(real.level.mean()), float(real.root_speed.mean())
    ratio = gen.level / ref_level
    return {"real_level": ref_level, "level_first": float(ratio[0]), "level_last": float(ratio[-1]),
            "level_max_gap": float(np.abs(ratio - 1).max()), "real_root_speed_m_s": ref_speed,
            "root_speed_first": float(gen.root_speed[0] / ref_speed),
            "root_speed_last": float(gen.root_speed[-1] / ref_speed)}


def plot(curves: dict[str, LevelCurve], real: LevelCurve, path: Path) -> None:
    """Level and root speed against time: each model's curve beside the capture's."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    t = (np.arange(len(real.level)) + 0.5) * BIN_S
    for ax, field, unit in ((axes[0], "level", "normalised level"), (axes[1], "root_speed", "root speed (m/s)")):
        ax.plot(t, getattr(real, field), "k-", lw=2, label="capture")
        for name, c in curves.items():
            ax.plot(t[: len(c.level)], getattr(c, field), marker="o", ms=3, label=name)
        ax.set_xlabel("time (s)")
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
    axes[0].axhspan(0.8 * real.level.mean(), 1.2 * real.level.mean(), color="0.85", zorder=0, label="capture +-20%")
    axes[0].legend(fontsize=7)
    fig.suptitle("Free-running dances on the validation songs (foot model off, temperature 1)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)

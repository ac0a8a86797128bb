"""Training of the motion style classifier (`evaluation/motion_style.py`), `dancenet train motion-style`:
class-balanced, time-stretched and mirrored segments of the training split's dances; the held-out figures
go into the weights and the model card (`training/cards.py`)."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from ..data.build import MODEL_FPS, build_dataset
from ..data.split import load_split
from ..environment import default_data_dir
from ..errors import DanceNetError
from ..evaluation.metrics import balanced_accuracy
from ..evaluation.motion_style import (
    FPS,
    HOP_S,
    SEGMENT_S,
    MotionStyleModel,
    MotionStyleNet,
    mirrored,
    motion_input,
    resample,
)
from .configs import MotionStyleSettings

BATCH = 32
LR = 1e-3
AUG_TEMPO = 0.1  # segments are time-stretched by up to +-10%


@dataclass
class Dance:
    """One training or test dance: body positions [T, 22, 3] at FPS and its style."""

    name: str
    style: str
    positions: np.ndarray


def _sample_batch(dances: Sequence[Dance], styles: Sequence[str], length: int, batch: int,
                  rng: np.random.Generator) -> tuple[torch.Tensor, torch.Tensor]:  # fmt: skip
    """Class-balanced: a style uniformly, then one of its dances and a random crop; each crop time-stretched
    and, half the time, mirrored."""
    by_style = [[d for d in dances if d.style == st] for st in styles]
    xs, ys = [], []
    for _ in range(batch):
        y = int(rng.integers(len(styles)))
        d = by_style[y][int(rng.integers(len(by_style[y])))]
        span = min(len(d.positions), int(round(length * rng.uniform(1 - AUG_TEMPO, 1 + AUG_TEMPO))))
        start = int(rng.integers(len(d.positions) - span + 1))
        p = resample(d.positions[start : start + span], 1.0, frames=length)
        xs.append(motion_input(mirrored(p) if rng.random() < 0.5 else p, FPS))
        ys.append(y)
    return torch.from_numpy(np.stack(xs)), torch.tensor(ys)


def train_motion_style_net(
    dances: Sequence[Dance],
    *,
    steps: int = MotionStyleSettings.steps,
    batch: int = BATCH,
    lr: float = LR,
    segment_s: float = SEGMENT_S,
    seed: int = MotionStyleSettings.seed,
    config: dict | None = None,
    log: Callable[[str], None] = print,
) -> MotionStyleModel:
    """Adam on class-balanced random segments, learning rate / 10 for the last 25% of steps. Styles: those
    of `dances`, sorted."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    styles = sorted({d.style for d in dances})
    config = {"channels": 64, "hidden": 64, "dropout": 0.3, **(config or {})}
    net = MotionStyleNet(len(styles), **config)
    frames = np.concatenate([motion_input(p, FPS) for d in dances for p in (d.positions, mirrored(d.positions))])
    net.mean.copy_(torch.from_numpy(frames.mean(axis=0)))
    net.std.copy_(torch.from_numpy(frames.std(axis=0) + 1e-3))
    length = int(round(segment_s * FPS))
    opt = torch.optim.Adam(net.parameters(), lr=lr)
    sched = torch.optim.lr_scheduler.MultiStepLR(opt, [int(0.75 * steps)], 0.1)
    net.train()
    loss_sum, t0 = 0.0, time.time()
    for step in range(1, steps + 1):
        x, y = _sample_batch(dances, styles, length, batch, rng)
        loss = nn.functional.cross_entropy(net(x), y)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        loss_sum += loss.item()
        if step % max(1, steps // 10) == 0:
            log(f"step {step}/{steps} loss {loss_sum / max(1, steps // 10):.3f} ({time.time() - t0:.0f} s)")
            loss_sum = 0.0
    meta = {"segment_s": segment_s, "steps": steps, "batch": batch, "lr": lr, "seed": seed}
    return MotionStyleModel(net, styles, config, meta)


def score_dances(model: MotionStyleModel, dances: Sequence[Dance], hop_s: float = HOP_S) -> dict:
    """Held-out accuracy by segment (every hop_s) and by dance (mean of its segments), with confusions."""
    n = len(model.styles)
    by_segment, by_dance = np.zeros((n, n), int), np.zeros((n, n), int)
    predictions = {}
    for d in dances:
        truth = model.styles.index(d.style)
        probs = model.classify_segments(d.positions, FPS, hop_s)
        np.add.at(by_segment, (truth, probs.argmax(axis=1)), 1)
        mean = probs.mean(axis=0)
        by_dance[truth, int(mean.argmax())] += 1
        predictions[d.name] = {"truth": d.style, "predicted": model.styles[int(mean.argmax())],
                               "p_truth": round(float(mean[truth]), 3), "segments": len(probs),
                               "segments_right": int((probs.argmax(axis=1) == truth).sum())}  # fmt: skip
    return {
        "segment_accuracy": float(np.trace(by_segment) / by_segment.sum()),
        "segment_balanced_accuracy": balanced_accuracy(by_segment),
        "dance_accuracy": float(np.trace(by_dance) / by_dance.sum()),
        "confusion_segment": by_segment.tolist(),
        "confusion_dance": by_dance.tolist(),
        "predictions": predictions,
    }


def load_dances() -> tuple[list[Dance], list[Dance], dict]:
    """The paired dataset's train and test dances (styles of the training split only), and the split."""
    if MODEL_FPS != FPS:
        raise DanceNetError(f"the dataset runs at {MODEL_FPS} fps, the motion style model at {FPS}")
    split = load_split()
    pairs = {p.seq: p for p in build_dataset(default_data_dir(), progress=False)}
    train = [Dance(s, pairs[s].style, pairs[s].positions.astype(np.float64)) for s in split["train"]]
    styles = {d.style for d in train}
    test = [Dance(s, pairs[s].style, pairs[s].positions.astype(np.float64)) for s in split["test"]
            if pairs[s].style in styles]  # fmt: skip
    return train, test, split


def train_and_ship(settings: MotionStyleSettings) -> MotionStyleModel:
    """Train on the training split, evaluate on the test split and write the weights (with those figures)."""
    torch.set_num_threads(1)
    train, test, _ = load_dances()
    t0 = time.time()
    model = train_motion_style_net(train, steps=settings.steps, seed=settings.seed)
    model.meta["train_seconds"] = round(time.time() - t0)
    model.meta["metrics"] = score_dances(model, test)
    model.meta["train_metrics"] = {k: v for k, v in score_dances(model, train).items() if k.endswith("accuracy")}
    model.save(settings.out)
    return model

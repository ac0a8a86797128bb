"""Training speed of DanceNet, printed as JSON: training frames per second (forward, backward, optimiser
step) for several settings measured in one run, interleaved round by round so a busy machine slows them
alike, and each one's ratio to the shipped setting of the first release (one Gaussian, batch 16, torch's
default threads).

    .venv/bin/python bench/training.py [--rounds 3] [--steps 3]

Inputs are random tensors of the real shapes (8-s windows of 185 features, 15 music channels): the
window sampler costs well under 1% of a step, and the benchmark then needs no data.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from dancenet_core.nets.variants import build_model  # noqa: E402
from dancenet_core.representation import FeatureLayout  # noqa: E402

WINDOW = 200
SETTINGS = {  # name -> (mixtures, batch, threads)
    "first release (K=1, batch 16, 2 threads)": (1, 16, 2),
    "K=1, batch 16, 1 thread": (1, 16, 1),
    "K=1, batch 64, 2 threads": (1, 64, 2),
    "K=8, batch 16, 2 threads (shipped now)": (8, 16, 2),
}


def step_seconds(mixtures: int, batch: int, threads: int, steps: int) -> float:
    """Median wall time of one optimiser step after a warm-up step."""
    torch.set_num_threads(threads)
    torch.manual_seed(0)
    layout = FeatureLayout(55, 5)
    model = build_model("dancenet", layout.size, layout.continuous.stop, ["a", "b", "c", "d"], WINDOW,
                        mixtures=mixtures)
    opt = torch.optim.RMSprop(model.parameters(), lr=1e-4)
    x = torch.randn(batch, WINDOW, layout.size)
    music = torch.randn(batch, WINDOW, model.cfg.music_dim)
    style = torch.zeros(batch, dtype=torch.long)
    times = []
    for _ in range(steps + 1):
        t = time.perf_counter()
        out = model(torch.nn.functional.dropout(x, 0.4), music, style)
        loss, _ = model.loss(out, x[:, 1:], music[:, 1:])
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 10.0)
        opt.step()
        times.append(time.perf_counter() - t)
    return float(np.median(times[1:]))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--steps", type=int, default=3)
    args = p.parse_args()
    fps: dict[str, list[float]] = {name: [] for name in SETTINGS}
    for _ in range(args.rounds):
        for name, (k, b, threads) in SETTINGS.items():
            fps[name].append(b * (WINDOW - 1) / step_seconds(k, b, threads, args.steps))
    base = float(np.median(fps[next(iter(SETTINGS))]))
    result = {
        "frames_per_second": {name: round(float(np.median(v))) for name, v in fps.items()},
        "ratio_to_first_release": {name: round(float(np.median(v)) / base, 2) for name, v in fps.items()},
        "rounds": args.rounds,
        "steps_per_measure": args.steps,
        "cpu_threads_available": torch.get_num_threads(),
    }
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()

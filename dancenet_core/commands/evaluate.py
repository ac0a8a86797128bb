"""`dancenet evaluate`: the paper's comparison table on the test split (`evaluation/comparison.py`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..evaluation import comparison


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = comparison.__doc__
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.add_argument("--data", type=Path, default=None, help="shared data folder (default ../shared/data)")
    p.add_argument("--out", type=Path, default=Path("out/evaluate"))
    p.add_argument("--runs", type=Path, default=Path("runs/compare"), help="where the compared models train")
    p.add_argument("--steps", type=int, default=800, help="training steps of every compared model")
    p.add_argument("--jobs", type=int, default=2, help="models trained at once (one CPU thread each)")
    p.add_argument("--takes", type=int, default=2, help="dances per test sequence and model (seeds 0..)")
    p.add_argument("--temperature", type=float, default=None, help="sampling temperature of the GMM models")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--variants", nargs="*", default=None,
                   help="a subset of the models (default: all; the flag with no names: only the shipped weights "
                   "and the real dances)")
    p.add_argument("--library", action="store_true",
                   help="add the motion-library engine's row (the training dances as its library)")
    p.add_argument("--library-only", action="store_true",
                   help="only the real dances and the motion-library engine's row (no DanceNet trained or run)")
    p.set_defaults(handler=comparison.compare)

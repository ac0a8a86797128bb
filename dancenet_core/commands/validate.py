"""`dancenet validate`: DanceNet's sampling settings (or a run's learning curve) on the validation songs."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..engines.dancenet import CLEANUPS, FOOT_CLEANUP
from ..evaluation import comparison


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = comparison.validate.__doc__
    p.add_argument("weights", nargs="*", help="DanceNet weights files (bundles) to compare (none with --curve)")
    p.add_argument("--data", type=Path, default=None, help="shared data folder (default ../shared/data)")
    p.add_argument("--pack", type=Path, default=None,
                   help="a training pack (`dancenet data pack`) instead of the data folder (no madmom needed)")
    p.add_argument("--out", type=Path, default=Path("out/validate"))
    p.add_argument("--drift", type=float, default=0.0, metavar="SECONDS",
                   help="also: free-running dances of this length against the capture's level and root speed, "
                        "per weights file (drift.png, drift.json; foot model off, the last temperature)")
    p.add_argument("--temperatures", type=float, nargs="+", default=[0.1, 0.3, 0.5, 1.0])
    p.add_argument("--smoothing", type=float, nargs="+", default=[1.0], help="output smoothing sigmas (frames)")
    p.add_argument("--takes", type=int, default=2)
    p.add_argument("--footfix", type=Path, default=None, metavar="NPZ",
                   help="a foot model's runtime weights (a run's footfix.npz) instead of the shipped one")
    p.add_argument("--cleanup", nargs="+", choices=[*CLEANUPS, "none"], default=[FOOT_CLEANUP],
                   help=f"foot clean-ups to compare (default: generation's, {FOOT_CLEANUP}; none: the floor only)")
    p.add_argument("--beat-lock", nargs="+", choices=["on", "off"], default=["on"],
                   help="with the beat lock (generation's default), without it, or both (on off)")
    p.add_argument("--curve", type=Path, default=None, metavar="RUN",
                   help="instead: the learning curve of a training run folder (its snapshots and log)")
    p.set_defaults(handler=comparison.validate)

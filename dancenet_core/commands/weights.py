"""`dancenet weights upgrade FILE...`: convert weights files of the old pickled format, in place, to plain
tensors that load with `weights_only=True` (same numbers); anything but that format's classes is refused.
`dancenet weights export [--weights DIR]`: write the plain arrays generation runs on (`.npz`, no torch) from
the DanceNet, style classifier and Foot Constraint Model checkpoints in DIR (training does this itself)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..checkpoint import upgrade
from ..environment import WEIGHTS_DIR
from ..nets.export import export_runtime


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    up = sub.add_parser("upgrade", help="convert old weights files in place to the safe format")
    up.add_argument("files", nargs="+", type=Path)
    up.set_defaults(handler=_upgrade)
    ex = sub.add_parser("export", help="write the runtime's .npz files from the checkpoints (.pt) in a folder")
    ex.add_argument("--weights", type=Path, default=WEIGHTS_DIR, help="folder of the checkpoints (default: shipped)")
    ex.set_defaults(handler=_export)


def _upgrade(args: argparse.Namespace) -> int:
    for f in args.files:
        upgrade(f)
        print(f"{f}: plain weights")
    return 0


def _export(args: argparse.Namespace) -> int:
    for path in export_runtime(args.weights):
        print(f"{path}: {path.stat().st_size / 1e6:.1f} MB")
    return 0

"""`dancenet weights upgrade FILE...`: convert TRUSTED weights files of the old pickled format, in place, to
plain tensors that load with `weights_only=True` (same numbers)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..checkpoint import upgrade


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    up = sub.add_parser("upgrade", help="convert TRUSTED old weights files in place to the safe format")
    up.add_argument("files", nargs="+", type=Path)
    up.set_defaults(handler=_upgrade)


def _upgrade(args: argparse.Namespace) -> int:
    for f in args.files:
        upgrade(f)
        print(f"{f}: plain weights")
    return 0

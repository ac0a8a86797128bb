"""`dancenet card dancenet|style|motion-style|library`: rewrite a model card from trained weights (or the shipped
motion library's from its arrays), without retraining.
DanceNet's card measures the weights on the test songs (with and without the foot clean-up and the beat lock) as
it goes, and keeps the measured tables of the card it rewrites."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..atomic import write_text
from ..checkpoint import load_weights
from ..constants import DEFAULT_TEMPERATURE
from ..environment import WEIGHTS_DIR, default_data_dir
from ..errors import DanceNetError
from ..evaluation.motion_style import DEFAULT_WEIGHTS as MOTION_STYLE_WEIGHTS
from ..evaluation.test_split import evaluate_on_test_split
from ..library.store import DEFAULT_LIBRARY
from ..nets.bundle import DEFAULT_BUNDLE, DanceNetBundle
from ..nets.footfix import WEIGHTS as FOOTFIX_WEIGHTS
from ..training.cards import (
    dancenet_card,
    kept_sections,
    validation_sections,
    write_library_card,
    write_motion_style_card,
    write_style_card,
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="model", required=True, metavar="MODEL")
    d = sub.add_parser("dancenet", help="measure DanceNet on the test songs; with --card, write its model card")
    d.add_argument("--weights", type=Path, default=DEFAULT_BUNDLE)
    d.add_argument("--data", type=Path, default=None, help="shared data folder (default ../shared/data)")
    d.add_argument("--temperature", type=float, default=DEFAULT_TEMPERATURE)
    d.add_argument("--seed", type=int, default=0)
    d.add_argument("--footfix", action="store_true", help="measure with the foot clean-up")
    d.add_argument("--no-beat-lock", dest="beat_lock", action="store_false",
                   help="measure without the beat lock (generation locks the dance to the song's beats)")
    d.add_argument("--json", type=Path, default=None, help="write the measurements as JSON")
    d.add_argument("--card", type=Path, default=None,
                   help="write the model card: measures the beat-locked dances with and without the foot clean-up "
                        "and the cleaned ones without the beat lock; keeps the measured tables of the card there")
    d.add_argument("--validation", type=Path, default=None,
                   help="folder of `dancenet validate` outputs to put in the card in place of its measured tables "
                        "(validation table, learning curve)")
    d.set_defaults(handler=_dancenet)
    s = sub.add_parser("style", help="STYLE_MODEL_CARD.md from the two checkpoints' stored metrics")
    s.add_argument("--data", type=Path, default=None, help="shared data folder (default ../shared/data)")
    s.add_argument("--out", type=Path, default=WEIGHTS_DIR, help="folder of the checkpoints, split and card")
    s.add_argument("--split", type=Path, default=None, help="split file (default OUT/song_split.json)")
    s.set_defaults(handler=_style)
    m = sub.add_parser("motion-style", help="the motion style model card from the metrics in its weights")
    m.add_argument("--weights", type=Path, default=MOTION_STYLE_WEIGHTS, help="weights file (the card goes beside it)")
    m.set_defaults(handler=_motion_style)
    lib = sub.add_parser("library", help="the shipped motion library's card from its arrays (its measured "
                         "sections kept)")
    lib.add_argument("--library", type=Path, default=DEFAULT_LIBRARY, help="the built library (the card goes beside "
                     "it)")
    lib.set_defaults(handler=_library)


def _dancenet(args: argparse.Namespace) -> int:
    if args.card and (args.footfix or not args.beat_lock):
        raise DanceNetError("--card measures with and without the foot clean-up and the beat lock itself: "
                            "leave out --footfix and --no-beat-lock")
    bundle = DanceNetBundle.load(args.weights)
    data = args.data or default_data_dir()
    result = evaluate_on_test_split(bundle, data, args.temperature, args.seed, args.footfix, args.beat_lock)
    if args.json:
        write_text(args.json, json.dumps(result, indent=1) + "\n")
    print(json.dumps(result["summary"], indent=1))
    if args.card:
        fixed = evaluate_on_test_split(bundle, data, args.temperature, args.seed, footfix=True)
        unlocked = evaluate_on_test_split(bundle, data, args.temperature, args.seed, footfix=True, beat_lock=False)
        print(json.dumps({"with_footfix": fixed["summary"]["generated"],
                          "with_footfix_no_beat_lock": unlocked["summary"]["generated"]}, indent=1))
        ff = (load_weights(FOOTFIX_WEIGHTS, "Foot Constraint Model weights", "train it")["info"]
              if FOOTFIX_WEIGHTS.is_file() else None)
        kept = validation_sections(args.validation) if args.validation else kept_sections(args.card)
        write_text(args.card, dancenet_card(bundle, result, fixed, unlocked, ff, kept))
    return 0


def _style(args: argparse.Namespace) -> int:
    print(write_style_card(args.data or default_data_dir(), args.out, args.split))
    return 0


def _motion_style(args: argparse.Namespace) -> int:
    print(write_motion_style_card(args.weights))
    return 0


def _library(args: argparse.Namespace) -> int:
    print(write_library_card(args.library))
    return 0

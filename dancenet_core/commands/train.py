"""`dancenet train dancenet|blend|footfix|style|motion-style|match`: the options come from the settings dataclasses
(`training/configs.py`), so the command line and code that builds settings directly never disagree."""

from __future__ import annotations

import argparse
import json

from ..environment import default_data_dir
from ..music.style import ARCHS
from ..training.blend import blend_files
from ..training.cards import write_motion_style_card, write_style_card
from ..training.configs import (
    BlendSettings,
    FootfixSettings,
    MatchSettings,
    MotionStyleSettings,
    StyleSettings,
    TrainSettings,
    add_options,
    from_args,
)
from ..training.dancenet import train
from ..training.footfix import train_footfix
from ..training.match import train_and_ship as train_match
from ..training.motion_style import train_and_ship
from ..training.style import train_style


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="model", required=True, metavar="MODEL")
    for name, settings, handler in (("dancenet", TrainSettings, _dancenet), ("blend", BlendSettings, _blend),
                                    ("footfix", FootfixSettings, _footfix),
                                    ("style", StyleSettings, _style),
                                    ("motion-style", MotionStyleSettings, _motion_style),
                                    ("match", MatchSettings, _match)):
        q = sub.add_parser(name, help=settings.__doc__.splitlines()[0], description=settings.__doc__)
        add_options(q, settings)
        q.set_defaults(handler=handler)


def _dancenet(args: argparse.Namespace) -> int:
    print(train(from_args(TrainSettings, args)))
    return 0


def _blend(args: argparse.Namespace) -> int:
    s = from_args(BlendSettings, args)
    print(blend_files(s.start, s.end, s.alpha, s.out, s.data, s.pack))
    return 0


def _footfix(args: argparse.Namespace) -> int:
    print(json.dumps(train_footfix(from_args(FootfixSettings, args)), indent=2))
    return 0


def _style(args: argparse.Namespace) -> int:
    settings = from_args(StyleSettings, args)
    results = train_style(settings, log=lambda m: print(m, flush=True))
    if not settings.validate and set(settings.arch) == set(ARCHS):
        print(write_style_card(settings.data or default_data_dir(), settings.out, settings.split))
    print(json.dumps({k: {m: v[m] for m in ("window_accuracy", "song_accuracy")} for k, v in results.items()}))
    return 0


def _motion_style(args: argparse.Namespace) -> int:
    settings = from_args(MotionStyleSettings, args)
    model = train_and_ship(settings)
    m = model.meta["metrics"]
    print(f"trained in {model.meta['train_seconds']} s; held-out segment accuracy {m['segment_accuracy']:.3f}, "
          f"dance accuracy {m['dance_accuracy']:.3f}")
    print(write_motion_style_card(settings.out))
    return 0


def _match(args: argparse.Namespace) -> int:
    settings = from_args(MatchSettings, args)
    f = train_match(settings)
    r, st, en = f["retrieval"], f["style_transfer"], f["style_transfer_energy"]
    print(f"{f['held_out']} songs: retrieval top-1 {r['top1']:.3f}, top-5 {r['top5']:.3f} of {r['candidates']}; "
          f"own style of the best bar {st['style_mean']:.3f} (energy matching {en['style_mean']:.3f}), mean of styles")
    print(f"wrote {settings.out}")
    return 0

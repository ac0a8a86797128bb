"""Training settings as dataclasses: the one place each option, its default and its help live. The command
line (`dancenet train ...`) is generated from them, and tests and scripts build them directly."""

from __future__ import annotations

import argparse
import dataclasses
import types
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Union, get_args, get_origin, get_type_hints

from ..environment import WEIGHTS_DIR
from ..music.style import ARCHS


def _option(default: Any, help: str, **argparse_kwargs: Any) -> Any:
    """A field with its command-line help (and any argparse settings it needs); a list default is copied."""
    metadata = {"help": help, **argparse_kwargs}
    if isinstance(default, list):
        return field(default_factory=lambda: list(default), metadata=metadata)
    return field(default=default, metadata=metadata)


@dataclass
class TrainSettings:
    """DanceNet (or, with `variant`, an ablation or baseline of the paper's comparison): the supplement's
    settings, sized for a 2-core CPU."""

    data: Path | None = _option(None, "shared data folder (default ../shared/data)")
    variant: str = _option("dancenet", "model of the paper's comparison (nets/variants.py)")
    out: Path = _option(Path("runs/dancenet"), "run folder: checkpoints, log and the trained dancenet.pt")
    minutes: float = _option(100.0, "training time budget")
    steps: int = _option(6000, "planned steps (lr drops by 10 at 77%%)")
    batch: int = _option(16, "windows per step")
    window: int = _option(200, "frames per window (8 s at 25 fps)")
    lr: float = _option(4e-4, "RMSprop learning rate")
    seed: int = _option(0, "seed of the windows, noise and initial weights")
    log_every: int = _option(20, "steps between log lines")
    checkpoint_every: int = _option(200, "steps between resumable checkpoints")
    resume: bool = _option(False, "continue from the run folder's checkpoint (the budget counts across sittings)")
    snapshot_every: int = _option(0, "keep the weights every N steps (0: never)")
    residual_output: bool = _option(
        False, "predict each frame as a change from the last one instead of outright: far better one step ahead, "
               "but free-running dances drift away (docs/experiments.md); off by default")
    own_inputs: float = _option(
        0.0, "share of input frames replaced by the model's own one-step draws (against exposure bias: the model "
             "learns to steer back from its own mistakes); costs one more forward pass")
    input_skip: bool = _option(
        False, "a linear path from the input frame to the outputs beside the residual stack (starts at zero, so a "
               "warm start begins as its source): carries the root's steps, outputs stay absolute")
    mixtures: int = _option(8, "Gaussian mixture components (DanceNet variants)")
    widths: list[int] = _option(
        [], "motion, residual and skip channels (default the shipped 256 64 256; the authors released 512 64 512)",
        nargs=3)
    own_passes: int = _option(
        1, "chained passes of own draws: pass k feeds the draws of pass k-1, so a stretch of N own frames is a "
           "true N-frame rollout when N <= passes (acLSTM's auto-conditioning, in parallel)")
    own_stretch: int = _option(
        0, "own frames come in stretches of this many, between stretches of real frames as long (0: single "
           "frames scattered at random)")
    own_ramp: float = _option(
        0.0, "share of the run over which the share of own frames rises from 0 to --own-inputs (scheduled sampling)")
    own_temperature: float = _option(1.0, "temperature of the own draws (generation runs at 1.0)")
    travel_weight: float = _option(
        0.0, "weight of the travel loss: the root's predicted displacement and turn summed over --travel-windows "
             "against the dancer's (keeps the path a dance takes, not only its next step)")
    travel_windows: list[int] = _option([25, 100], "frame counts the travel loss sums over (1 s and 4 s)", nargs="+")
    history_dropout: float = _option(
        0.0, "share of input frames hidden whole (set to the capture's mean) in stretches of --history-stretch "
             "frames: with the last frames hidden the model has to find where the dance is in its bar from the "
             "music, which it otherwise reads off the frames before")
    history_stretch: int = _option(12, "length in frames of each hidden stretch of --history-dropout (12: about a "
                                       "beat at 120 BPM)")
    pack: Path | None = _option(
        None, "train from a training pack (`dancenet data pack`) instead of the data folder (a GPU machine "
              "without madmom or the data)")
    input_noise: float = _option(0.04, "Gaussian noise on the normalised input frames (the authors' 0.04)")
    input_dropout: float | None = _option(
        0.1, "share of input channels zeroed in training (the authors: 0.4; it hides the previous frame's root "
             "velocity so often that the model learns to shuffle: see the model card)")
    motion_prior: bool = _option(
        False, "train a motion prior: the training songs' dances and the CMU dance clips without music, in one "
               "style (training/prior.py); fine-tune it on the paired dances with --init")
    init: Path | None = _option(None, "warm start from a trained DanceNet bundle")
    validation: bool = _option(False, "leave the split's validation songs out of training (to choose settings on them)")


@dataclass
class BlendSettings:
    """A DanceNet between two runs of one lineage: (1 - alpha) x START + alpha x END, weight by weight."""

    start: Path = _option(WEIGHTS_DIR / "dancenet.pt", "weights the END run was warm-started from")
    end: Path = _option(Path("runs/dancenet/dancenet.pt"), "weights of the run continued from START")
    alpha: float = _option(0.5, "how far toward END (0: START, 1: END)")
    out: Path = _option(Path("runs/blend/dancenet.pt"), "bundle to write (its .npz twin goes beside it)")
    data: Path | None = _option(
        None, "shared data folder to measure the blend's held-out loss on (default ../shared/data)")
    pack: Path | None = _option(None, "or a training pack (`dancenet data pack`) to measure it on")


@dataclass
class FootfixSettings:
    """The Foot Constraint Model and its LSTM baseline, on the training split and DanceNet's own dances."""

    data: Path | None = _option(None, "shared data folder (default ../shared/data)")
    steps: int = _option(400, "training steps of each model")
    seeds: int = _option(2, "DanceNet dances per training song for the contact loss")
    slide_weight: float = _option(2.5, "weight of the contact loss's sliding term")
    root_weight: float = _option(3.0, "weight of the contact loss's pelvis-velocity term")
    dancenet: Path = _option(WEIGHTS_DIR / "dancenet.pt", "DanceNet weights whose dances it learns to fix")
    out: Path = _option(WEIGHTS_DIR / "footfix.pt", "weights file to write")


@dataclass
class StyleSettings:
    """The music style classifier and its baseline, trained the same way on a fixed song split."""

    data: Path | None = _option(None, "shared data folder, or one with manifest.csv and the songs")
    out: Path = _option(WEIGHTS_DIR, "folder of the checkpoints, split and model card")
    split: Path | None = _option(None, "split file (reused if it exists; default OUT/song_split.json)")
    steps: int = _option(400, "training steps")
    lr: float = _option(1e-3, "Adam learning rate")
    batch: int = _option(64, "windows per step")
    seed: int = _option(2020, "seed of the split (if made) and of training")
    threads: int = _option(1, "torch threads")
    arch: list[str] = _option(list(ARCHS), "the models to train", choices=ARCHS, nargs="+")
    validate: bool = _option(
        False, "hold out training songs by song instead of the test songs, to choose settings; ships nothing")


@dataclass
class MotionStyleSettings:
    """The motion style classifier (the evaluation's FID features and style judge)."""

    out: Path = _option(WEIGHTS_DIR / "motion_style.pt", "weights file (the card goes beside it)")
    steps: int = _option(1200, "training steps")
    seed: int = _option(2020, "seed of training")


@dataclass
class MatchSettings:
    """The match of music and movement (the library engine's figures against the song's bars), settings chosen on
    the validation songs."""

    out: Path = _option(WEIGHTS_DIR / "match.npz", "weights file (the card goes beside it)")
    validate: bool = _option(False, "report on the validation songs (never on the test songs) and write the card "
                                    "beside --out as <name>_card.md; training leaves the validation songs out "
                                    "either way")
    steps: int = _option(600, "training steps (lr drops by 10 at 75%%)")
    context: int = _option(2, "bars of music either side of a bar that its embedding reads")
    style_weight: float = _option(1.0, "weight of the training styles' classifier loss on both embeddings beside "
                                       "the contrastive one (0: contrastive alone)")
    balanced: bool = _option(True, "batches drawn with every style equally likely")
    dropout: float = _option(0.5, "dropout of the inputs and the hidden layer")
    noise: float = _option(0.5, "Gaussian noise on the standardised inputs in training")
    temperature: float = _option(0.1, "temperature of the contrastive loss")
    seed: int = _option(0, "seed of training")


def _plain_type(annotation: Any) -> Any:
    """`Path | None` -> Path: the type argparse converts a value with."""
    if get_origin(annotation) in (Union, types.UnionType):
        return next(a for a in get_args(annotation) if a is not type(None))
    return annotation


def add_options(parser: argparse.ArgumentParser, settings: type) -> None:
    """One `--option` per field of the dataclass `settings` (booleans as --x/--no-x), defaults and help from it."""
    hints = get_type_hints(settings)
    for f in dataclasses.fields(settings):
        meta = dict(f.metadata)
        kind = _plain_type(hints[f.name])
        flag = "--" + f.name.replace("_", "-")
        if kind is bool:
            parser.add_argument(flag, action=argparse.BooleanOptionalAction, default=f.default, **meta)
        elif get_origin(kind) is list:
            parser.add_argument(flag, type=get_args(kind)[0], default=f.default_factory(), **meta)
        else:
            parser.add_argument(flag, type=kind, default=f.default, **meta)


def from_args(settings: type, args: argparse.Namespace) -> Any:
    """The dataclass `settings` filled from parsed options (those `add_options` made)."""
    return settings(**{f.name: getattr(args, f.name) for f in dataclasses.fields(settings)})

"""What a user asks for: one `DanceRequest`, built by the command line, the Blender add-on, batch mode and the
tests, and checked here (one-line DanceNetErrors) before a second of music analysis.

Each field that a user sets carries an `Option` in its metadata: how the command line and batch mode offer it
(`add_options`, `options_from`) and, with a label, how the add-on's Dance panel does (`panel_options`). A new
setting is a field here and the engine that reads it; the front-ends pick it up from the metadata.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterator
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .constants import DEFAULT_TEMPERATURE, FRAME_RATES, MAX_TEMPERATURE, MIN_PART_S, ROOT_MODES
from .errors import DanceNetError

if TYPE_CHECKING:
    from .motion import Motion

MAX_SEED = 2**32 - 1
MAX_TAKES = 100
DEFAULT_ENGINE = "dancenet"
# The energy presets' factors on the temperature (1 keeps the dance as the user's temperature makes it) and on the
# size of the moves (`engines.dancenet.scale_moves`): a model trained with the travel loss moves about as much at
# any temperature (joint speed 1.24 vs 1.36 m/s at x0.6 and x1.3 on the example song), so the preset scales both.
ENERGY_SCALES = {"calm": 0.6, "as-danced": 1.0, "lively": 1.3}
ENERGY_MOVES = {"calm": 0.75, "as-danced": 1.0, "lively": 1.15}


@dataclass(frozen=True)
class Option:
    """How a DanceRequest field is offered to users.

    `flag` names the command-line option (`dancenet generate` and batch mode; None: not an option there);
    `label` puts it on the add-on's Dance panel (None: not there); `choices` are (value, label, description)
    triples; `panel_max`/`soft_max` bound the panel's slider where it should stop short of what a request
    accepts.
    """

    help: str
    kind: type = str
    flag: str | None = None
    label: str | None = None
    choices: tuple[tuple[str, str, str], ...] = ()
    minimum: float | None = None
    maximum: float | None = None
    soft_max: float | None = None
    panel_max: float | None = None
    metavar: str | None = None


def _option(default: Any, option: Option) -> Any:
    return field(default=default, metadata={"option": option})


_ROOT_LABELS = {
    "travel": ("Travelling", "The dancer moves across the floor as danced"),
    "in-place": ("In Place", "The hips' path across the floor removed; turns and height kept"),
    "root-bone": ("Root Bone", "A root bone on the floor carries the path and heading (game engines); a new rig "
                  "gets one"),
}
_ROOT_CHOICES = tuple((mode, *_ROOT_LABELS[mode]) for mode in ROOT_MODES)


RETURN_CHOICES = (
    ("repeat", "Repeat", "A returning section is danced as it was the first time"),
    ("mirror", "Mirror", "A returning section is danced as the first time, left and right swapped"),
    ("anew", "Anew", "Every section is danced anew"))


@dataclass(frozen=True)
class SectionOverride:
    """Settings for one section of the song's form (`music.form`: A1, B1, A2, ...) that differ from the dance's:
    its style or energy (the section is then danced anew with them), or how it is danced where it returns."""

    section: str
    style: str | None = None
    energy: str | None = None
    returns: str | None = None

    KEYS = ("style", "energy", "returns")

    @classmethod
    def parse(cls, text: str) -> SectionOverride:
        """`A2:style=tango,energy=lively,returns=anew` (the command line's and batch lists' form)."""
        name, _, rest = str(text).partition(":")
        values: dict[str, str] = {}
        for item in filter(None, (p.strip() for p in rest.split(","))):
            key, eq, value = item.partition("=")
            if not eq or key.strip() not in cls.KEYS or not value.strip():
                raise DanceNetError(f"section setting '{item}' in '{text}': write SECTION:key=value,... with keys "
                                    f"{', '.join(cls.KEYS)} (e.g. A2:style=tango,energy=lively)")
            values[key.strip()] = value.strip()
        if not name.strip() or not values:
            raise DanceNetError(f"section settings '{text}': write SECTION:key=value,... (e.g. A2:returns=anew)")
        return cls(name.strip(), **values)

    @classmethod
    def parse_many(cls, text: str) -> tuple[SectionOverride, ...]:
        """Settings of several sections separated by ';' (a batch list's cell), or of one."""
        return tuple(cls.parse(t) for t in str(text).split(";") if t.strip())

    def __str__(self) -> str:
        return f"{self.section}:" + ",".join(f"{k}={getattr(self, k)}" for k in self.KEYS if getattr(self, k))

    @property
    def redances(self) -> bool:
        """Whether the section is danced anew with settings of its own (a style or an energy)."""
        return self.style is not None or self.energy is not None


@dataclass(frozen=True)
class DanceRequest:
    """One Generate Dance: the song, the part of it, how to dance it and how to shape the takes.

    No bpy objects and nothing mutable is shared: it crosses to the add-on's worker thread as it is.
    """

    song: Path  # an audio file (the add-on passes a sound strip's file)
    style: str = _option("auto", Option(
        "auto (the music's style) or a style the engine knows", flag="--style"))
    seed: int = _option(0, Option(
        "another seed, another dance to the same song; same seed, same dance", int, "--seed", "Seed", minimum=0,
        maximum=MAX_SEED))
    temperature: float = _option(DEFAULT_TEMPERATURE, Option(
        f"variety of the dance: 1 as the model learnt the dancers, lower calmer, 0 the most likely "
        f"(default {DEFAULT_TEMPERATURE:g})", float, "--temperature", "Temperature", minimum=0.0,
        maximum=MAX_TEMPERATURE, soft_max=1.5))
    takes: int = _option(1, Option(
        "different dances generated at once (one file set, or one action, each)", int, "--takes", "Takes",
        minimum=1, maximum=MAX_TAKES, panel_max=8))
    energy: str = _option("as-danced", Option(
        "how much the dancer puts in: calm or lively scale the size of the moves (x0.75, x1.15) and the "
        f"temperature (x0.6, x1.3, at most {MAX_TEMPERATURE:g})", str, "--energy", "Energy", choices=(
            ("calm", "Calm", "Smaller, steadier moves (moves x0.75, temperature x0.6)"),
            ("as-danced", "As Danced", "The moves and the temperature as the model makes them"),
            ("lively", "Lively", "Bolder, bigger moves (moves x1.15, temperature x1.3)"))))
    footfix: bool = _option(True, Option(
        "remove foot sliding and floor contact errors", bool, "--no-footfix",
        "Foot Clean-up"))
    beat_lock: bool = _option(True, Option(
        "lock the dance to the song's beats: its own beats moved onto them, every frame played at 0.85-1.15x the "
        "speed it was danced", bool, "--no-beat-lock", "Beat Lock"))
    start_s: float = _option(0.0, Option(
        "dance from this many seconds into the song (default: its beginning)", float, "--start",
        metavar="SECONDS"))
    end_s: float | None = _option(None, Option(
        "dance up to this many seconds into the song (default: its end)", float, "--end", metavar="SECONDS"))
    fps: float | None = _option(None, Option(
        "frame rate of the takes, slerp-resampled (default: the engine's own, 25 for DanceNet)", int, "--fps",
        choices=tuple((str(r), str(r), "") for r in FRAME_RATES)))
    root_motion: str = _option("travel", Option(
        "travel (as danced), in-place (no horizontal path, heading kept) or root-bone (a 'root' joint on the "
        "floor carries path and heading)", str, "--root-motion", "Root Motion", choices=_ROOT_CHOICES))
    returns: str = _option("repeat", Option(
        "where the music returns (a chorus heard again): repeat the dance of its first hearing, mirror it (left "
        "and right swapped) or dance it anew", str, "--returns", "Returns", choices=RETURN_CHOICES))
    sections: tuple[SectionOverride, ...] = _option((), Option(
        "settings of one section of the song's form (`dancenet analyze` names them A1, B1, A2, ...), repeatable: "
        "SECTION:style=S,energy=E,returns=R (e.g. A2:style=tango,energy=lively)", SectionOverride.parse_many,
        "--section", metavar="SECTION:KEY=VALUE,..."))
    redo_section: str | None = None  # with continue_from: dance only this section anew, keep the rest of it
    continue_from: Motion | None = None  # a dance to the same part of the song, kept up to `at_s` seconds
    at_s: float = 0.0
    engine: str = _option(DEFAULT_ENGINE, Option(
        "what makes the dance: dancenet (the network dances anew) or library (figures cut from motion capture on "
        "the song's beats)", str, "--engine", "Engine", choices=(
            ("dancenet", "DanceNet", "The network dances anew to the music"),
            ("library", "Motion Library", "Figures cut from a library of motion capture on the song's beats"))))
    weights: str | None = _option(None, Option(
        "the engine's weights file (default: the shipped ones)", str, "--weights"))
    library: Path | None = _option(None, Option(
        "a folder of BVH clips built with `dancenet library build` (default: the shipped CMU dance clips), for "
        "--engine library", Path, "--library", "Library", metavar="FOLDER"))
    commercial: bool = _option(False, Option(
        "make a dance a studio may use: only parts whose terms allow commercial use run (the weight-free music "
        "analysis, the motion library engine on a library of your own clips; docs/licence.md)", bool,
        "--commercial", "Commercial Use"))

    def check(self) -> None:
        """Reject what no engine can dance, whatever the song: a one-line DanceNetError that says what to do."""
        self.check_settings()
        check_song_path(self.song)

    def check_settings(self) -> None:
        """`check` without the song: the settings a batch gives all its songs, checked before any is read."""
        check_part(self.start_s, self.end_s)
        if isinstance(self.seed, bool) or not isinstance(self.seed, int | np.integer) or \
                not 0 <= self.seed <= MAX_SEED:
            raise DanceNetError(f"seed must be a whole number from 0 to {MAX_SEED}, got {self.seed}")
        if not 0 <= self.temperature <= MAX_TEMPERATURE:  # also false for NaN
            raise DanceNetError(f"temperature must be from 0 to {MAX_TEMPERATURE:g} (0 = the most likely dance, "
                                f"default {DEFAULT_TEMPERATURE:g}), got {self.temperature}")
        if not 1 <= self.takes <= MAX_TAKES:
            raise DanceNetError(f"takes must be from 1 to {MAX_TAKES}, got {self.takes}")
        if self.fps is not None and not (np.isfinite(self.fps) and 1 <= self.fps <= 1000):
            raise DanceNetError(f"the frame rate must be from 1 to 1000 fps, got {self.fps}")
        for name, _default, o in options():
            allowed = [c[0] for c in o.choices]
            if o.kind is str and allowed and getattr(self, name) not in allowed:
                raise DanceNetError(f"unknown {name.replace('_', ' ')} '{getattr(self, name)}'; choose one of: "
                                    f"{', '.join(allowed)}")
        for o in self.sections:
            for key, allowed in (("energy", ENERGY_SCALES), ("returns", [c[0] for c in RETURN_CHOICES])):
                if getattr(o, key) is not None and getattr(o, key) not in allowed:
                    raise DanceNetError(f"unknown {key} '{getattr(o, key)}' for section {o.section}; choose one "
                                        f"of: {', '.join(allowed)}")
        if len({o.section for o in self.sections}) < len(self.sections):
            raise DanceNetError("a section is given settings twice: give each section once (--section)")
        if self.commercial:
            check_commercial(self)
        if self.redo_section is not None and self.continue_from is None:
            raise DanceNetError("dancing one section anew needs the dance it belongs to (continue_from)")
        if self.continue_from is not None and not 0 < self.at_s <= self.continue_from.duration:
            raise DanceNetError(f"the new dancing must start within the kept dance (0 to "
                                f"{self.continue_from.duration:.2f} s), got {self.at_s}")

    @property
    def sampling_temperature(self) -> float:
        """The temperature the engine samples at: the user's, scaled by the energy preset."""
        return min(self.temperature * ENERGY_SCALES[self.energy], MAX_TEMPERATURE)

    @property
    def move_scale(self) -> float:
        """How much larger than the model makes them the dance's moves are (the energy preset)."""
        return ENERGY_MOVES[self.energy]

    def part(self, duration_s: float) -> tuple[float, float]:
        """(start, end) seconds of the song to dance: the end clipped to the song's; a start too close to the
        song's end is an error that says how long the song is."""
        end = duration_s if self.end_s is None else min(self.end_s, duration_s)
        if end - self.start_s < MIN_PART_S:
            raise DanceNetError(f"start {self.start_s:g} s leaves less than {MIN_PART_S:g} s of the song to dance "
                                f"(the song lasts {duration_s:.1f} s)")
        return self.start_s, end


def check_commercial(request: DanceRequest) -> None:
    """A one-line error for a part the commercial mode leaves out (`licence.py` says why each is left out)."""
    if request.engine != "library":
        raise DanceNetError("commercial use: DanceNet was trained on Dance with Melody, which grants no licence; "
                            "dance with --engine library --library FOLDER (a library of clips you may use)")
    if request.weights is not None:
        raise DanceNetError("commercial use: --weights are trained weights, which the commercial mode does not load; "
                            "leave --weights out")
    if request.library is None:
        raise DanceNetError("commercial use: the shipped CMU library was built from AMASS conversions "
                            "(non-commercial); give --library FOLDER, clips of your own built with "
                            "`dancenet library build FOLDER`")


def check_part(start_s: float, end_s: float | None) -> None:
    """Reject a part of the song that cannot exist whatever the song (before the music is analysed)."""
    if not (np.isfinite(start_s) and start_s >= 0):
        raise DanceNetError(f"start must be 0 or more seconds into the song, got {start_s}")
    if end_s is not None and not (np.isfinite(end_s) and end_s >= start_s + MIN_PART_S):
        raise DanceNetError(f"end ({end_s} s) must be at least {MIN_PART_S:g} s after start ({start_s} s)")


def check_song_path(song: str | Path) -> Path:
    """`song` as a Path if it names a file; a one-line error saying what it is otherwise."""
    path = Path(song)
    if path.is_dir():
        raise DanceNetError(f"{song} is a folder, not an audio file; give the path of a song file")
    if not path.is_file():
        raise DanceNetError(f"song not found: {song} (check the path)")
    return path


def options() -> Iterator[tuple[str, Any, Option]]:
    """(field name, default, Option) for every setting users set, in the request's order."""
    for f in fields(DanceRequest):
        if "option" in f.metadata:
            yield f.name, (None if f.default is MISSING else f.default), f.metadata["option"]


def panel_options() -> list[tuple[str, Any, Option]]:
    """The settings the add-on's Dance panel offers (those with a label), in order."""
    return [(name, default, o) for name, default, o in options() if o.label is not None]


def add_options(parser: argparse.ArgumentParser, help_overrides: dict[str, str] | None = None) -> None:
    """The request's command-line options (each field with a flag), for `dancenet generate` and batch mode."""
    for name, default, o in options():
        if o.flag is None:
            continue
        text = (help_overrides or {}).get(name, o.help)
        if o.kind is bool:
            parser.add_argument(o.flag, dest=name, action="store_false" if default else "store_true",
                                help=f"do not {text}" if default else text)
            continue
        if default == ():  # a setting given once per item (each --section adds one)
            parser.add_argument(o.flag, dest=name, type=_argument_type(o.kind), action="append", default=None,
                                metavar=o.metavar, help=text)
            continue
        choices = [o.kind(c[0]) for c in o.choices] or None
        parser.add_argument(o.flag, dest=name, type=o.kind, default=default, choices=choices, metavar=o.metavar,
                            help=text)


def _argument_type(parse: Callable[[str], Any]) -> Callable[[str], Any]:
    """`parse` for argparse: its one-line DanceNetError becomes argparse's usage error."""
    def typed(text: str) -> Any:
        try:
            return parse(text)
        except DanceNetError as e:
            raise argparse.ArgumentTypeError(str(e)) from None
    return typed


def options_from(args: argparse.Namespace) -> dict[str, Any]:
    """The DanceRequest fields `add_options` parsed (weights and library as given, as str and Path)."""
    values = {name: getattr(args, name) for name, _default, o in options() if o.flag is not None}
    for name, default, _o in options():
        if default == () and name in values:  # the appended items, one tuple
            values[name] = tuple(item for given in values[name] or () for item in given)
    if values.get("weights") is not None:
        values["weights"] = str(values["weights"])
    return values

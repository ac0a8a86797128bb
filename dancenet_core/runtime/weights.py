"""What a Generate Dance loads: the three networks' weights as plain arrays (`.npz` files beside the
training checkpoints in `weights/`, read with `allow_pickle=False`, so a crafted file cannot run code),
with what each needs around its network (normaliser, skeleton, style names, windows). No torch.

Training writes these files from its checkpoints (`nets/export.py`; `dancenet weights export` redoes it).
"""

from __future__ import annotations

import json
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.special import softmax

from ..atomic import atomic_open
from ..environment import WEIGHTS_DIR
from ..errors import DanceNetError, first_line
from ..music.style import StyleClassifier, weights_inputs
from ..representation import FeatureLayout, Normalizer
from ..shaping.floor import floor_lift
from ..skeleton import LOWER_BODY, TOE_ENDS, Skeleton
from .config import DanceNetConfig
from .numpy_nets import NumpyDanceNet, NumpyFootNet, NumpyStyleNet, toe_heights

RUNTIME_FORMAT = "dancenet-runtime-1"
DEFAULT_RUNTIME = WEIGHTS_DIR / "dancenet.npz"
STYLE_RUNTIME = WEIGHTS_DIR / "style_classifier.npz"
FOOTFIX_RUNTIME = WEIGHTS_DIR / "footfix.npz"
META = "meta"  # the entry holding a file's JSON metadata, as a 0-d string array


def _plain(value: object) -> object:
    """numpy numbers and arrays, and paths, in metadata (e.g. training facts) as JSON data."""
    if isinstance(value, np.generic | np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON data")


def write_arrays(path: str | Path, arrays: dict[str, np.ndarray], meta: dict) -> None:
    """Arrays under their names and `meta` as JSON, in one uncompressed `.npz` (loads fast), written atomically."""
    text = json.dumps({"format": RUNTIME_FORMAT, **meta}, default=_plain)
    with atomic_open(path, "wb") as f:
        np.savez(f, **{META: np.array(text)}, **arrays)


def read_arrays(path: str | Path, what: str, hint: str) -> tuple[dict[str, np.ndarray], dict]:
    """The arrays and metadata of a file `write_arrays` wrote; a one-line DanceNetError for anything else."""
    path = Path(path)
    if not path.is_file():
        raise DanceNetError(f"{what} not found: {path}; {hint}")
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        meta = json.loads(str(arrays.pop(META)))
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as e:
        raise DanceNetError(f"cannot read the {what} {path}: {first_line(e)}; {hint}") from e
    if not isinstance(meta, dict) or meta.get("format") != RUNTIME_FORMAT:
        raise DanceNetError(f"{path} is not a {what} file ({RUNTIME_FORMAT}); {hint}")
    return arrays, meta


def _group(arrays: dict[str, np.ndarray], prefix: str) -> dict[str, np.ndarray]:
    """The entries named `prefix/...`, without the prefix."""
    return {k[len(prefix) + 1 :]: v for k, v in arrays.items() if k.startswith(prefix + "/")}


def _prefixed(prefix: str, arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {f"{prefix}/{k}": np.asarray(v) for k, v in arrays.items()}


def _normalizer_arrays(norm: Normalizer) -> dict[str, np.ndarray]:
    return _prefixed("normalizer", {"mean": norm.mean, "std": norm.std, "constant": norm.constant})


def _normalizer(arrays: dict[str, np.ndarray]) -> Normalizer:
    n = _group(arrays, "normalizer")
    return Normalizer(n["mean"], n["std"], n["constant"])


@dataclass
class RuntimeBundle:
    """A trained DanceNet as generation uses it (`nets/bundle.py`'s `DanceNetBundle` without torch)."""

    model: NumpyDanceNet
    normalizer: Normalizer
    skeleton: Skeleton
    start_frames: dict[str, np.ndarray]  # per style: [N, D] real first frames (unnormalised)
    info: dict = field(default_factory=dict)

    @property
    def styles(self) -> list[str]:
        return list(self.model.cfg.styles)

    def save(self, path: str | Path) -> None:
        arrays = {**_prefixed("state", self.model.state), **_normalizer_arrays(self.normalizer),
                  "skeleton_offsets": self.skeleton.offsets, **_prefixed("start_frames", self.start_frames)}
        write_arrays(path, arrays, {"kind": "dancenet", "config": self.model.cfg.to_dict(), "info": self.info})

    @classmethod
    def load(cls, path: str | Path = DEFAULT_RUNTIME) -> RuntimeBundle:
        arrays, meta = read_arrays(path, "DanceNet weights", "reinstall the package or pass --weights")
        try:
            model = NumpyDanceNet(DanceNetConfig(**meta["config"]), _group(arrays, "state"))
            return cls(model, _normalizer(arrays), Skeleton(arrays["skeleton_offsets"]),
                       _group(arrays, "start_frames"), meta.get("info", {}))
        except (KeyError, TypeError) as e:
            raise DanceNetError(f"{path} is not a DanceNet weights file ({first_line(e)})") from e


@dataclass(frozen=True)
class FootChannels:
    """Where the Foot Constraint Model's inputs and outputs sit in a frame's feature vector."""

    lower: np.ndarray  # root channels + leg joint rotations (what the toe kinematics read)
    toes: np.ndarray  # toe-end positions
    contacts: np.ndarray

    # The root's travel within `lower`: dx, dz, dyaw. The model leaves them alone so that cleaning the feet
    # never changes where the dancer goes: a model free to change them halved the ground covered.
    TRAVEL = (0, 2, 3)

    @classmethod
    def for_layout(cls, layout: FeatureLayout) -> FootChannels:
        root = list(range(layout.root.start, layout.root.stop))
        legs = [layout.rotations.start + 3 * (j - 1) + k for j in LOWER_BODY[1:] for k in range(3)]
        toes = [layout.end_effectors.start + 3 * e + k for e in TOE_ENDS for k in range(3)]
        contacts = list(range(layout.contacts.start, layout.contacts.stop))
        return cls(np.array(root + legs), np.array(toes), np.array(contacts))

    @property
    def inputs(self) -> np.ndarray:
        return np.concatenate([self.lower, self.toes, self.contacts])

    @property
    def steered(self) -> np.ndarray:
        """Positions within `lower` of the channels the model corrects (all but the root's travel)."""
        return np.delete(np.arange(len(self.lower)), self.TRAVEL)

    @property
    def corrected(self) -> np.ndarray:
        """The feature channels the model's output is added to."""
        return self.lower[self.steered]


class RuntimeFootFixer:
    """The shipped Foot Constraint Model with its normaliser and skeleton (`FootFixer` without torch)."""

    def __init__(self, net: NumpyFootNet, normalizer: Normalizer, layout: FeatureLayout, skeleton: Skeleton,
                 info: dict | None = None) -> None:
        self.net = net
        self.norm = normalizer
        self.layout = layout
        self.skeleton = skeleton
        self.ch = FootChannels.for_layout(layout)
        self.info = dict(info or {})

    def __call__(self, features: np.ndarray) -> np.ndarray:
        """Unnormalised features [T, D] -> the same with the lower body corrected and no toe below the floor."""
        x = self.norm.normalize(features)
        x[:, self.ch.corrected] += self.net(x[:, self.ch.inputs])
        out = self.norm.denormalize(x)
        out[:, 1] += self.floor_lift(x)
        return out

    def floor_lift(self, x: np.ndarray) -> np.ndarray:
        """Root lift [T] (metres) for normalised frames `x` [T, D] (see `floor_lift`)."""
        lower = x[:, self.ch.lower] * self.norm.std[self.ch.lower] + self.norm.mean[self.ch.lower]
        return floor_lift(toe_heights(lower, self.skeleton).min(axis=-1))

    def save(self, path: str | Path) -> None:
        arrays = {**_prefixed("state", self.net.state), **_normalizer_arrays(self.norm),
                  "skeleton_offsets": self.skeleton.offsets}
        write_arrays(path, arrays, {"kind": "footfix", "num_joints": self.layout.num_joints,
                                    "num_end_sites": self.layout.num_end_sites, "info": self.info})

    @classmethod
    def load(cls, path: str | Path = FOOTFIX_RUNTIME) -> RuntimeFootFixer:
        hint = "reinstall the package or use --no-footfix"
        arrays, meta = read_arrays(path, "Foot Constraint Model weights", hint)
        try:
            fixer = cls(NumpyFootNet(_group(arrays, "state")), _normalizer(arrays),
                        FeatureLayout(meta["num_joints"], meta["num_end_sites"]), Skeleton(arrays["skeleton_offsets"]),
                        meta.get("info"))
        except (KeyError, TypeError) as e:
            raise DanceNetError(f"{path} is not a Foot Constraint Model weights file ({first_line(e)}); {hint}") from e
        (w_in, _, _), (w_out, _, _) = fixer.net.layers[0], fixer.net.layers[-1]
        if (w_in.shape[0], w_out.shape[1]) != (3 * len(fixer.ch.inputs), len(fixer.ch.corrected)):
            # A model that also writes the root's travel (an older layout) would move the dancer: it cannot be used.
            raise DanceNetError(f"{path} is a Foot Constraint Model for other channels ({w_in.shape[0] // 3} in, "
                                f"{w_out.shape[1]} out; this version needs {len(fixer.ch.inputs)} in, "
                                f"{len(fixer.ch.corrected)} out); {hint}")
        return fixer


class RuntimeStyleModel(StyleClassifier):
    """The music style classifier on its numpy network (`nets/style_torch.py`'s `StyleModel` without torch)."""

    def __init__(self, net: NumpyStyleNet, styles: Sequence[str], config: dict, meta: dict | None = None) -> None:
        super().__init__(styles, config, meta)
        self.net = net

    @property
    def arch(self) -> str:
        return self.net.arch

    def logits(self, x: np.ndarray) -> np.ndarray:
        return self.net(x)

    def window_probabilities(self, features: np.ndarray, starts: np.ndarray, batch: int = 64) -> np.ndarray:
        """As `StyleClassifier.window_probabilities`, with the layers that overlapping windows share run once."""
        return softmax(self.net.windows(features, starts, min(self.window, len(features))), axis=1)

    def save(self, path: str | Path) -> None:
        write_arrays(path, _prefixed("state", self.net.state), {
            "kind": "style", "arch": self.arch, "styles": list(self.styles), "config": self.config,
            "meta": self.full_meta()})

    @classmethod
    def load(cls, path: str | Path = STYLE_RUNTIME) -> RuntimeStyleModel:
        hint = "reinstall the package or choose the style (--style)"
        arrays, meta = read_arrays(path, "style classifier weights", hint)
        try:
            state = _group(arrays, "state")
            return cls(NumpyStyleNet(meta["arch"], state), meta["styles"], weights_inputs(state, meta["config"]),
                       meta["meta"])
        except (KeyError, TypeError) as e:
            raise DanceNetError(f"{path} is not a style classifier weights file ({first_line(e)}); {hint}") from e

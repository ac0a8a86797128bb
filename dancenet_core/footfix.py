"""Foot Constraint Model (supplement, section 3): a small learned post-process against foot sliding.

Three temporal convs (kernel 3, dilations 1, 3, 9) read the lower body's rotations (root channels and
the legs), the toe-end positions and the foot contacts, and output an increment to the lower-body
rotations. Trained on real motion whose lower body was made to slide by Gaussian smoothing and noise;
the paper chose this over IK because predicted contacts are not accurate enough for IK (85-90%).
All channels are in the dance model's normalised feature space.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import torch
from scipy.ndimage import gaussian_filter1d
from torch import nn

from .errors import DanceNetError
from .representation import FeatureLayout, Normalizer
from .skeleton import LOWER_BODY, TOE_ENDS

WEIGHTS = Path(__file__).resolve().parent / "weights" / "footfix.pt"


@dataclass(frozen=True)
class FootChannels:
    """Where the model's inputs and outputs sit in a frame's feature vector."""

    lower: np.ndarray  # root channels + leg joint rotations (what gets corrected)
    toes: np.ndarray  # toe-end positions
    contacts: np.ndarray

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


class FootConstraintModel(nn.Module):
    """3 temporal convs, kernel 3, dilations 1, 3, 9 (non-causal: the whole dance is known)."""

    def __init__(self, n_in: int, n_out: int, hidden: int = 128) -> None:
        super().__init__()
        self.net = nn.Sequential(
            nn.Conv1d(n_in, hidden, 3, padding=1, dilation=1), nn.ReLU(),
            nn.Conv1d(hidden, hidden, 3, padding=3, dilation=3), nn.ReLU(),
            nn.Conv1d(hidden, n_out, 3, padding=9, dilation=9),
        )  # fmt: skip

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """x [B, T, n_in] -> increment [B, T, n_out]."""
        return self.net(x.transpose(1, 2)).transpose(1, 2)


class LstmBaseline(nn.Module):
    """The paper's baseline: fully connected + LSTM + fully connected."""

    def __init__(self, n_in: int, n_out: int, hidden: int = 128) -> None:
        super().__init__()
        self.inp = nn.Linear(n_in, hidden)
        self.lstm = nn.LSTM(hidden, hidden, batch_first=True)
        self.out = nn.Linear(hidden, n_out)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h, _ = self.lstm(torch.relu(self.inp(x)))
        return self.out(h)


def simulate_sliding(x: np.ndarray, ch: FootChannels, rng: np.random.Generator) -> np.ndarray:
    """Real frames [B, T, D] (normalised) -> the same with sliding feet: the lower body and toes smoothed
    and noisy (the supplement's recipe), plus a slow random drift on the root's steps and turns, which is
    what makes a planted foot skate."""
    y = x.copy()
    cols = np.concatenate([ch.lower, ch.toes])
    for b in range(len(y)):
        sigma = rng.uniform(1.0, 4.0)
        y[b][:, cols] = gaussian_filter1d(y[b][:, cols], sigma, axis=0, mode="nearest")
        drift = gaussian_filter1d(rng.normal(0, 1, (len(y[b]), 3)), rng.uniform(3.0, 10.0), axis=0)
        drift *= rng.uniform(0.0, 0.5) / (drift.std(0) + 1e-9)
        y[b][:, ch.lower[[0, 2, 3]]] += drift.astype(np.float32)  # root dx, dz, dyaw
    y[..., cols] += rng.normal(0, rng.uniform(0.02, 0.1), y[..., cols].shape).astype(np.float32)
    return y


def smoothness(y: torch.Tensor) -> torch.Tensor:
    return ((y[:, 2:] - 2 * y[:, 1:-1] + y[:, :-2]) ** 2).mean()


def train_model(
    model: nn.Module,
    train: list[np.ndarray],
    test: list[np.ndarray],
    ch: FootChannels,
    steps: int,
    seed: int = 0,
    window: int = 200,
    batch: int = 32,
) -> dict[str, float]:
    """Adam 5e-4, MSE + 0.1 x smoothness; returns train time and the test MSE (fixed corrupted windows)."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    opt = torch.optim.Adam(model.parameters(), lr=5e-4)

    def windows(seqs: list[np.ndarray], n: int, r: np.random.Generator) -> np.ndarray:
        picks = r.integers(len(seqs), size=n)
        out = []
        for i in picks:
            s = r.integers(0, len(seqs[i]) - window + 1)
            out.append(seqs[i][s : s + window])
        return np.stack(out)

    test_rng = np.random.default_rng(1234)
    test_clean = windows(test, 128, test_rng)
    test_in = simulate_sliding(test_clean, ch, test_rng)
    t0 = time.time()
    model.train()
    for _ in range(steps):
        clean = windows(train, batch, rng)
        noisy = simulate_sliding(clean, ch, rng)
        xin = torch.tensor(noisy[..., ch.inputs])
        target = torch.tensor(clean[..., ch.lower])
        pred = torch.tensor(noisy[..., ch.lower]) + model(xin)
        loss = ((pred - target) ** 2).mean() + 0.1 * smoothness(pred)
        opt.zero_grad()
        loss.backward()
        opt.step()
    model.eval()
    with torch.no_grad():
        pred = torch.tensor(test_in[..., ch.lower]) + model(torch.tensor(test_in[..., ch.inputs]))
        mse = float(((pred - torch.tensor(test_clean[..., ch.lower])) ** 2).mean())
    untouched = float(((test_in[..., ch.lower] - test_clean[..., ch.lower]) ** 2).mean())
    return {"train_seconds": time.time() - t0, "test_mse": mse, "test_mse_without_model": untouched}


class FootFixer:
    """The shipped Foot Constraint Model with its normaliser."""

    def __init__(self, model: FootConstraintModel, normalizer: Normalizer, layout: FeatureLayout) -> None:
        self.model = model.eval()
        self.norm = normalizer
        self.layout = layout
        self.ch = FootChannels.for_layout(layout)

    @torch.no_grad()
    def __call__(self, features: np.ndarray) -> np.ndarray:
        """Unnormalised features [T, D] -> the same with the lower body corrected."""
        x = self.norm.normalize(features)
        inc = self.model(torch.tensor(x[None, :, self.ch.inputs]))[0].numpy()
        x[:, self.ch.lower] += inc
        return self.norm.denormalize(x)

    def save(self, path: Path, info: dict) -> None:
        torch.save({"state_dict": self.model.state_dict(), "mean": self.norm.mean, "std": self.norm.std,
                    "constant": self.norm.constant, "num_joints": self.layout.num_joints,
                    "num_end_sites": self.layout.num_end_sites, "info": info}, path)

    @classmethod
    def load(cls, path: Path = WEIGHTS) -> FootFixer:
        if not path.is_file():
            raise DanceNetError(f"Foot Constraint Model weights not found at {path}; reinstall the package")
        d = torch.load(path, map_location="cpu", weights_only=False)
        layout = FeatureLayout(d["num_joints"], d["num_end_sites"])
        ch = FootChannels.for_layout(layout)
        model = FootConstraintModel(len(ch.inputs), len(ch.lower))
        model.load_state_dict(d["state_dict"])
        return cls(model, Normalizer(d["mean"], d["std"], d["constant"]), layout)


@lru_cache(maxsize=1)
def shipped_fixer() -> FootFixer:
    return FootFixer.load()


def main(argv: list[str] | None = None) -> None:
    """Train the Foot Constraint Model and the LSTM baseline on the training split; write weights + card."""
    from .data.build import build_dataset, default_data_dir, load_split

    p = argparse.ArgumentParser(description=main.__doc__)
    p.add_argument("--data", type=Path, default=None)
    p.add_argument("--steps", type=int, default=1500)
    p.add_argument("--out", type=Path, default=WEIGHTS)
    args = p.parse_args(argv)
    pairs = build_dataset(args.data or default_data_dir())
    split = load_split()
    layout = FeatureLayout(55, 5)
    train_pairs = [q for q in pairs if q.seq in split["train"]]
    norm = Normalizer.fit([q.motion for q in train_pairs] + [q.mirrored for q in train_pairs],
                          binary=layout.contacts)
    train = [norm.normalize(q.motion) for q in train_pairs] + [norm.normalize(q.mirrored) for q in train_pairs]
    test = [norm.normalize(q.motion) for q in pairs if q.seq in split["test"]]
    ch = FootChannels.for_layout(layout)
    ours = FootConstraintModel(len(ch.inputs), len(ch.lower))
    res_ours = train_model(ours, train, test, ch, args.steps)
    base = LstmBaseline(len(ch.inputs), len(ch.lower))
    res_base = train_model(base, train, test, ch, args.steps)
    info = {"steps": args.steps, "ours": res_ours, "baseline_lstm": res_base,
            "train_sequences": sorted(q.seq for q in train_pairs)}
    FootFixer(ours, norm, layout).save(args.out, info)
    print(json.dumps(info, indent=2))


if __name__ == "__main__":
    main()

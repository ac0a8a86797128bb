"""Foot Constraint Model (supplement, section 3): a small learned post-process against foot sliding.

Three temporal convs (kernel 3, dilations 1, 3, 9) read the lower body's rotations (root channels and
the legs), the toe-end positions and the foot contacts, and output an increment to the lower-body
rotations; the paper chose this over IK because predicted contacts are not accurate enough for IK (85-90%).
All channels are in the dance model's normalised feature space.

Training, as the paper: real motion made to slide (Gaussian smoothing and noise), MSE + 0.1 x smoothness,
Adam 5e-4. That alone removed only 3% of the sliding in DanceNet's dances (its feet shuffle along the floor,
unlike the simulation), so the model also trains on DanceNet's own dances to the training songs (two takes
per song), with physical terms through differentiable forward kinematics (`contact_losses`):
- slide: the toe ends' horizontal travel on frames where DanceNet's toe is within 5 cm of the floor (the
  sliding metric's test). Contact is decided on DanceNet's heights, not the corrected ones: an earlier
  version used the corrected heights and learnt to lift the feet out of the test (lowest toe 2-8 cm up,
  share of toe frames near the floor 0.88 -> 0.37).
- height: toe heights stay DanceNet's, against floating.
- root and still: the pelvis' velocity stays DanceNet's, and no frame's lower body may slow below
  min(DanceNet's speed, 10 cm/s). Without them the model stopped the body to stop the feet (freezes of up
  to 7 s where DanceNet had none over 0.16 s).
- jitter: lower-body joint accelerations may not rise above DanceNet's (the jitter metric is a mean
  acceleration; a smoothness term on rotations alone let it rise 11%).
Stronger smoothing in the simulation flattens steps as DanceNet does. After the model, the root is lifted
(smoothly) wherever a toe would still be below the floor, so feet never go through it (DanceNet's own toes
dip 2-7 cm below it).
On the test songs this takes sliding from 0.63 to 0.23 of contact frames with jitter down 10%, toes on the
floor and no freezes. The price is the paper's own test: on simulated sliding both this model and the LSTM
baseline end above the uncorrected input's MSE (the physical terms pull away from clean real motion), ours
still below the baseline's. A constant glide on stiff legs cannot be pinned while the pelvis keeps its
speed and the toes their height, so there the model does not reduce sliding.
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
from scipy.ndimage import gaussian_filter1d, maximum_filter1d
from torch import nn

from .checkpoint import load_weights, save_weights
from .errors import DanceNetError, first_line
from .kinematics import rotvec_to_matrix_torch
from .metrics import CONTACT_TOE_M
from .representation import FeatureLayout, Normalizer
from .skeleton import LOWER_BODY, TOE_ENDS, Skeleton

WEIGHTS = Path(__file__).resolve().parent / "weights" / "footfix.pt"
# Lower-body joints moving less than this on average (4 mm a frame = 10 cm/s at 25 fps, twice the freeze
# metric's 5 cm/s) are at risk of reading as a freeze; the model must not slow them below it.
MOVING_M_PER_FRAME = 0.004


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


class ToeKinematics:
    """World toe-end positions from normalised lower-body channels, differentiable.

    The contact loss needs where the toes really go; decoding integrates the root's steps and turns over
    the window, so a window starts at the origin facing +Z (sliding is about differences, not places).
    """

    def __init__(self, skeleton: Skeleton, norm: Normalizer, ch: FootChannels) -> None:
        self.mean = torch.tensor(norm.mean[ch.lower])
        self.std = torch.tensor(norm.std[ch.lower])
        self.offsets = torch.tensor(skeleton.offsets, dtype=torch.float32)
        self.parents = skeleton.parents
        self.feet = [int(j) for j in skeleton.end_site_parents()[list(TOE_ENDS)]]
        self.toe_offsets = torch.tensor(skeleton.end_site_offsets()[list(TOE_ENDS)], dtype=torch.float32)

    def __call__(self, lower: torch.Tensor) -> torch.Tensor:
        """Normalised lower-body channels [B, T, L] -> toe ends [B, T, 2, 3] (metres, floor at y = 0)."""
        return self.positions(lower)[1]

    def positions(self, lower: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Normalised lower-body channels [B, T, L] -> (lower-body joints [B, T, J, 3], toe ends [B, T, 2, 3])."""
        x = lower * self.std + self.mean
        dyaw = torch.cat([torch.zeros_like(x[:, :1, 3]), x[:, 1:, 3]], 1)
        yaw = torch.cumsum(dyaw, 1)
        prev = yaw - dyaw
        c, s = torch.cos(prev), torch.sin(prev)
        step_x = (c * x[..., 0] + s * x[..., 2])[:, 1:]
        step_z = (-s * x[..., 0] + c * x[..., 2])[:, 1:]
        zero = torch.zeros_like(x[:, :1, 0])
        root = torch.stack([torch.cumsum(torch.cat([zero, step_x], 1), 1), x[..., 1],
                            torch.cumsum(torch.cat([zero, step_z], 1), 1)], -1)
        cy, sy, z, o = torch.cos(yaw), torch.sin(yaw), torch.zeros_like(yaw), torch.ones_like(yaw)
        ry = torch.stack([cy, z, sy, z, o, z, -sy, z, cy], -1).reshape(*yaw.shape, 3, 3)
        swing = torch.stack([x[..., 4], z, x[..., 5]], -1)
        rot = {0: ry @ rotvec_to_matrix_torch(swing)}
        pos = {0: root + self.offsets[0]}
        for i, j in enumerate(LOWER_BODY[1:]):
            p = self.parents[j]
            pos[j] = pos[p] + (rot[p] @ self.offsets[j].unsqueeze(-1)).squeeze(-1)
            rot[j] = rot[p] @ rotvec_to_matrix_torch(x[..., 6 + 3 * i : 9 + 3 * i])
        toes = torch.stack([pos[f] + (rot[f] @ o.unsqueeze(-1)).squeeze(-1)
                            for f, o in zip(self.feet, self.toe_offsets, strict=True)], -2)
        return torch.stack([pos[j] for j in LOWER_BODY], -2), toes


def simulate_sliding(x: np.ndarray, ch: FootChannels, rng: np.random.Generator) -> np.ndarray:
    """Real frames [B, T, D] (normalised) -> the same with sliding feet, like DanceNet's: the supplement's
    Gaussian smoothing and noise of the lower body and toes (strong smoothing flattens the steps, so the
    feet shuffle near the floor as generated ones do), plus a slow random drift of the root's steps and
    turns, which is what makes a planted foot skate."""
    y = x.copy()
    cols = np.concatenate([ch.lower, ch.toes])
    for b in range(len(y)):
        sigma = rng.uniform(1.0, 8.0)
        y[b][:, cols] = gaussian_filter1d(y[b][:, cols], sigma, axis=0, mode="nearest")
        drift = gaussian_filter1d(rng.normal(0, 1, (len(y[b]), 3)), rng.uniform(3.0, 10.0), axis=0)
        drift *= rng.uniform(0.0, 0.5) / (drift.std(0) + 1e-9)
        y[b][:, ch.lower[[0, 2, 3]]] += drift.astype(np.float32)  # root dx, dz, dyaw
    y[..., cols] += rng.normal(0, rng.uniform(0.02, 0.1), y[..., cols].shape).astype(np.float32)
    return y


def smoothness(y: torch.Tensor) -> torch.Tensor:
    return ((y[:, 2:] - 2 * y[:, 1:-1] + y[:, :-2]) ** 2).mean()


def contact_losses(kin: ToeKinematics, before: torch.Tensor, after: torch.Tensor) -> dict[str, torch.Tensor]:
    """Physical terms (all in cm per frame) of correcting DanceNet's lower body `before` into `after`
    (normalised [B, T, L]).

    slide: horizontal toe travel on frames where DanceNet's own toe is within 5 cm of the window's floor (the
    sliding metric's test, on the uncorrected heights, so lifting a foot off the floor is never a way out);
    height: toe heights leaving DanceNet's (against floating feet); root: the pelvis' velocity leaving
    DanceNet's (against freezing: stopping the body would also stop the feet); jitter: lower-body joint
    accelerations rising above DanceNet's (the jitter metric is a mean acceleration)."""
    with torch.no_grad():
        joints0, toes0 = kin.positions(before)
        h0 = toes0[..., 1]
        floor = torch.quantile(h0.min(-1).values, 0.02, dim=1)[:, None, None]
        planted = torch.sigmoid((floor + CONTACT_TOE_M - h0[:, 1:]) / 0.01)
    joints1, toes1 = kin.positions(after)
    step = ((toes1[:, 1:, :, [0, 2]] - toes1[:, :-1, :, [0, 2]]) ** 2).sum(-1).add(1e-8).sqrt()
    root_v0, root_v1 = joints0[:, 1:, 0] - joints0[:, :-1, 0], joints1[:, 1:, 0] - joints1[:, :-1, 0]
    pts0, pts1 = torch.cat([joints0, toes0], -2), torch.cat([joints1, toes1], -2)
    acc0 = (pts0[:, 2:] - 2 * pts0[:, 1:-1] + pts0[:, :-2]).norm(dim=-1)
    acc1 = (pts1[:, 2:] - 2 * pts1[:, 1:-1] + pts1[:, :-2]).add(1e-8).norm(dim=-1)
    speed0 = (joints0[:, 1:] - joints0[:, :-1]).norm(dim=-1).mean(-1)
    speed1 = (joints1[:, 1:] - joints1[:, :-1]).add(1e-8).norm(dim=-1).mean(-1)
    return {
        "slide": 100 * (planted * step).sum() / planted.sum().clamp(min=1.0),
        "height": 100 * (toes1[..., 1] - h0).abs().mean(),
        "root": 100 * (root_v1 - root_v0).norm(dim=-1).mean(),
        "jitter": 100 * torch.relu(acc1 - acc0).mean(),
        "still": 100 * torch.relu(speed0.clamp(max=MOVING_M_PER_FRAME) - speed1).mean(),
    }


@dataclass
class ContactTraining:
    """DanceNet's own dances to pin feet on: no ground truth, so the loss is physical (`contact_losses`,
    through `kin`, weighted here) plus staying close to DanceNet's motion and smooth."""

    dances: list[np.ndarray]  # normalised generated features [T, D]
    kin: ToeKinematics
    slide_weight: float = 2.5
    stay_weight: float = 1.0
    height_weight: float = 1.0
    root_weight: float = 3.0
    jitter_weight: float = 10.0
    still_weight: float = 10.0

    def loss(self, before: torch.Tensor, inc: torch.Tensor) -> torch.Tensor:
        after = before + inc
        t = contact_losses(self.kin, before, after)
        return (self.slide_weight * t["slide"] + self.height_weight * t["height"] + self.root_weight * t["root"]
                + self.jitter_weight * t["jitter"] + self.still_weight * t["still"]
                + self.stay_weight * (inc**2).mean() + 0.1 * smoothness(after))


def _windows(seqs: list[np.ndarray], n: int, window: int, r: np.random.Generator) -> np.ndarray:
    out = []
    for i in r.integers(len(seqs), size=n):
        s = r.integers(0, len(seqs[i]) - window + 1)
        out.append(seqs[i][s : s + window])
    return np.stack(out)


def train_model(
    model: nn.Module,
    train: list[np.ndarray],
    test: list[np.ndarray],
    ch: FootChannels,
    steps: int,
    seed: int = 0,
    window: int = 200,
    batch: int = 32,
    contact: ContactTraining | None = None,
) -> dict[str, float]:
    """Adam 5e-4, MSE + 0.1 x smoothness on simulated sliding (the paper's), plus, with `contact`, the
    contact loss on DanceNet's dances; returns train time and the test MSE (fixed corrupted windows)."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    opt = torch.optim.Adam(model.parameters(), lr=5e-4)
    test_rng = np.random.default_rng(1234)
    test_clean = _windows(test, 128, window, test_rng)
    test_in = simulate_sliding(test_clean, ch, test_rng)
    t0 = time.time()
    model.train()
    for _ in range(steps):
        clean = _windows(train, batch, window, rng)
        noisy = simulate_sliding(clean, ch, rng)
        pred = torch.tensor(noisy[..., ch.lower]) + model(torch.tensor(noisy[..., ch.inputs]))
        loss = ((pred - torch.tensor(clean[..., ch.lower])) ** 2).mean() + 0.1 * smoothness(pred)
        if contact is not None:
            gen = torch.tensor(_windows(contact.dances, batch, window, rng))
            loss = loss + contact.loss(gen[..., ch.lower], model(gen[..., ch.inputs]))
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
    """The shipped Foot Constraint Model with its normaliser and the skeleton it was trained on."""

    def __init__(self, model: FootConstraintModel, normalizer: Normalizer, layout: FeatureLayout,
                 skeleton: Skeleton) -> None:
        self.model = model.eval()
        self.norm = normalizer
        self.layout = layout
        self.skeleton = skeleton
        self.ch = FootChannels.for_layout(layout)
        self.kin = ToeKinematics(skeleton, normalizer, self.ch)

    @torch.no_grad()
    def __call__(self, features: np.ndarray) -> np.ndarray:
        """Unnormalised features [T, D] -> the same with the lower body corrected and no toe below the floor."""
        x = self.norm.normalize(features)
        x[:, self.ch.lower] += self.model(torch.tensor(x[None, :, self.ch.inputs]))[0].numpy()
        out = self.norm.denormalize(x)
        out[:, 1] += self.floor_lift(x)
        return out

    def floor_lift(self, x: np.ndarray) -> np.ndarray:
        """Root lift [T] (metres) that keeps both toe ends at or above the floor (y = 0): the dip, widened
        and smoothed so the lift eases in and out rather than jerking, and never less than the dip."""
        low = self.kin(torch.tensor(x[None, :, self.ch.lower]))[0, :, :, 1].min(-1).values.numpy()
        need = np.maximum(0.0, -low)
        return np.maximum(need, gaussian_filter1d(maximum_filter1d(need, 9), 2.0, mode="nearest"))

    def save(self, path: Path, info: dict) -> None:
        save_weights({"state_dict": self.model.state_dict(), "mean": self.norm.mean, "std": self.norm.std,
                      "constant": self.norm.constant, "num_joints": self.layout.num_joints,
                      "num_end_sites": self.layout.num_end_sites, "skeleton_offsets": self.skeleton.offsets,
                      "info": info}, path)

    @classmethod
    def load(cls, path: Path = WEIGHTS) -> FootFixer:
        d = load_weights(path, "Foot Constraint Model weights", "reinstall the package or use --no-footfix")
        try:
            layout = FeatureLayout(d["num_joints"], d["num_end_sites"])
            ch = FootChannels.for_layout(layout)
            model = FootConstraintModel(len(ch.inputs), len(ch.lower))
            model.load_state_dict(d["state_dict"])
            norm = Normalizer(np.asarray(d["mean"]), np.asarray(d["std"]), np.asarray(d["constant"]))
            return cls(model, norm, layout, Skeleton(np.asarray(d["skeleton_offsets"])))
        except (RuntimeError, KeyError, TypeError, ValueError, AttributeError) as e:
            raise DanceNetError(f"{path} is not a Foot Constraint Model weights file "
                                f"({first_line(e)}); reinstall the package or use --no-footfix") from e


@lru_cache(maxsize=1)
def shipped_fixer() -> FootFixer:
    return FootFixer.load()


def dancenet_dances(bundle, pairs: list, seeds: int, temperature: float) -> list[np.ndarray]:  # noqa: ANN001
    """DanceNet's dances (unnormalised features) to each pair's music, from its first frame, `seeds` each:
    the motion the Foot Constraint Model will have to clean."""
    from .generate import sample_dance
    from .model.sampler import Sampling, music_conditioning

    out = []
    for q in pairs:
        cond = music_conditioning(bundle.model, q.music, bundle.styles.index(q.style))
        first = bundle.normalizer.normalize(np.repeat(q.motion[:1], seeds, axis=0))
        out += sample_dance(bundle, cond, first, Sampling(temperature, np.random.default_rng(len(out))))
    return out


def main(argv: list[str] | None = None) -> None:
    """Train the Foot Constraint Model and the LSTM baseline on the training split; write weights + info."""
    from .data.build import build_dataset, default_data_dir, load_split
    from .generate import DEFAULT_TEMPERATURE
    from .model.bundle import DEFAULT_BUNDLE, DanceNetBundle

    p = argparse.ArgumentParser(description=main.__doc__)
    p.add_argument("--data", type=Path, default=None)
    p.add_argument("--steps", type=int, default=400)
    p.add_argument("--seeds", type=int, default=2, help="DanceNet dances per training song for the contact loss")
    p.add_argument("--slide-weight", type=float, default=ContactTraining.slide_weight)
    p.add_argument("--root-weight", type=float, default=ContactTraining.root_weight)
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
    bundle = DanceNetBundle.load(DEFAULT_BUNDLE)
    t0 = time.time()
    known = [q for q in train_pairs if q.style in bundle.styles]
    dances = [norm.normalize(f) for f in dancenet_dances(bundle, known, args.seeds, DEFAULT_TEMPERATURE)]
    contact = ContactTraining(dances, ToeKinematics(bundle.skeleton, norm, ch), slide_weight=args.slide_weight,
                              root_weight=args.root_weight)
    generation_seconds = time.time() - t0
    ours = FootConstraintModel(len(ch.inputs), len(ch.lower))
    res_ours = train_model(ours, train, test, ch, args.steps, contact=contact)
    base = LstmBaseline(len(ch.inputs), len(ch.lower))
    res_base = train_model(base, train, test, ch, args.steps, contact=contact)
    info = {"steps": args.steps, "ours": res_ours, "baseline_lstm": res_base,
            "dancenet_dances": len(dances), "dancenet_generation_seconds": generation_seconds,
            "contact_weights": {k: v for k, v in vars(contact).items() if k.endswith("_weight")},
            "train_sequences": sorted(q.seq for q in train_pairs)}
    FootFixer(ours, norm, layout, bundle.skeleton).save(args.out, info)
    print(json.dumps(info, indent=2))


if __name__ == "__main__":
    main()

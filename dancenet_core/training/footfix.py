"""Training of the Foot Constraint Model (`nets/footfix.py`), `dancenet train footfix`.

As the paper: real motion made to slide (Gaussian smoothing and noise), MSE + 0.1 x smoothness,
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

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from scipy.ndimage import gaussian_filter1d
from torch import nn

from ..constants import DEFAULT_TEMPERATURE
from ..data.build import build_dataset
from ..data.split import load_split
from ..engines.dancenet import sample_dance
from ..environment import default_data_dir
from ..errors import DanceNetError
from ..evaluation.metrics import CONTACT_TOE_M
from ..nets.bundle import DanceNetBundle
from ..nets.export import fixer_to_runtime
from ..nets.footfix import FootChannels, FootConstraintModel, FootFixer, ToeKinematics
from ..representation import FeatureLayout, Normalizer
from ..runtime.sampler import Sampling, music_conditioning
from .configs import FootfixSettings

# Lower-body joints moving less than this on average (4 mm a frame = 10 cm/s at 25 fps, twice the freeze
# metric's 5 cm/s) are at risk of reading as a freeze; the model must not slow them below it.
MOVING_M_PER_FRAME = 0.004


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

def lower_increment(model: nn.Module, x: torch.Tensor, ch: FootChannels) -> torch.Tensor:
    """The model's correction of windows x [B, T, D] in the lower-body channels [B, T, L], zero on the root's
    travel (which the model does not write)."""
    inc = model(x[..., ch.inputs])
    full = inc.new_zeros(*inc.shape[:-1], len(ch.lower))
    full[..., ch.steered] = inc
    return full

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
    slide_weight: float = FootfixSettings.slide_weight
    stay_weight: float = 1.0
    height_weight: float = 1.0
    root_weight: float = FootfixSettings.root_weight
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

def train_foot_model(
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
    for step in range(steps):
        clean = _windows(train, batch, window, rng)
        noisy = torch.tensor(simulate_sliding(clean, ch, rng))
        pred = noisy[..., ch.lower] + lower_increment(model, noisy, ch)
        loss = ((pred - torch.tensor(clean[..., ch.lower])) ** 2).mean() + 0.1 * smoothness(pred)
        if contact is not None:
            gen = torch.tensor(_windows(contact.dances, batch, window, rng))
            loss = loss + contact.loss(gen[..., ch.lower], lower_increment(model, gen, ch))
        if not torch.isfinite(loss):  # a foot model of NaN weights once shipped silently would ruin every dance
            raise DanceNetError(f"the foot model's training diverged at step {step + 1} (its loss is not finite); "
                                "nothing was written: lower --slide-weight or check the DanceNet weights it cleans")
        opt.zero_grad()
        loss.backward()
        opt.step()
    model.eval()
    with torch.no_grad():
        pred = torch.tensor(test_in[..., ch.lower]) + lower_increment(model, torch.tensor(test_in), ch)
        mse = float(((pred - torch.tensor(test_clean[..., ch.lower])) ** 2).mean())
    untouched = float(((test_in[..., ch.lower] - test_clean[..., ch.lower]) ** 2).mean())
    return {"train_seconds": time.time() - t0, "test_mse": mse, "test_mse_without_model": untouched}

def dancenet_dances(bundle: DanceNetBundle, pairs: list, seeds: int, temperature: float) -> list[np.ndarray]:
    """DanceNet's dances (unnormalised features) to each pair's music, from its first frame, `seeds` each:
    the motion the Foot Constraint Model will have to clean."""
    out = []
    for q in pairs:
        cond = music_conditioning(bundle.model, q.music, bundle.styles.index(q.style))
        first = bundle.normalizer.normalize(np.repeat(q.motion[:1], seeds, axis=0))
        out += sample_dance(bundle, cond, first, Sampling(temperature, np.random.default_rng(len(out))))
    return out

def train_footfix(args: FootfixSettings) -> dict:
    """Train the Foot Constraint Model and the LSTM baseline on the training split; write weights + info."""
    args.out.parent.mkdir(parents=True, exist_ok=True)  # now, not after the training (a lost run otherwise)
    pairs = build_dataset(args.data or default_data_dir())
    split = load_split()
    layout = FeatureLayout(55, 5)
    train_pairs = [q for q in pairs if q.seq in split["train"]]
    norm = Normalizer.fit([q.motion for q in train_pairs] + [q.mirrored for q in train_pairs],
                          binary=layout.contacts)
    train = [norm.normalize(q.motion) for q in train_pairs] + [norm.normalize(q.mirrored) for q in train_pairs]
    test = [norm.normalize(q.motion) for q in pairs if q.seq in split["test"]]
    ch = FootChannels.for_layout(layout)
    bundle = DanceNetBundle.load(args.dancenet)
    t0 = time.time()
    known = [q for q in train_pairs if q.style in bundle.styles]
    dances = [norm.normalize(f) for f in dancenet_dances(bundle, known, args.seeds, DEFAULT_TEMPERATURE)]
    contact = ContactTraining(dances, ToeKinematics(bundle.skeleton, norm, ch), slide_weight=args.slide_weight,
                              root_weight=args.root_weight)
    generation_seconds = time.time() - t0
    ours = FootConstraintModel(len(ch.inputs), len(ch.corrected))
    res_ours = train_foot_model(ours, train, test, ch, args.steps, contact=contact)
    base = LstmBaseline(len(ch.inputs), len(ch.corrected))
    res_base = train_foot_model(base, train, test, ch, args.steps, contact=contact)
    info = {"steps": args.steps, "ours": res_ours, "baseline_lstm": res_base,
            "dancenet_dances": len(dances), "dancenet_generation_seconds": generation_seconds,
            "contact_weights": {k: v for k, v in vars(contact).items() if k.endswith("_weight")},
            "train_sequences": sorted(q.seq for q in train_pairs)}
    fixer = FootFixer(ours, norm, layout, bundle.skeleton)
    fixer.save(args.out, info)
    fixer_to_runtime(fixer).save(Path(args.out).with_suffix(".npz"))  # what generation runs, without torch
    return info

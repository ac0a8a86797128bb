"""Train DanceNet (or, with --variant, an ablation or baseline of the paper's comparison) on the paired
dataset (supplement's settings, sized for a 2-core CPU).

Runs in the background with checkpoints (resume with --resume), a fixed seed, and a JSON-lines log of
train and test loss. Under `torchrun --nproc_per_node N` it trains data-parallel (gloo on CPU, nccl on
GPUs); only rank 0 writes.

    dancenet train dancenet --out runs/dancenet --minutes 100
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from torch.nn import functional as F

from ..checkpoint import load_weights, save_weights
from ..data.build import PairedSequence, build_dataset, mean_skeleton, with_mel_music
from ..data.pack import load_pack
from ..data.split import load_split
from ..data.windows import Batch, WindowSampler
from ..environment import default_data_dir
from ..nets.bundle import DanceNetBundle
from ..nets.dancenet import DanceNet
from ..nets.export import bundle_to_runtime
from ..nets.variants import build_model, music_features
from ..representation import FeatureLayout, Normalizer
from ..runtime.sampler import DRAW_LIMIT
from .configs import TrainSettings
from .prior import PRIOR_STYLE, prior_sequences, silent
from .tensor_windows import TensorWindows

MIN_STYLE_SEQUENCES = 2  # a style danced in fewer training sequences cannot be learned or held out


def shipped_styles(pairs: list, train_ids: set[str]) -> tuple[list[str], dict[str, str]]:
    """Styles with enough training sequences, and the reason each other style is left out."""
    counts: dict[str, int] = {}
    for p in pairs:
        counts[p.style] = counts.get(p.style, 0) + (p.seq in train_ids)
    keep = sorted(s for s, c in counts.items() if c >= MIN_STYLE_SEQUENCES)
    left_out = {s: f"only {c} training sequence(s)" for s, c in counts.items() if s not in keep}
    return keep, left_out


def warm_start(model: torch.nn.Module, source: torch.nn.Module) -> None:
    """Start `model` from a trained DanceNet of the same sizes but maybe fewer mixture components or styles.

    Every component starts as the source's first one (means nudged apart so they can specialise, logits
    equal); a style the source lacks starts at the mean of its style embeddings. Why: the CPU budget buys
    a few thousand steps, and starting from a trained network spends them on what is new.
    """
    src, dst = source.state_dict(), model.state_dict()
    k_src, k, d = source.cfg.mixtures, model.cfg.mixtures, model.cfg.continuous_dim
    for name, value in src.items():
        if name in dst and dst[name].shape == value.shape:
            dst[name] = value.clone()
    emb = "style_embedding.weight"
    rows = {s: src[emb][i] for i, s in enumerate(source.cfg.styles)}
    mean = src[emb].mean(0)
    dst[emb] = torch.stack([rows.get(s, mean) for s in model.cfg.styles])
    if k == k_src and model.cfg.residual_output == source.cfg.residual_output:
        model.load_state_dict(dst)  # same head: nothing to re-lay out
        return
    gen = torch.Generator().manual_seed(0)
    for name in ("decoder.3.weight", "decoder.3.bias"):
        w = src[name]
        mu = w[k_src : k_src + d]
        if model.cfg.residual_output and not source.cfg.residual_output:
            mu = torch.zeros_like(mu)  # a change of zero: the warm-started model first copies the last frame
        ls = w[k_src + k_src * d : k_src + 2 * k_src * d][:d]
        contacts = w[k_src + 2 * k_src * d :]
        logits = torch.zeros((k,) + w.shape[1:])
        spread = mu.std() if mu.abs().max() > 0 else w.std()
        mus = [mu + (0.0 if i == 0 else 0.05 * torch.randn(mu.shape, generator=gen) * spread) for i in range(k)]
        dst[name] = torch.cat([logits, *mus, *([ls] * k), contacts])
    model.load_state_dict(dst)


def own_mask(shape: tuple[int, int], share: float, stretch: int, device: torch.device) -> torch.Tensor:
    """Which frames [B, T] the model's own draws replace: a random `share` of single frames, or (stretch > 0)
    stretches of `stretch` own frames at a random phase per window, between real stretches, `share` of all."""
    if stretch <= 0:
        return torch.rand(shape, device=device) < share
    period = max(stretch + 1, round(stretch / max(share, 1e-6)))
    phase = torch.randint(0, period, (shape[0], 1), device=device)
    return (torch.arange(shape[1], device=device) + phase) % period < stretch


@torch.no_grad()
def with_own_predictions(model: torch.nn.Module, frames: torch.Tensor, music: torch.Tensor, style: torch.Tensor,
                         share: float, passes: int = 1, stretch: int = 0, temperature: float = 0.5) -> torch.Tensor:
    """`frames` [B, T, D] with frames 1.. chosen by `own_mask` replaced by the model's own draws (component by
    its weight, then its mean and `temperature` x its spread; contacts by their logits).

    Why: teacher forcing only ever shows the network real previous frames, so its first own mistakes at
    generation are inputs it never saw, and a dance drifts or freezes (exposure bias). Trained on its own
    draws against the real next frame, it learns to steer back. Each of `passes` feeds the previous pass's
    draws (acLSTM's auto-conditioning, for all windows at once): the own frames see errors accumulated over
    up to `passes` own steps, and each pass is one step of the fixed-point iteration whose limit is a true
    free run inside the own stretches (exact after `passes` >= `stretch` for a window's first stretch).
    """
    was_training = model.training
    model.eval()
    mask = own_mask(frames.shape[:2], share, stretch, frames.device)[:, 1:, None]
    mixed = frames
    for _ in range(passes):
        logits, mu, log_sigma, contacts = model.split(model(mixed, music, style))
        comp = torch.distributions.Categorical(logits=logits).sample()[..., None, None]
        d = mu.shape[-1]
        pick = comp.expand(*comp.shape[:-2], 1, d)
        mean = mu.gather(-2, pick)[..., 0, :]
        sigma = log_sigma.gather(-2, pick)[..., 0, :].exp()
        own = torch.cat([mean + temperature * sigma * torch.randn_like(mean), (contacts > 0).to(mean.dtype)], -1)
        own[..., :d] *= model.modelled.to(own.dtype)  # constant channels stay at their (zero) value
        # A pass fed a half-converged rollout can draw far outside the data (NaN within 200 steps on a GPU run
        # with 4 passes at temperature 1): clip to DRAW_LIMIT standard deviations, wider than the capture's range.
        own = own.nan_to_num(0.0).clamp(-DRAW_LIMIT, DRAW_LIMIT)
        mixed = frames.clone()
        mixed[:, 1:] = torch.where(mask, own, frames[:, 1:])
    model.train(was_training)
    return mixed


def hide_history(frames: torch.Tensor, share: float, stretch: int) -> torch.Tensor:
    """Input frames [B, T, D] with stretches of `stretch` whole frames (`share` of them, `own_mask`) set to zero,
    the capture's mean once normalised.

    Why: the dilated stack reads the dance's phase off the frames before (and the input skip copies the last
    one), so teacher forcing barely needs the music, and a dance keeps its own rhythm whatever the song does
    (its BAS against other songs' beats was within 5% of its own song's). With the recent frames hidden, the
    next frame's timing can only come from the music."""
    hidden = own_mask(frames.shape[:2], share, stretch, frames.device)
    return frames.masked_fill(hidden[..., None], 0.0)


ROOT_STEP = [0, 2, 3]  # the root's sideways and forward step and its turn (representation.py)


def travel_loss(model: torch.nn.Module, out: torch.Tensor, target: torch.Tensor, mean: torch.Tensor,
                std: torch.Tensor, windows: list[int]) -> torch.Tensor:
    """How far the predicted root path strays from the dancer's over whole windows.

    The mixture's expected root step (sideways, forward, turn; unnormalised by `mean`/`std` of those channels)
    is turned into the world by the dancer's own heading and summed over every window of each length; the
    squared difference to the dancer's sums, in units of their spread, averaged. Why: a step-by-step NLL lets
    a model shuffle in place (each step's mean shrunk toward zero costs little); this loss sees the ground a
    second or four seconds of dance covers (FACT's and Bailando's remedy for freezing dances).
    """
    logits, mu, _, _ = model.split(out)
    expected = (torch.softmax(logits, -1)[..., None] * mu).sum(-2)
    pred = expected[..., ROOT_STEP] * std + mean
    true = target[..., ROOT_STEP] * std + mean
    prev_yaw = torch.cumsum(true[..., 2], 1) - true[..., 2]
    c, s = torch.cos(prev_yaw), torch.sin(prev_yaw)

    def path(v: torch.Tensor) -> torch.Tensor:  # world steps (rotation about +Y, as decode) and turn, summed
        return torch.cumsum(torch.stack([v[..., 0] * c + v[..., 1] * s, -v[..., 0] * s + v[..., 1] * c,
                                         v[..., 2]], -1), 1)

    cp, cq = path(pred), path(true)
    terms = []
    for n in (n for n in windows if n < out.shape[1]):
        sp, sq = cp[:, n:] - cp[:, :-n], cq[:, n:] - cq[:, :-n]
        terms.append((((sp - sq) ** 2).mean((0, 1)) / ((sq**2).mean((0, 1)).detach() + 1e-6)).mean())
    return torch.stack(terms).mean() if terms else out.new_zeros(())


def held_out_windows(pairs: list[PairedSequence], norm: Normalizer, styles: list[str], layout: FeatureLayout,
                     window: int, seed: int) -> Batch:
    """The fixed, noise-free windows a run's held-out loss is measured on (the same for a run and its blends)."""
    return WindowSampler(pairs, norm, styles, layout, window=window, stride=25, seed=seed).fixed_windows(64)


def windows_loss(model: torch.nn.Module, windows: Batch, name: str, device: torch.device) -> dict[str, float]:
    """`model`'s loss on `windows` as {name}_loss and its parts (the model is left in the mode it was in)."""
    was_training = model.training
    model.eval()
    with torch.no_grad():
        music = torch.tensor(windows.music, device=device)
        o = model(torch.tensor(windows.motion, device=device), music, torch.tensor(windows.style, device=device))
        loss, parts = model.loss(o, torch.tensor(windows.target[:, 1:], device=device), music[:, 1:])
    model.train(was_training)
    return {f"{name}_loss": loss.item()} | {f"{name}_{k}": v for k, v in parts.items()}


def prime_rmsprop(opt: torch.optim.RMSprop, model: torch.nn.Module,
                  batch_loss: Callable[[], tuple[torch.Tensor, dict]], batches: int = 20) -> None:
    """Start RMSprop's running mean of squared gradients at their mean over `batches` batches, taking no step.

    Why: from an empty history RMSprop's first step moves every weight by 10x the learning rate in the sign of
    its gradient; a warm start's held-out loss went from -0.46 to 15.8 in that one step (learning rate 1e-6)
    and took hundreds of steps to come back. Primed, the first step is an ordinary one.
    """
    params = [p for g in opt.param_groups for p in g["params"]]
    mean_sq = [torch.zeros_like(p) for p in params]
    for _ in range(batches):
        opt.zero_grad()
        batch_loss()[0].backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 10.0)
        for acc, p in zip(mean_sq, params, strict=True):
            if p.grad is not None:
                acc += p.grad.detach() ** 2 / batches
    opt.zero_grad()
    for acc, p in zip(mean_sq, params, strict=True):
        opt.state[p] = {"step": torch.zeros((), dtype=torch.float32), "square_avg": acc}


def _log(out: Path, record: dict) -> None:
    """Append a line to the run's log, opened and closed each time: the log of a run that stops with an error
    is never left open, and a reader always sees whole lines."""
    with open(out / "log.jsonl", "a") as log:
        log.write(json.dumps(record) + "\n")


def _ddp() -> tuple[int, int]:
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world > 1 and not torch.distributed.is_initialized():
        backend = "nccl" if torch.cuda.is_available() else "gloo"
        torch.distributed.init_process_group(backend)
    rank = torch.distributed.get_rank() if world > 1 else 0
    return rank, world


@dataclass
class _Songs:
    """What a run trains on and is measured on: the training sequences, the held-out ones (the validation songs
    when held out, else the test songs), the styles learnt and why others are left out."""

    train: list[PairedSequence]
    held_out: list[PairedSequence]
    styles: list[str]
    left_out: dict[str, str]
    validation: set[str]  # the validation songs held out of training (none unless --validation)
    test: set[str]


def _songs(args: TrainSettings, pairs: list[PairedSequence] | None, split: dict | None, rank: int) -> _Songs:
    """The sequences (the built dataset, a pack, or `pairs`) split by `split` (default: the shipped one)."""
    if pairs is None and args.pack:
        pairs = load_pack(args.pack)
    elif pairs is None:
        pairs = build_dataset(args.data or default_data_dir(), progress=rank == 0)
        if music_features(args.variant) == "mel":
            pairs = with_mel_music(pairs, args.data or default_data_dir())
    split = split or load_split()
    # Validation songs (training songs held out by song) stay out of training: settings are chosen on them.
    held_out = set(split.get("validation", [])) if args.validation else set()
    train_ids, test_ids = set(split["train"]) - held_out, set(split["test"])
    styles, left_out = shipped_styles(pairs, train_ids)
    train_pairs = [p for p in pairs if p.seq in train_ids and p.style in styles]
    test_pairs = [p for p in pairs if p.seq in test_ids and p.style in styles]
    eval_pairs = [p for p in pairs if p.seq in held_out and p.style in styles] if held_out else test_pairs
    if args.motion_prior:  # motion without music, in one style; held-out windows silent too
        train_pairs, eval_pairs, styles = prior_sequences(train_pairs, args.data or default_data_dir()), \
            silent(eval_pairs), [PRIOR_STYLE]
    return _Songs(train_pairs, eval_pairs, styles, left_out, held_out, test_ids)


def _run_info(args: TrainSettings, songs: _Songs, windows: WindowSampler, device: torch.device) -> dict:
    """What the weights file tells about its run (the model card's facts)."""
    return {
        "variant": args.variant,
        "data": "Dance with Melody (Tang et al. 2018, both folders), training split of weights/song_split.json"
                + (" less its validation songs" if songs.validation else "")
                + (", and the CMU dance clips; all without music (a motion prior)" if args.motion_prior else ""),
        "validation_sequences": sorted(songs.validation),
        "init": str(args.init) if args.init else None,
        "minutes_per_style": {s: round(sum(len(p.motion) for p in songs.train if p.style == s) / 1500, 2)
                              for s in songs.styles},
        "train_sequences": sorted(p.seq for p in songs.train),
        "test_sequences": sorted(songs.test),  # the split's, also when a pack (which holds none of them) trains
        "styles_left_out": songs.left_out,
        "train_minutes": sum(len(p.motion) for p in songs.train) / 25 / 60,
        "windows": len(windows.index),
        "cluster_sizes": windows.cluster_sizes.tolist(),
        "settings": asdict(args) | {"data": str(args.data)},
        "device": torch.cuda.get_device_name(device) if device.type == "cuda" else "CPU",
    }


class _Run:
    """One training run: the model, its optimiser and windows, and where it stands (step, elapsed seconds)."""

    def __init__(self, args: TrainSettings, songs: _Songs, rank: int, world: int, device: torch.device) -> None:
        self.args, self.songs, self.rank, self.device = args, songs, rank, device
        self.out = Path(args.out)
        self.rng = np.random.default_rng(args.seed + rank)
        layout = FeatureLayout(55, 5)
        self.init = DanceNetBundle.load(args.init) if args.init else None
        # A warm start keeps its normaliser: its weights were learnt on that scale.
        self.norm = self.init.normalizer if self.init else Normalizer.fit(
            [p.motion for p in songs.train] + [p.mirrored for p in songs.train], binary=layout.contacts)
        model = self.model = build_model(args.variant, layout.size, layout.continuous.stop, songs.styles, args.window,
                                         mixtures=args.mixtures, residual_output=args.residual_output,
                                         input_skip=args.input_skip, widths=tuple(args.widths) or None)
        if args.input_dropout is not None:
            model.cfg.input_dropout = args.input_dropout
        model.modelled.copy_(torch.tensor(~self.norm.constant[layout.continuous]))
        if self.init:
            warm_start(model, self.init.model)
        model.to(device)
        self.net = torch.nn.parallel.DistributedDataParallel(model, find_unused_parameters=True) if world > 1 \
            else model
        self.opt = torch.optim.RMSprop(model.parameters(), lr=args.lr)
        self.windows = WindowSampler(songs.train, self.norm, songs.styles, layout, window=args.window, seed=args.seed)
        # On a GPU the numpy batch is the bottleneck: draw the same windows from tensors on the device instead.
        self.device_windows = TensorWindows(self.windows, device) if device.type == "cuda" else None
        self.root_mean, self.root_std = (torch.tensor(a[ROOT_STEP], dtype=torch.float32, device=device)
                                         for a in (self.norm.mean, self.norm.std))
        # Held-out loss on the validation songs when they are held out (settings are chosen there), else on the
        # test songs (a figure for the card only).
        self.eval_name = "val" if songs.validation else "test"
        self.test_windows = held_out_windows(songs.held_out, self.norm, songs.styles, layout, args.window, args.seed)
        self.start_frames = {s: np.stack([p.motion[0] for p in songs.train if p.style == s]) for s in songs.styles}
        self.info = _run_info(args, songs, self.windows, device)
        self.step, self.elapsed, self.budget = 0, 0.0, args.minutes * 60

    def resume(self) -> None:
        """Carry on from the run's checkpoint: weights, optimiser, position and every generator's state."""
        state = load_weights(self.out / "checkpoint.pt", "training checkpoint", "delete it to start the run afresh")
        self.model.load_state_dict(state["bundle"]["state_dict"])
        self.opt.load_state_dict(state["optimizer"])
        self.step, self.elapsed = state["step"], state["elapsed"]
        self.rng.bit_generator.state = state["rng"]
        torch.set_rng_state(state["torch_rng"])
        if self.device.type == "cuda" and state.get("cuda_rng") is not None:  # the device's windows and draws
            torch.cuda.set_rng_state(state["cuda_rng"], self.device)
        if self.rank == 0:
            print(f"resumed at step {self.step} ({self.elapsed / 60:.1f} min)")

    def checkpoint(self) -> None:
        save_weights({"bundle": self.bundle().to_dict(), "optimizer": self.opt.state_dict(), "step": self.step,
                      "elapsed": self.elapsed, "rng": self.rng.bit_generator.state, "torch_rng": torch.get_rng_state(),
                      "cuda_rng": torch.cuda.get_rng_state(self.device) if self.device.type == "cuda" else None},
                     self.out / "checkpoint.pt")

    def bundle(self) -> DanceNetBundle:
        return DanceNetBundle(self.model, self.norm, mean_skeleton(self.songs.train), self.start_frames,
                              self.info | {"steps": self.step, "train_seconds": self.elapsed})

    def held_out_loss(self) -> dict[str, float]:
        return windows_loss(self.model, self.test_windows, self.eval_name, self.device)

    def batch_loss(self) -> tuple[torch.Tensor, dict[str, float]]:
        """The training loss of one fresh batch (own draws and travel loss as the settings ask)."""
        args, model, cfg = self.args, self.model, self.model.cfg
        if self.device_windows:
            b = self.device_windows.batch(args.batch, input_noise=args.input_noise)
            noisy, music, style, target = b.motion, b.music, b.style, b.target
        else:
            b = self.windows.batch(self.rng, args.batch, input_noise=args.input_noise)
            noisy, music, style, target = (torch.tensor(a, device=self.device)
                                           for a in (b.motion, b.music, b.style, b.target))
        progress = max(self.step / args.steps, self.elapsed / self.budget)
        share = args.own_inputs * (min(1.0, progress / args.own_ramp) if args.own_ramp > 0 else 1.0)
        if share > 0:
            noisy = with_own_predictions(model, noisy, music, style, share, args.own_passes, args.own_stretch,
                                         args.own_temperature)
        x = F.dropout(noisy, cfg.input_dropout, training=True)
        if args.history_dropout > 0:
            x = hide_history(x, args.history_dropout, args.history_stretch)
        # A residual output starts from the frame before dropout: dropout hides channels from the network,
        # not from the frame the change is added to (at generation that frame is whole).
        net = self.net
        o = net(x, music, style, base=noisy) if getattr(cfg, "residual_output", False) else net(x, music, style)
        loss, parts = model.loss(o, target[:, 1:], music[:, 1:])
        if args.travel_weight > 0:
            travel = travel_loss(model, o, target[:, 1:], self.root_mean, self.root_std, args.travel_windows)
            loss = loss + args.travel_weight * travel
            parts["travel"] = float(travel.detach())
        return loss, parts

    def optimise(self) -> tuple[torch.Tensor, dict[str, float]]:
        """One step of the optimiser on a fresh batch; its loss and the loss's parts."""
        args, opt = self.args, self.opt
        loss, parts = self.batch_loss()
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(self.model.parameters(), 10.0)
        opt.step()
        self.step += 1
        # The supplement drops the rate by 10 at 77% of training (epoch 1000 of 1300); here 77% of the
        # planned steps or of the time budget, whichever comes first.
        progress = max(self.step / args.steps, self.elapsed / self.budget)
        if progress >= 0.77 and opt.param_groups[0]["lr"] > args.lr * 0.5:
            for g in opt.param_groups:
                g["lr"] = args.lr * 0.1
        return loss, parts

    def record(self, loss: torch.Tensor, parts: dict[str, float]) -> None:
        """What rank 0 writes after a step: the log line, a snapshot, the checkpoint, as often as asked."""
        args, step, out = self.args, self.step, self.out
        if step % args.log_every == 0 or step == 1:
            rec = {"step": step, "minutes": round(self.elapsed / 60, 2), "lr": self.opt.param_groups[0]["lr"],
                   "loss": loss.item(), **parts}
            if step % (args.log_every * 5) == 0 or step == 1:
                rec |= self.held_out_loss()
            _log(out, rec)
        if args.snapshot_every and step % args.snapshot_every == 0:
            # Kept weights along the way: the learning curve (held-out FID_k against time) is measured on them.
            # Each carries its held-out loss, so a snapshot chosen for shipping has its card's figures.
            (out / "snapshots").mkdir(exist_ok=True)
            snapshot = self.bundle()
            snapshot.info |= self.held_out_loss()
            snapshot.save(out / "snapshots" / f"step{step:06d}.pt")

    def finish(self) -> None:
        """The run's weights (with their held-out loss), the runtime's arrays, the log's last line."""
        final = self.bundle()
        final.info |= self.held_out_loss()
        final.save(self.out / "dancenet.pt")
        if isinstance(final.model, DanceNet):  # what generation runs, without torch
            bundle_to_runtime(final).save(self.out / "dancenet.npz")
        _log(self.out, {"step": self.step, "minutes": round(self.elapsed / 60, 2), "done": True,
                        **self.held_out_loss()})


def train(args: TrainSettings, pairs: list[PairedSequence] | None = None, split: dict | None = None) -> Path:
    """Train; `pairs` and `split` default to the built dataset and the shipped song split."""
    rank, world = _ddp()
    local = int(os.environ.get("LOCAL_RANK", 0))
    device = torch.device(f"cuda:{local}" if torch.cuda.is_available() else "cpu")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(args.seed + rank)
    run = _Run(args, _songs(args, pairs, split, rank), rank, world, device)
    if args.resume and (out / "checkpoint.pt").is_file():
        run.resume()
    run.model.train()
    if run.init and run.step == 0:
        prime_rmsprop(run.opt, run.model, run.batch_loss)
    t_last = time.time()
    while run.step < args.steps and run.elapsed < run.budget:
        loss, parts = run.optimise()
        now = time.time()
        run.elapsed += now - t_last
        t_last = now
        if rank == 0:
            run.record(loss, parts)
        if rank == 0 and run.step % args.checkpoint_every == 0:
            run.checkpoint()
            t_last = time.time()
    if rank == 0:
        run.finish()
    return out / "dancenet.pt"

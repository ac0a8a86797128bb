"""Training of the match of music and movement (`library/match.py`), `dancenet train match`: each bar of a training
song against the bar danced to it, contrastive (InfoNCE both ways, the batch's other bars as negatives), mirrored
dances as more pairs; settings chosen on the validation songs, figures reported on the test split."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from ..atomic import write_text
from ..data.build import MODEL_FPS, PairedSequence, build_dataset
from ..data.dance_with_melody import read_manifest
from ..data.split import load_split
from ..environment import default_data_dir
from ..library.match import SAMPLES, SPEED_COLS, MatchModel, mirrored, motion_bars, motion_frames, music_bars
from ..music.features import FPS as MUSIC_FPS
from ..music.features import ONSET_COL, analyze_music
from .configs import MatchSettings

MIN_BAR_S, MAX_BAR_S = 0.6, 4.0  # bars outside this (a tracker's gap or stutter) are left out


@dataclass
class SongBars:
    """One dance's bars: music rows (with context), motion rows (and of its mirror image), per-bar music onset
    strength and motion energy (the energy baseline) and the style."""

    seq: str
    style: str
    music: np.ndarray
    motion: np.ndarray
    motion_mirror: np.ndarray
    onset: np.ndarray
    energy: np.ndarray


def song_bars(pair: PairedSequence, audio: str, offset_s: float, context: int) -> SongBars | None:
    """The dance's bars: the song's tracked bars (downbeat to downbeat) that the motion covers."""
    analysis = analyze_music(audio)
    beats, downs = analysis.beat_times, analysis.downbeat_times
    n = len(pair.positions)
    bars = []
    for a, b in zip(downs[:-1], downs[1:], strict=True):
        bb = beats[(beats >= a - 1e-6) & (beats <= b + 1e-6)]
        if len(bb) < 3 or not MIN_BAR_S <= b - a <= MAX_BAR_S:
            continue
        if (bb[0] - offset_s) * MODEL_FPS < 0 or (bb[-1] - offset_s) * MODEL_FPS > n - 1:
            continue
        bars.append(bb)
    if len(bars) < 2:
        return None
    music = music_bars(analysis.features, bars, context)
    beat_frames = [(bb - offset_s) * MODEL_FPS for bb in bars]
    out, speed = [], None
    for pos in (pair.positions, mirrored(pair.positions)):
        frames = motion_frames(pos, MODEL_FPS)
        out.append(np.concatenate([motion_bars(frames, bf[None], MODEL_FPS) for bf in beat_frames]))
        if speed is None:
            speed = frames[:, SPEED_COLS].mean(1)
    onset = np.array([analysis.features[int(bb[0] * MUSIC_FPS) : int(bb[-1] * MUSIC_FPS) + 1, ONSET_COL].mean()
                      for bb in bars])
    energy = np.array([speed[int(bf[0]) : int(np.ceil(bf[-1])) + 1].mean() for bf in beat_frames])
    return SongBars(pair.seq, pair.style, music, out[0], out[1], onset, energy)


def load_bars(context: int, seqs: Sequence[str] | None = None) -> dict[str, SongBars]:
    """Every (or the named) sequence's bars from the paired dataset."""
    rec = {r.seq: r for r in read_manifest(default_data_dir())}
    pairs = build_dataset(default_data_dir(), progress=False)
    out = {}
    for p in pairs:
        if seqs is not None and p.seq not in seqs:
            continue
        s = song_bars(p, str(rec[p.seq].audio), rec[p.seq].music_offset_s, context)
        if s is not None:
            out[p.seq] = s
    return out


class Tower(nn.Module):
    """Standardised input -> hidden (ReLU, dropout) -> embedding, unit length."""

    def __init__(self, mean: np.ndarray, std: np.ndarray, hidden: int, dim: int, dropout: float, noise: float) -> None:
        super().__init__()
        self.noise = noise
        self.register_buffer("mean", torch.from_numpy(mean))
        self.register_buffer("std", torch.from_numpy(std))
        self.net = nn.Sequential(nn.Dropout(dropout), nn.Linear(len(mean), hidden), nn.ReLU(), nn.Dropout(dropout),
                                 nn.Linear(hidden, dim))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = (x - self.mean) / self.std
        if self.training and self.noise > 0:
            x = x + self.noise * torch.randn_like(x)
        return nn.functional.normalize(self.net(x), dim=-1)

    def layers(self) -> list[tuple[np.ndarray, np.ndarray]]:
        return [(m.weight.detach().numpy().copy(), m.bias.detach().numpy().copy())
                for m in self.net if isinstance(m, nn.Linear)]


def _stats(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return x.mean(0).astype(np.float32), (x.std(0) + 1e-3).astype(np.float32)


def train_match(songs: Sequence[SongBars], settings: MatchSettings, *, batch: int = 256, hidden: int = 256,
                dim: int = 64, lr: float = 1e-3, weight_decay: float = 1e-4, log: Callable[[str], None] = print
                ) -> tuple[MatchModel, list[float]]:
    """InfoNCE both ways on random batches of bars (a dance or its mirror image), with `settings.style_weight` times
    a style classifier's loss on both embeddings (one linear head, kept with the model: `MatchModel.style_probs`);
    `settings.balanced`: bars drawn with each style equally likely. Adam, lr / 10 for the last quarter. Returns the
    model and the loss per tenth of the steps."""
    s = settings
    seed, steps, context, temperature = s.seed, s.steps, s.context, s.temperature
    style_weight, balanced, dropout, noise = s.style_weight, s.balanced, s.dropout, s.noise
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    music = np.concatenate([s.music for s in songs for _ in (0, 1)])
    motion = np.concatenate([m for s in songs for m in (s.motion, s.motion_mirror)])
    styles = sorted({s.style for s in songs})
    label = np.concatenate([[styles.index(s.style)] * len(s.music) for s in songs for _ in (0, 1)])
    share = np.bincount(label, minlength=len(styles)) / len(label)
    p = 1.0 / share[label] if balanced else np.ones(len(label))
    p /= p.sum()
    mu, mo = (Tower(*_stats(music), hidden, dim, dropout, noise),
              Tower(*_stats(motion), hidden, dim, dropout, noise))
    head = nn.Linear(dim, len(styles))
    opt = torch.optim.AdamW([*mu.parameters(), *mo.parameters(), *head.parameters()], lr=lr,
                            weight_decay=weight_decay)
    sched = torch.optim.lr_scheduler.MultiStepLR(opt, [int(0.75 * steps)], 0.1)
    xm, xd, y = torch.from_numpy(music), torch.from_numpy(motion), torch.from_numpy(label)
    curve, total, t0 = [], 0.0, time.time()
    every = max(1, steps // 10)
    for step in range(1, steps + 1):
        idx = torch.from_numpy(rng.choice(len(music), min(batch, len(music)), replace=False, p=p))
        em, ed = mu(xm[idx]), mo(xd[idx])
        logits = em @ ed.T / temperature
        target = torch.arange(len(idx))
        loss = 0.5 * (nn.functional.cross_entropy(logits, target) + nn.functional.cross_entropy(logits.T, target))
        if style_weight > 0:
            loss = loss + 0.5 * style_weight * (nn.functional.cross_entropy(head(em), y[idx])
                                                + nn.functional.cross_entropy(head(ed), y[idx]))
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        total += loss.item()
        if step % every == 0:
            curve.append(round(total / every, 4))
            log(f"step {step}/{steps} loss {total / every:.3f} ({time.time() - t0:.0f} s)")
            total = 0.0
    mu.eval()
    mo.eval()
    meta = {"context": context, "steps": steps, "batch": batch, "hidden": hidden, "dim": dim, "dropout": dropout,
            "noise": noise, "style_weight": style_weight, "balanced": balanced, "temperature": temperature, "lr": lr,
            "weight_decay": weight_decay, "seed": seed,
            "train_seconds": round(time.time() - t0)}
    meta["styles"] = styles
    head_layer = (head.weight.detach().numpy().copy(), head.bias.detach().numpy().copy())
    return MatchModel(mu.mean.numpy(), mu.std.numpy(), mo.mean.numpy(), mo.std.numpy(), mu.layers(), mo.layers(),
                      meta, head_layer), curve


def retrieval(model: MatchModel, songs: Sequence[SongBars], candidates: int = 32, seed: int = 0) -> dict:
    """Top-1 / top-5: each bar of music against the bar danced to it and `candidates` - 1 other bars of `songs`,
    drawn at random (seeded)."""
    rng = np.random.default_rng(seed)
    em = model.embed_music(np.concatenate([s.music for s in songs]))
    ed = model.embed_motion(np.concatenate([s.motion for s in songs]))
    ranks = []
    for i in range(len(em)):
        others = rng.choice(np.delete(np.arange(len(ed)), i), candidates - 1, replace=False)
        s = ed[np.concatenate([[i], others])] @ em[i]
        ranks.append(int((s[1:] > s[0]).sum()))
    ranks = np.array(ranks)
    return {"candidates": candidates, "top1": float(np.mean(ranks < 1)), "top5": float(np.mean(ranks < 5)),
            "bars": len(ranks)}


def style_transfer(model: MatchModel | None, songs: Sequence[SongBars], library: Sequence[SongBars],
                   song_weight: float = 0.0) -> dict:
    """For each bar of `songs`, the best-scoring motion bar of `library`: the share from dances of the song's own
    style (per style and their mean); `model` None: energy matching alone (the bar whose motion energy rank is
    nearest the music's onset-strength rank)."""
    lib_style = np.concatenate([[s.style] * len(s.motion) for s in library])
    if model is None:
        lib_e = np.concatenate([s.energy for s in library])
        lib_rank = np.argsort(np.argsort(lib_e)) / max(1, len(lib_e) - 1)
        song_on = np.concatenate([s.onset for s in songs])
        on_sorted = np.sort(song_on)
    else:
        ed = model.embed_motion(np.concatenate([s.motion for s in library]))
    hits: dict[str, list[float]] = {}
    for s in songs:
        if model is None:
            r = np.searchsorted(on_sorted, s.onset) / max(1, len(on_sorted) - 1)
            best = np.argmin(np.abs(lib_rank[None] - r[:, None]), axis=1)
        else:
            best = np.argmax(song_music(model.embed_music(s.music), song_weight) @ ed.T, axis=1)
        hits.setdefault(s.style, []).append(float(np.mean(lib_style[best] == s.style)))
    per_style = {k: round(float(np.mean(v)), 4) for k, v in sorted(hits.items())}
    all_songs = [h for v in hits.values() for h in v]
    return {"per_style": per_style, "style_mean": round(float(np.mean(list(per_style.values()))), 4),
            "song_mean": round(float(np.mean(all_songs)), 4)}


def song_music(bars: np.ndarray, song_weight: float) -> np.ndarray:
    return bars + song_weight * bars.mean(0)


def split_songs(bars: dict[str, SongBars]) -> tuple[list[SongBars], list[SongBars], list[SongBars]]:
    """(training less validation, validation, test) songs of the song split."""
    split = load_split()
    val = set(split["validation"])
    train = [bars[s] for s in split["train"] if s in bars and s not in val]
    return train, [bars[s] for s in split["validation"] if s in bars], [bars[s] for s in split["test"] if s in bars]


def train_and_ship(settings: MatchSettings, log: Callable[[str], None] = print) -> dict:
    """Train on the training songs less the validation songs and write the weights and their card; figures on the
    validation songs (`validate`: settings are chosen on those) or on the test songs, there also against the
    validation songs' dances alone (motion the model never saw)."""
    torch.set_num_threads(1)
    bars = load_bars(settings.context)
    train, val, test = split_songs(bars)
    fit_on = train
    model, curve = train_match(fit_on, settings, log=log)
    held = val if settings.validate else test
    figures = {"held_out": "validation" if settings.validate else "test",
               "train_songs": [s.seq for s in fit_on], "held_out_songs": [s.seq for s in held],
               "train_bars": int(sum(len(s.music) for s in fit_on)),
               "held_out_bars": int(sum(len(s.music) for s in held)),
               "loss_curve": curve, "retrieval": retrieval(model, held),
               "retrieval_chance": {"top1": 1 / 32, "top5": 5 / 32},
               "style_transfer": style_transfer(model, held, fit_on),
               "style_transfer_energy": style_transfer(None, held, fit_on)}
    if not settings.validate:
        figures["style_transfer_unseen_motion"] = style_transfer(model, test, val)
        figures["style_transfer_unseen_motion_energy"] = style_transfer(None, test, val)
    model.meta["figures"] = figures
    model.save(settings.out)
    write_card(settings, model)
    return figures


def _styles_row(name: str, r: dict) -> str:
    return f"| {name} | " + " | ".join(f"{100 * v:.0f}%" for v in r["per_style"].values()) + \
        f" | {100 * r['style_mean']:.0f}% | {100 * r['song_mean']:.0f}% |"


def write_card(settings: MatchSettings, model: MatchModel) -> Path:
    """MATCH_MODEL_CARD.md beside the weights: data, settings, curve and figures, from the weights' own record."""
    f, m = model.meta["figures"], model.meta
    styles = list(f["style_transfer"]["per_style"])
    head = "| scored by | " + " | ".join(styles) + " | mean of styles | mean of songs |\n|" + "---|" * (len(styles) + 3)
    r = f["retrieval"]
    cmd = "dancenet train match" + (" --validate --out runs/match_validate.npz" if settings.validate else "")
    text = f"""# Match of music and movement: model card

What it is: two small networks that map a bar of music (its accents at {SAMPLES} points over its beats, its chroma,
onset strength, beat length and beat count, with {m['context']} bars either side) and a bar of motion (each body
joint relative to the pelvis in the dancer's heading frame, joint speeds, the pelvis' speed and height at the same
points, and the beat length) to unit vectors whose cosine says how well the motion fits the music, and a style
head on both. The library engine uses it for a library whose clips name no style (`library/choreography.py`): the
part's music's style (the head over its bars) against each clip's (the head over its figures), so that such a
library dances the song's style; the per-bar cosine is available to the plan but off by default, as it did not
help on the validation songs (docs/matching.md has the plan's figures). Run time: numpy only (`library/match.py`);
weights: `{settings.out.name}`.

## Data

The paired capture of Dance with Melody (`dancenet data build`): each tracked bar of a song (downbeat to downbeat,
{MIN_BAR_S}-{MAX_BAR_S} s) that its dance covers, and the bar danced to it, plus its mirror image. Trained on
{len(f['train_songs'])} training songs, the validation songs left out ({f['train_bars']} bars); figures on the
{f['held_out']} songs ({f['held_out_bars']} bars: {', '.join(f['held_out_songs'])}), which the model never saw.
Settings were chosen on the validation songs (held out by song: `dancenet train match --validate`).

## Settings

InfoNCE both ways (each bar of music against the bar danced to it, the batch's other bars as negatives), temperature
{m['temperature']}, plus {m['style_weight']} x a linear style classifier's loss on both embeddings (one head for both,
over the training dances' styles: {', '.join(m['styles'])}; shipped with the weights, the plan's style term reads
it), batches of {m['batch']} bars with every style equally
likely: {m['balanced']}; hidden layer {m['hidden']}, embedding {m['dim']}, dropout {m['dropout']}, input noise
{m['noise']}, AdamW lr {m['lr']} (weight decay {m['weight_decay']}), {m['steps']} steps (lr / 10 for the last
quarter), seed {m['seed']}; {m['train_seconds']} s on one CPU thread.

Loss per tenth of training: {', '.join(f'{x:.2f}' for x in f['loss_curve'])}.

## Figures ({f['held_out']} songs, `{cmd}`)

Retrieval: each bar of music against the bar danced to it among {r['candidates']} motion bars of the
{f['held_out']} songs: top-1 {100 * r['top1']:.1f}% (chance {100 / r['candidates']:.1f}%), top-5
{100 * r['top5']:.1f}% (chance {500 / r['candidates']:.1f}%), {r['bars']} bars.

Style transfer without labels: for each bar of a {f['held_out']} song, the best-scoring motion bar among all bars
of the training dances (the dances the model was trained on: the motion side is not held out here); the share from
dances of the song's own style. Energy matching: the bar whose motion energy rank is nearest the music's onset
strength rank. Chance by style is 25%; the training dances are mostly waltz, so energy matching's waltz share is
high by itself.

{head}
{_styles_row('learned match', f['style_transfer'])}
{_styles_row('energy matching', f['style_transfer_energy'])}
"""
    if not settings.validate:
        text += f"""
Motion the model never saw: the test songs' bars against the validation songs' dances only (held out from this run):

{head}
{_styles_row('learned match', f['style_transfer_unseen_motion'])}
{_styles_row('energy matching', f['style_transfer_unseen_motion_energy'])}
"""
    text += """
## Limits

Ten test songs, six of them waltzes: a song is a tenth of a figure. Waltz is told apart by its three beats a bar;
cha-cha, rumba and tango are all four beats a bar and close in tempo, and the validation tango is taken for a
rumba or cha-cha by every setting tried. How the plan uses it, and the share of a dance's frames from clips of the
song's style, is in docs/matching.md.
"""
    path = settings.out.with_name("MATCH_MODEL_CARD.md" if not settings.validate else settings.out.stem + "_card.md")
    write_text(path, text)
    return path

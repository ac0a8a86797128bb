"""Musical style classifier (paper section 4.2) and its FC + Bi-LSTM baseline, with training on the
Dance with Melody songs.

The classifier sees 30-second windows of a song's [T, 15] classifier input (10 fps; `classifier_input`) as a
one-channel image:
three Conv2d layers with (2, 1) kernels along time, channels 1-16-24-32 (the last with stride 2, as in the
authors' music encoder), BatchNorm and ReLU, then a Bi-LSTM over time and a fully connected layer on its
time-averaged output. A song's style is the mean of its windows' probabilities. Style names live in the
checkpoint's metadata, never in code, so a model trained on other styles needs no code change.

The classifier input is the music features with the beat and downbeat activation columns replaced by a bump of
fixed height at each beat and downbeat that madmom's DBN tracked: sampled at 10 fps, the 100-fps activations
miss many of their peaks (a song's highest sampled beat value ranges 0.24-0.93 on the training songs), while
the tracked beats carry tempo and metre (3 beats a bar for waltz) intact. DanceNet's own input is unchanged.

Train: `python -m dancenet_core.style train --data DIR --out DIR` (DIR holds manifest.csv and the songs);
`... card --data DIR --out DIR` rewrites the model card from the checkpoints' stored metrics.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from .atomic import write_text
from .checkpoint import read_checkpoint, save_weights
from .errors import DanceNetError
from .features import (
    BEAT_COL,
    CHROMA_COLS,
    DOWNBEAT_COL,
    FEATURE_VERSION,
    FPS,
    N_FEATURES,
    ONSET_COL,
    MusicAnalysis,
    analyze_music,
)

WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"
DEFAULT_WEIGHTS = WEIGHTS_DIR / "style_classifier.pt"
BASELINE_WEIGHTS = WEIGHTS_DIR / "style_baseline.pt"
SPLIT_FILE = WEIGHTS_DIR / "song_split.json"
CHECKPOINT_FORMAT = "dancenet-style-2"  # 2: beat and downbeat columns are DBN bumps (`classifier_input`)
WINDOW_S = 30.0  # the paper's window: style is not decided by a 2-3 s clip
HOP_S = 5.0  # between windows when a whole song is classified
SPLIT_SEED = 2020
TEST_FRACTION = 0.2
ARCHS = ("conv", "baseline")
# Settings chosen on training songs held out by song (`validate`), never on the test split.
STEPS = 200
HIDDEN = 32
DROPOUT = 0.3
LR = 1e-3
BATCH = 64
AUG_TEMPO = 0.12  # training windows are played up to 12% faster or slower
AUG_GAIN = 0.4  # on the onset channel; the beat and downbeat bumps have a fixed height
AUG_NOISE = 0.02
# Validation (conv, 7 training songs held out), sampled activations as input: balanced window accuracy 0.72 after
# 200 steps with chroma blanked in half the windows, 0.54-0.70 over 100-300 steps without (training accuracy 0.84 vs
# 0.93: harmony gets memorised).
AUG_CHROMA_DROP = 0.5
# Bump width: a beat between two frames still shows at exp(-1/8) = 0.88, and bumps of the fastest songs
# (190 bpm, 3.2 frames apart) dip to 0.28 between beats.
BUMP_SIGMA_FRAMES = 1.0
# `train --validate`, 200 steps: balanced accuracy by window (by song) of the conv model with the sampled beat and
# downbeat activations as input (the previous input) and with DBN bumps (this one), and of the baseline with bumps.
VALIDATION = {"activations": "0.72 (0.60)", "bumps": "0.88 (1.00)", "baseline": "0.70 (0.67)"}
# The same, with tango (the extra folder) as a fourth style: 200 steps and 400 steps.
VALIDATION_WITH_TANGO = {"200": "0.55 (0.50)", "400": "0.50 (0.50)"}


def bump_track(positions: np.ndarray, num_frames: int) -> np.ndarray:
    """[num_frames] float32 with a Gaussian bump of height 1 at each (fractional) frame position, overlapping
    bumps joined by their maximum: every beat shows at nearly full height, whatever the frame grid."""
    p = np.concatenate([[-np.inf], np.sort(np.asarray(positions, np.float64)), [np.inf]])
    grid = np.arange(num_frames, dtype=np.float64)
    i = np.searchsorted(p, grid)
    nearest = np.minimum(grid - p[i - 1], p[i] - grid)
    return np.exp(-0.5 * (nearest / BUMP_SIGMA_FRAMES) ** 2).astype(np.float32)


def classifier_input(analysis: MusicAnalysis) -> np.ndarray:
    """[T, 15] input of the style classifier: the music features, with the beat and downbeat activations
    replaced by bumps at the DBN's beat and downbeat times (see the module docstring for why)."""
    x = analysis.features.astype(np.float32, copy=True)
    x[:, BEAT_COL] = bump_track(analysis.beat_times * analysis.fps, len(x))
    x[:, DOWNBEAT_COL] = bump_track(analysis.downbeat_times * analysis.fps, len(x))
    return x


class StyleConvNet(nn.Module):
    """Temporal conv (kernel 2 along time, 1-16-24-32) + Bi-LSTM + FC: the paper's classifier."""

    def __init__(self, n_styles: int, hidden: int = HIDDEN, dropout: float = DROPOUT) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        for i, (cin, cout) in enumerate(((1, 16), (16, 24), (24, 32))):
            stride = (2, 1) if i == 2 else (1, 1)
            layers += [nn.Conv2d(cin, cout, (2, 1), stride=stride), nn.BatchNorm2d(cout), nn.ReLU()]
        self.conv = nn.Sequential(*layers, nn.Dropout(dropout))
        self.lstm = nn.LSTM(32 * N_FEATURES, hidden, batch_first=True, bidirectional=True)
        self.fc = nn.Linear(2 * hidden, n_styles)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """[B, T, 15] features -> [B, n_styles] logits."""
        h = self.conv(x.unsqueeze(1))  # [B, 32, T', 15]
        h = h.permute(0, 2, 1, 3).flatten(2)  # [B, T', 32 * 15]
        out, _ = self.lstm(h)
        return self.fc(out.mean(dim=1))


class StyleBaseline(nn.Module):
    """The paper's baseline: the temporal convolutions replaced by a per-frame fully connected layer."""

    def __init__(self, n_styles: int, hidden: int = HIDDEN, dropout: float = DROPOUT) -> None:
        super().__init__()
        self.fc_in = nn.Sequential(nn.Linear(N_FEATURES, 32 * N_FEATURES), nn.ReLU(), nn.Dropout(dropout))
        self.lstm = nn.LSTM(32 * N_FEATURES, hidden, batch_first=True, bidirectional=True)
        self.fc = nn.Linear(2 * hidden, n_styles)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """[B, T, 15] features -> [B, n_styles] logits."""
        out, _ = self.lstm(self.fc_in(x))
        return self.fc(out.mean(dim=1))


def build_net(arch: str, n_styles: int, **config: float) -> nn.Module:
    if arch == "conv":
        return StyleConvNet(n_styles, **config)  # type: ignore[arg-type]
    if arch == "baseline":
        return StyleBaseline(n_styles, **config)  # type: ignore[arg-type]
    raise ValueError(f"unknown style architecture {arch!r}; expected one of {ARCHS}")


def window_starts(num_frames: int, window: int, hop: int) -> np.ndarray:
    """Starts of windows every `hop` frames, plus one flush with the end so the tail counts too;
    a song shorter than a window is one shorter window."""
    if num_frames <= window:
        return np.zeros(1, dtype=np.int64)
    starts = np.arange(0, num_frames - window + 1, hop)
    if starts[-1] != num_frames - window:
        starts = np.append(starts, num_frames - window)
    return starts


@dataclass
class StyleResult:
    """A song's style: mean window probabilities, and each window's own."""

    styles: tuple[str, ...]
    probabilities: np.ndarray  # [S]
    window_starts_s: np.ndarray  # [W]
    window_probabilities: np.ndarray  # [W, S]
    window_s: float

    @property
    def style(self) -> str:
        return self.styles[int(np.argmax(self.probabilities))]

    def window_styles(self) -> list[str]:
        return [self.styles[int(i)] for i in np.argmax(self.window_probabilities, axis=1)]

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return {
            "style": self.style,
            "probabilities": {s: round(float(p), 4) for s, p in zip(self.styles, self.probabilities, strict=True)},
            "window_s": self.window_s,
            "windows": [
                {
                    "start_s": round(float(t), 2),
                    "style": s,
                    "probabilities": {n: round(float(p), 4) for n, p in zip(self.styles, probs, strict=True)},
                }
                for t, s, probs in zip(
                    self.window_starts_s, self.window_styles(), self.window_probabilities, strict=True
                )
            ],
        }


class StyleModel:
    """A trained network plus what it needs to be used: style names, window and frame rate."""

    def __init__(self, net: nn.Module, arch: str, styles: Sequence[str], config: dict, meta: dict | None = None):
        self.net = net.eval()
        self.arch = arch
        self.styles = tuple(styles)
        self.config = dict(config)
        self.meta = dict(meta or {})
        self.fps = int(self.meta.get("fps", FPS))
        self.window = int(round(float(self.meta.get("window_s", WINDOW_S)) * self.fps))
        self.hop = int(round(float(self.meta.get("hop_s", HOP_S)) * self.fps))

    def eval_mode(self) -> StyleModel:
        """Back to inference (dropout off, BatchNorm running statistics) after training steps."""
        self.net.eval()
        return self

    @classmethod
    def load(cls, path: str | Path = DEFAULT_WEIGHTS) -> StyleModel:
        ckpt = read_checkpoint(path, CHECKPOINT_FORMAT, "style model", "python -m dancenet_core.style train")
        net = build_net(ckpt["arch"], len(ckpt["styles"]), **ckpt["config"])
        net.load_state_dict(ckpt["state_dict"])
        return cls(net, ckpt["arch"], ckpt["styles"], ckpt["config"], ckpt["meta"])

    def save(self, path: str | Path) -> None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        meta = {
            **self.meta,
            "fps": self.fps,
            "window_s": self.window / self.fps,
            "hop_s": self.hop / self.fps,
            "feature_version": FEATURE_VERSION,
        }
        save_weights(
            {
                "format": CHECKPOINT_FORMAT,
                "arch": self.arch,
                "styles": list(self.styles),
                "config": self.config,
                "meta": meta,
                "state_dict": self.net.state_dict(),
            },
            path,
        )

    @torch.no_grad()
    def window_probabilities(self, features: np.ndarray, starts: np.ndarray, batch: int = 64) -> np.ndarray:
        """[W, S] softmax of the windows of `features` starting at `starts`."""
        length = min(self.window, len(features))
        x = torch.from_numpy(np.ascontiguousarray(features, dtype=np.float32))
        out = []
        for i in range(0, len(starts), batch):
            xb = torch.stack([x[s : s + length] for s in starts[i : i + batch]])
            out.append(torch.softmax(self.net(xb), dim=1))
        return torch.cat(out).numpy()

    def classify(self, analysis: MusicAnalysis) -> StyleResult:
        """Style of a whole song from its analysis (features and tracked beats): mean of the windows'
        probabilities (an overconfident window counts at most 1, where in a mean of log-probabilities it could
        veto a style)."""
        features = analysis.features
        if analysis.fps != self.fps or features.ndim != 2 or features.shape[1] != N_FEATURES:
            raise ValueError(
                f"expected [T, {N_FEATURES}] features at {self.fps} fps, got {features.shape} at {analysis.fps}"
            )
        if len(features) < 4:
            raise DanceNetError("the song is too short to classify its style; give at least a few seconds")
        starts = window_starts(len(features), self.window, self.hop)
        probs = self.window_probabilities(classifier_input(analysis), starts)
        return StyleResult(
            self.styles,
            probs.mean(axis=0),
            starts / self.fps,
            probs,
            min(self.window, len(features)) / self.fps,
        )


# ----------------------------------------------------------------------------------------------- training


@dataclass
class Song:
    seq: str
    style: str
    analysis: MusicAnalysis


def read_manifest(data_dir: Path) -> list[dict[str, str]]:
    """The dance set's songs as rows (seq, style, song_s, audio), both folders (data/dance_with_melody.py)."""
    from .data.dance_with_melody import read_manifest as read_sequences

    return [{"seq": q.seq, "style": q.style, "song_s": str(q.song_s), "audio": str(q.audio), "song": q.song}
            for q in read_sequences(data_dir)]


def make_split(rows: Sequence[dict[str, str]], seed: int = SPLIT_SEED, test_fraction: float = TEST_FRACTION) -> dict:
    """By song, stratified by style: round(test_fraction * n) songs of each style (at least one) are held
    out. A style with a single song can't be both learnt and tested, so it is excluded, with the reason."""
    rng = np.random.default_rng(seed)
    by_style: dict[str, list[str]] = {}
    for r in rows:
        by_style.setdefault(r["style"], []).append(r["seq"])
    split: dict = {"seed": seed, "test_fraction": test_fraction, "train": [], "test": [], "excluded": {}}
    for style in sorted(by_style):
        seqs = sorted(by_style[style], key=_seq_order)
        if len(seqs) < 2:
            for s in seqs:
                split["excluded"][s] = (
                    f"only song of style '{style}': it cannot be held out and "
                    "trained on at once, so the style classifier leaves this style out"
                )
            continue
        n_test = max(1, int(round(test_fraction * len(seqs))))
        test = set(rng.permutation(seqs)[:n_test].tolist())
        split["test"] += [s for s in seqs if s in test]
        split["train"] += [s for s in seqs if s not in test]
    return split


def extend_split(split: dict, rows: Sequence[dict[str, str]], excluded: dict[str, str]) -> dict:
    """The split with sequences it has not seen placed by the same by-song rule, nothing already placed moved.

    A new sequence of a style the split already holds trains (the test songs stay as they were); a new
    style's songs are split as `make_split` does, keeping sequences danced to one song on the same side.
    `excluded` names sequences to leave out, with the reason (e.g. data found to be unusable).
    """
    placed = set(split["train"]) | set(split["test"]) | set(split["excluded"])
    new = [r for r in rows if r["seq"] not in placed]
    out = {k: (dict(v) if isinstance(v, dict) else list(v) if isinstance(v, list) else v) for k, v in split.items()}
    out["excluded"].update({s: why for s, why in excluded.items() if s not in placed or s in split["excluded"]})
    for s in excluded:
        for side in ("train", "test"):
            if s in out[side]:
                out[side].remove(s)
    new = [r for r in new if r["seq"] not in excluded]
    known = {r["style"] for r in rows if r["seq"] in set(out["train"])}
    out["train"] += [r["seq"] for r in new if r["style"] in known]
    rng = np.random.default_rng(split["seed"])
    for style in sorted({r["style"] for r in new} - known):
        songs: dict[str, list[str]] = {}
        for r in sorted((r for r in new if r["style"] == style), key=lambda r: _seq_order(r["seq"])):
            songs.setdefault(r.get("song", r["seq"]), []).append(r["seq"])
        keys = list(songs)
        n_test = max(1, int(round(split["test_fraction"] * len(keys))))
        test = set(rng.permutation(keys)[:n_test].tolist())
        out["test"] += [s for k in keys if k in test for s in songs[k]]
        out["train"] += [s for k in keys if k not in test for s in songs[k]]
    return out


def load_or_make_split(path: Path, rows: Sequence[dict[str, str]], seed: int) -> dict:
    """The split is fixed once written: later runs (and the dance model) reuse the same file."""
    if path.is_file():
        split = json.loads(path.read_text())
        known = {r["seq"] for r in rows}
        missing = [s for s in split["train"] + split["test"] if s not in known]
        if missing:
            raise DanceNetError(f"{path} names songs not in the manifest: {missing[:3]}; delete it to re-split")
        return split
    split = make_split(rows, seed)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, json.dumps(split, indent=1) + "\n")
    return split


def _seq_order(seq: str) -> tuple[str, int]:
    head, _, num = seq.rpartition("_")
    return (head, int(num)) if num.isdigit() else (seq, 0)


def load_songs(rows: Sequence[dict[str, str]], seqs: Sequence[str], log: Callable[[str], None]) -> list[Song]:
    """Features of each song's whole audio (not only the danced span), from the feature cache if there."""
    style_of = {r["seq"]: r["style"] for r in rows}
    audio_of = {r["seq"]: r["audio"] for r in rows}
    songs = []
    for i, seq in enumerate(seqs):
        audio = Path(audio_of[seq])
        if not audio.is_file():
            raise DanceNetError(f"no audio for {seq} at {audio}")
        t = time.time()
        analysis = analyze_music(audio)
        log(f"[{i + 1}/{len(seqs)}] {seq} {style_of[seq]} {analysis.duration_s:.0f} s " f"({time.time() - t:.1f} s)")
        songs.append(Song(seq, style_of[seq], analysis))
    return songs


def transpose_chroma(x: np.ndarray, semitones: int) -> np.ndarray:
    """A copy of [T, 15] features in another key: the 12 chroma bins rolled, rhythm columns untouched. A key is
    no style cue, and with 4-5 songs of a style the net would otherwise learn their keys."""
    out = x.copy()
    out[:, CHROMA_COLS] = np.roll(x[:, CHROMA_COLS], semitones, axis=1)
    return out


def augment_window(song: MusicAnalysis, window: int, rng: np.random.Generator) -> np.ndarray:
    """A random training window of a song's classifier input: random offset, tempo x U(1 -+ AUG_TEMPO) (window
    * rate frames played back at `rate`; the beat and downbeat bumps are redrawn at the moved beat times, so
    they keep their height and beats per bar stay as they are), random key, a gain on the onset channel
    (activation heights differ between recordings more than between styles) and Gaussian noise; chroma is
    blanked with probability AUG_CHROMA_DROP so that the net cannot lean on harmony alone."""
    feats = song.features
    span = min(len(feats), int(round(window * rng.uniform(1 - AUG_TEMPO, 1 + AUG_TEMPO))))
    start = int(rng.integers(len(feats) - span + 1))
    x = transpose_chroma(_resample_frames(feats[start : start + span], window), int(rng.integers(12)))
    scale = (window - 1) / max(1, span - 1)  # source frame start + u lands on window frame u * scale
    for col, times in ((BEAT_COL, song.beat_times), (DOWNBEAT_COL, song.downbeat_times)):
        x[:, col] = bump_track((times * song.fps - start) * scale, window)
    x[:, ONSET_COL] *= rng.uniform(1 - AUG_GAIN, 1 + AUG_GAIN)
    if rng.random() < AUG_CHROMA_DROP:
        x[:, CHROMA_COLS] = 0.0
    return (x + AUG_NOISE * rng.standard_normal(x.shape)).astype(np.float32)


def _sample_batch(
    songs: Sequence[Song], styles: Sequence[str], window: int, batch: int, rng: np.random.Generator
) -> tuple[torch.Tensor, torch.Tensor]:
    """Style drawn uniformly (waltz has five times the songs of any other style), then a song of it and an
    augmented window."""
    by_style = [[s for s in songs if s.style == st] for st in styles]
    ys = rng.integers(len(styles), size=batch)
    xs = [augment_window(by_style[y][int(rng.integers(len(by_style[y])))].analysis, window, rng) for y in ys]
    return torch.from_numpy(np.stack(xs)), torch.from_numpy(ys)


def _resample_frames(x: np.ndarray, n: int) -> np.ndarray:
    """Linear interpolation of [T, F] frames to n frames, first and last aligned (a copy)."""
    if len(x) == n:
        return x.copy()
    src, dst = np.arange(len(x)), np.linspace(0, len(x) - 1, n)
    return np.stack([np.interp(dst, src, x[:, k]) for k in range(x.shape[1])], axis=1).astype(x.dtype)


def train_model(
    arch: str,
    train: Sequence[Song],
    styles: Sequence[str],
    *,
    steps: int,
    lr: float,
    batch: int,
    seed: int,
    log: Callable[[str], None],
    hidden: int = HIDDEN,
    dropout: float = DROPOUT,
    val: Sequence[Song] = (),
    eval_every: int = 25,
) -> StyleModel:
    """Adam with the supplement's schedule shape (lr / 10 at 60% and 83% of the steps). With `val` songs
    (training songs held out by song, never the test split) their balanced accuracy is logged every
    `eval_every` steps and kept in meta["validation"], to choose settings and the step count."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    window = int(WINDOW_S * FPS)
    config = {"hidden": hidden, "dropout": dropout}
    net = build_net(arch, len(styles), **config)
    model = StyleModel(net, arch, styles, config, {"fps": FPS, "window_s": WINDOW_S, "hop_s": HOP_S})
    opt = torch.optim.Adam(net.parameters(), lr=lr)
    sched = torch.optim.lr_scheduler.MultiStepLR(opt, [round(steps * 18 / 30), round(steps * 25 / 30)], 0.1)
    loss_fn = nn.CrossEntropyLoss()
    history = []
    total, correct, t0 = 0.0, 0, time.time()
    for step in range(1, steps + 1):
        net.train()
        x, y = _sample_batch(train, styles, window, batch, rng)
        logits = net(x)
        loss = loss_fn(logits, y)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        total += float(loss.detach()) * len(y)
        correct += int((logits.argmax(1) == y).sum())
        if step % eval_every == 0 or step == steps:
            n = eval_every if step % eval_every == 0 else step % eval_every
            line = f"{arch} step {step}/{steps} loss {total / (n * batch):.4f} acc {correct / (n * batch):.3f}"
            if val:
                m = evaluate(model.eval_mode(), val)
                bw, bs = _balanced(m["confusion_window"]), _balanced(m["confusion_song"])
                history.append({"step": step, "balanced_window": bw, "balanced_song": bs})
                line += f" | validation balanced: window {bw:.3f} song {bs:.3f}"
            log(f"{line} ({time.time() - t0:.0f} s)")
            total, correct = 0.0, 0
    if history:
        model.meta["validation"] = history
    return model.eval_mode()


def evaluate(model: StyleModel, songs: Sequence[Song]) -> dict:
    """Accuracy and confusion matrices (rows: truth, columns: prediction) by window and by song."""
    n = len(model.styles)
    by_window = np.zeros((n, n), dtype=int)
    by_song = np.zeros((n, n), dtype=int)
    predictions = {}
    for song in songs:
        truth = model.styles.index(song.style)
        result = model.classify(song.analysis)
        for p in np.argmax(result.window_probabilities, axis=1):
            by_window[truth, p] += 1
        by_song[truth, model.styles.index(result.style)] += 1
        predictions[song.seq] = {
            "truth": song.style,
            "predicted": result.style,
            "p_truth": round(float(result.probabilities[truth]), 3),
        }
    return {
        "window_accuracy": float(np.trace(by_window) / max(1, by_window.sum())),
        "song_accuracy": float(np.trace(by_song) / max(1, by_song.sum())),
        "windows": int(by_window.sum()),
        "songs": int(by_song.sum()),
        "confusion_window": by_window.tolist(),
        "confusion_song": by_song.tolist(),
        "predictions": predictions,
    }


def train_style(
    data_dir: str | Path,
    out_dir: str | Path,
    *,
    steps: int = STEPS,
    lr: float = LR,
    batch: int = BATCH,
    seed: int = SPLIT_SEED,
    split_path: str | Path | None = None,
    threads: int = 1,
    validate: bool = False,
    archs: Sequence[str] = ARCHS,
    log: Callable[[str], None] = print,
) -> dict:
    """Train the classifier and the baseline the same way on the same fixed song split; write both
    checkpoints, the split and a model card to out_dir; return the held-out metrics. With `validate`, the
    test songs are not even loaded: a validation split of the training songs (by song, stratified, as
    make_split) is held out instead, the models learn from the rest and are scored on it; nothing is
    shipped from such a run. One torch thread by default: on a small shared machine OpenMP threads that wait
    on each other cost more than they give."""
    data_dir, out_dir = Path(data_dir), Path(out_dir)
    rows = read_manifest(data_dir)
    split_file = Path(split_path) if split_path else out_dir / SPLIT_FILE.name
    split = load_or_make_split(split_file, rows, seed)
    styles = sorted({r["style"] for r in rows if r["seq"] in set(split["train"])})
    train_seqs, test_seqs = split["train"], split["test"]
    if validate:
        test_seqs = _validation_songs(split, rows)
        train_seqs = [s for s in train_seqs if s not in set(test_seqs)]
        log(f"validation songs (held out of training): {', '.join(test_seqs)}")
    train = load_songs(rows, train_seqs, log)
    test = load_songs(rows, test_seqs, log)
    torch.set_num_threads(threads)
    results = {}
    for arch in archs:
        t0 = time.time()
        model = train_model(
            arch, train, styles, steps=steps, lr=lr, batch=batch, seed=seed, log=log, val=test if validate else ()
        )
        metrics = evaluate(model, test)
        metrics["train"] = {k: v for k, v in evaluate(model, train).items() if k.endswith("accuracy")}
        metrics["train_seconds"] = round(time.time() - t0)
        results[arch] = metrics
        log(
            f"{arch}: {'validation' if validate else 'held-out'} window accuracy {metrics['window_accuracy']:.3f} "
            f"(balanced {_balanced(metrics['confusion_window']):.3f}), song accuracy "
            f"{metrics['song_accuracy']:.3f} (balanced {_balanced(metrics['confusion_song']):.3f})"
        )
        if validate:
            continue
        model.meta["training"] = {
            "steps": steps,
            "lr": lr,
            "batch": batch,
            "seed": seed,
            "split": split_file.name,
            "threads": threads,
            "metrics": metrics,
        }
        model.save(out_dir / {"conv": DEFAULT_WEIGHTS, "baseline": BASELINE_WEIGHTS}[arch].name)
    if not validate and set(archs) == set(ARCHS):
        write_model_card(data_dir, out_dir, split_file)
    return results


def write_model_card(data_dir: str | Path, out_dir: str | Path, split_path: str | Path | None = None) -> Path:
    """STYLE_MODEL_CARD.md in out_dir, from the two checkpoints' training metadata, the split and the
    manifest (so the card can be rewritten without retraining)."""
    out_dir = Path(out_dir)
    rows = read_manifest(Path(data_dir))
    split = json.loads(Path(split_path or out_dir / SPLIT_FILE.name).read_text())
    trained = {}
    for arch, path in (("conv", DEFAULT_WEIGHTS), ("baseline", BASELINE_WEIGHTS)):
        model = StyleModel.load(out_dir / path.name)
        if "metrics" not in model.meta.get("training", {}):
            raise DanceNetError(f"{out_dir / path.name} has no training metrics; retrain it with this version")
        trained[arch] = model
    card = out_dir / "STYLE_MODEL_CARD.md"
    write_text(card, model_card(trained["conv"], trained["baseline"], split, rows))
    return card


def _validation_songs(split: dict, rows: Sequence[dict[str, str]]) -> list[str]:
    """The training songs that `train --validate` holds out."""
    return make_split([r for r in rows if r["seq"] in set(split["train"])], split["seed"])["test"]


def _majority(m: list[list[int]]) -> float:
    """Accuracy of always answering the style with most test items (rows of confusion matrix m)."""
    return max(sum(r) for r in m) / max(1, sum(sum(r) for r in m))


def _balanced(m: list[list[int]]) -> float:
    """Mean recall over the styles present in the test set."""
    recalls = [r[i] / sum(r) for i, r in enumerate(m) if sum(r)]
    return sum(recalls) / max(1, len(recalls))


def model_card(conv: StyleModel, baseline: StyleModel, split: dict, rows: Sequence[dict[str, str]]) -> str:
    """Markdown summary of data, split, settings and held-out results of both models, like Table 2."""
    styles = conv.styles
    settings = conv.meta["training"]
    c, b = conv.meta["training"]["metrics"], baseline.meta["training"]["metrics"]
    style_of = {r["seq"]: r["style"] for r in rows}
    seconds = {r["seq"]: float(r["song_s"]) for r in rows}

    def count(seqs: Sequence[str], st: str) -> str:
        chosen = [s for s in seqs if style_of[s] == st]
        return f"{len(chosen)} ({sum(seconds[s] for s in chosen) / 60:.1f} min)"

    def confusion(m: list[list[int]]) -> list[str]:
        lines = ["| truth \\ predicted | " + " | ".join(styles) + " |", "|---" * (len(styles) + 1) + "|"]
        lines += [f"| {st} | " + " | ".join(str(v) for v in row) + " |" for st, row in zip(styles, m, strict=True)]
        return lines

    per_style = {st: [s for s in split["train"] if style_of[s] == st] for st in styles}
    common = max(styles, key=lambda st: len(per_style[st]))
    counts = sorted(len(v) for st, v in per_style.items() if st != common) or [0]
    few = str(counts[0]) if counts[0] == counts[-1] else f"{counts[0]}-{counts[-1]}"

    def minority(m: dict) -> str:
        rest = {s: p for s, p in m["predictions"].items() if p["truth"] != common}
        return f"{sum(p['predicted'] == p['truth'] for p in rest.values())} of {len(rest)} right"

    out = [
        "# Style classifier model card",
        "",
        "Musical style classifier of DanceNet (Zhuang et al. 2020, section 4.2), trained by "
        "`python -m dancenet_core.style train`. Files: `style_classifier.pt` (temporal conv + Bi-LSTM + FC), "
        "`style_baseline.pt` (FC + Bi-LSTM + FC, the paper's baseline), `song_split.json`.",
        "",
        "## Data",
        "",
        "Dance with Melody (Tang et al. 2018) songs, the whole audio of each (not only the danced span); "
        "research use only, no licence. Input: 15 channels at 10 fps in "
        f"{WINDOW_S:g}-second windows: the music features' deep chroma (12) and onset (1) (feature version "
        f"`{FEATURE_VERSION}`), and in place of their beat and downbeat activations a bump of height 1 (Gaussian, "
        f"sigma {BUMP_SIGMA_FRAMES:g} frame) at each beat and downbeat tracked by madmom's DBN (3 or 4 beats a "
        "bar); see below for why. No two sequences share a recording (checked by waveform cross-correlation).",
        "",
        "| style | train songs | test songs |",
        "|---|---|---|",
        *[f"| {st} | {count(split['train'], st)} | {count(split['test'], st)} |" for st in styles],
        "",
        f"Split by song, stratified by style, seed {split['seed']}: "
        f"round({split['test_fraction']} x n) songs of each style held out (at least one). Excluded:",
        "",
        *[f"- {s} ({style_of[s]}): {why}" for s, why in split["excluded"].items()],
        "",
        "## Training",
        "",
        f"Adam, learning rate {settings['lr']:g} divided by 10 at 60% and 83% of {settings['steps']} steps "
        f"(the supplement's schedule shape), batch {settings['batch']} windows, seed {settings['seed']}, "
        "cross-entropy; the last step is shipped. Each window: style drawn uniformly (waltz has most songs), "
        f"then a song and a random offset; played up to {100 * AUG_TEMPO:g}% faster or slower (chroma and "
        "onset resampled in time, the bumps redrawn at the moved beat times: beats per second change, beats "
        "per bar do not), transposed by a random number of semitones (chroma rolled), the onset channel times "
        f"a gain in [{1 - AUG_GAIN:g}, {1 + AUG_GAIN:g}], plus Gaussian noise (sigma {AUG_NOISE:g})"
        + (f"; chroma blanked in {100 * AUG_CHROMA_DROP:g}% of windows. " if AUG_CHROMA_DROP else ". ")
        + f"Both models: Bi-LSTM of {conv.config['hidden']} units each way, dropout {conv.config['dropout']:g}, "
        "mean over time, then FC; trained by the same code with the same settings.",
        "",
        "These settings were chosen with `train --validate`, which holds out training songs by song ("
        + ", ".join(_validation_songs(split, rows))
        + ") and never loads the test songs; the shipped models were then trained on all training songs.",
        "",
        "## What differs from the paper, and why",
        "",
        "- Architecture as in section 4.2 (three temporal conv layers, kernel 2, channels 1-16-24-32, then a "
        "Bi-LSTM and a fully connected layer; the baseline puts a per-frame fully connected layer in place of "
        "the convolutions), 30-second windows, cross-entropy.",
        "- Input: the paper feeds its music features as they are. Here the beat and downbeat activation "
        "channels are replaced by bumps at the DBN-tracked beats and downbeats. Sampled at 10 fps, madmom's "
        "100-fps activations miss many of their peaks (a training song's highest sampled beat value ranges "
        "0.24-0.93), so the metre and tempo that tell these ballroom styles apart (waltz 3 beats a bar at "
        "83-88 bpm; cha-cha 115-125 bpm; rumba mostly 88-95 bpm) came through blurred; the tracked beats "
        "carry them intact. On the validation songs, with the same settings, the balanced accuracy of ours by "
        f"window (by song) rose from {VALIDATION['activations']} to {VALIDATION['bumps']}; the baseline's with "
        f"bumps is {VALIDATION['baseline']}. DanceNet's own music input is unchanged.",
        f"- Tango (added with the extra data folder): with the same settings the balanced accuracy on the "
        f"validation songs is {VALIDATION_WITH_TANGO['200']} by window (by song) at 200 steps and "
        f"{VALIDATION_WITH_TANGO['400']} at 400: tango's songs (about 120-130 bpm, four beats a bar) are learnt, "
        "and cha-cha's, in the same tempo range, are taken for tango (see the confusion below). The style can "
        "always be chosen by hand (`--style`, the panel).",
        f"- Styles: the dance styles of the training data ({len(styles)} here) instead of the paper's two music "
        f"styles, and {sum(seconds[q] for q in split['train']) / 3600:.1f} hours of music instead of 35.7: hence "
        "the augmentation, the small Bi-LSTM "
        f"({conv.config['hidden']} units), dropout and the short schedule, all chosen on validation songs.",
        "",
        "## Held-out results",
        "",
        f"Windows every {HOP_S:g} s over each test song ({c['windows']} windows, {c['songs']} songs); "
        "a song's style is the mean of its windows' probabilities.",
        "",
        "Balanced accuracy is the mean of the per-style recalls: the fairer number with this many waltzes, "
        f"since always answering the most common style scores {100 / len(styles):.1f}% on it.",
        "",
        "| method | window accuracy | balanced, by window | song accuracy | balanced, by song "
        "| train window accuracy | training time |",
        "|---|---|---|---|---|---|---|",
        f"| Always the most common style | {100 * _majority(c['confusion_window']):.1f}% "
        f"| {100 / len(styles):.1f}% | {100 * _majority(c['confusion_song']):.1f}% | {100 / len(styles):.1f}% "
        "| - | - |",
        *[
            f"| {name} | {100 * m['window_accuracy']:.1f}% | {100 * _balanced(m['confusion_window']):.1f}% "
            f"| {100 * m['song_accuracy']:.1f}% | {100 * _balanced(m['confusion_song']):.1f}% "
            f"| {100 * m['train']['window_accuracy']:.1f}% | {m['train_seconds']} s |"
            for name, m in (("Baseline (FC + Bi-LSTM)", b), ("Ours (Temporal Conv + Bi-LSTM)", c))
        ],
        "",
        "The paper's Table 2 (its own 35.7 h of music, two styles, accuracy): baseline 88.0%, ours 92.1%. With "
        f"{len(split['test'])} test songs here, one song is {100 / max(1, len(split['test'])):.1f} points "
        "of song accuracy: the numbers are indicative only.",
        "",
        "### Confusion by window, ours",
        "",
        *confusion(c["confusion_window"]),
        "",
        "### Confusion by window, baseline",
        "",
        *confusion(b["confusion_window"]),
        "",
        "### By song",
        "",
        "| song | truth | ours | baseline |",
        "|---|---|---|---|",
        *[
            f"| {s} | {p['truth']} | {p['predicted']} ({p['p_truth']:.2f}) "
            f"| {b['predictions'][s]['predicted']} ({b['predictions'][s]['p_truth']:.2f}) |"
            for s, p in c["predictions"].items()
        ],
        "",
        "(In brackets: the probability given to the true style.)",
        "",
        "## Limits",
        "",
        f"Held-out songs of the styles other than {common}: ours gets {minority(c)}, the baseline "
        f"{minority(b)}. Ballroom styles differ mostly in tempo and metre, which the beat and downbeat "
        f"channels carry, but the models have learnt from {few} songs per style apart from {common} and "
        "fit their training songs far better than new ones: treat the style as a suggestion that the user "
        "can override. The models know only the styles listed above. Rumba and cha-cha are both 4 beats a bar "
        "and told apart mostly by tempo: a rumba whose beat is tracked at cha-cha tempo (as that of the test "
        "rumba here, 130 bpm; two training rumbas are tracked at 120 and 188 bpm) is taken for a cha-cha.",
        "",
    ]
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m dancenet_core.style", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    t = sub.add_parser("train", help="train the classifier and the baseline on a fixed song split")
    c = sub.add_parser("card", help="rewrite STYLE_MODEL_CARD.md from trained checkpoints")
    for p in (t, c):
        p.add_argument("--data", required=True, help="folder with manifest.csv and the songs")
        p.add_argument("--out", required=True, help="folder of the checkpoints, split and model card")
        p.add_argument("--split", help="split file (reused if it exists; default OUT/song_split.json)")
    t.add_argument("--steps", type=int, default=STEPS)
    t.add_argument("--lr", type=float, default=LR)
    t.add_argument("--batch", type=int, default=BATCH)
    t.add_argument("--seed", type=int, default=SPLIT_SEED)
    t.add_argument("--threads", type=int, default=1, help="torch threads")
    t.add_argument("--arch", choices=ARCHS, action="append", help="train only this model (repeatable)")
    t.add_argument(
        "--validate",
        action="store_true",
        help="hold out training songs by song instead of the test songs, to choose settings; ships nothing",
    )
    args = parser.parse_args(argv)
    try:
        if args.command == "card":
            print(write_model_card(args.data, args.out, args.split))
            return 0
        results = train_style(
            args.data,
            args.out,
            steps=args.steps,
            lr=args.lr,
            batch=args.batch,
            seed=args.seed,
            split_path=args.split,
            threads=args.threads,
            validate=args.validate,
            archs=args.arch or ARCHS,
            log=lambda m: print(m, flush=True),
        )
    except DanceNetError as e:
        print(f"dancenet: error: {e}", file=sys.stderr)
        return 2
    print(json.dumps({k: {m: v[m] for m in ("window_accuracy", "song_accuracy")} for k, v in results.items()}))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Training of the musical style classifier and its baseline (`dancenet train style`) on the Dance with Melody
songs, with the augmentation that lets them learn from a few songs per style; the model card is
`training/cards.py`."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from ..data.dance_with_melody import Recording, read_manifest
from ..data.split import SPLIT_FILE, load_or_make_split, validation_songs
from ..environment import default_data_dir
from ..errors import DanceNetError
from ..evaluation.metrics import balanced_accuracy
from ..music.features import CHROMA_COLS, FPS, N_FEATURES, ONSET_COL, MusicAnalysis, analyze_music
from ..music.style import (
    BASELINE_WEIGHTS,
    DEFAULT_WEIGHTS,
    DROPOUT,
    HIDDEN,
    HOP_S,
    N_INPUTS,
    WINDOW_S,
    draw_rhythm,
)
from ..nets.export import style_to_runtime
from ..nets.style_torch import StyleModel, build_net
from ..series import stretch_frames
from .configs import StyleSettings

# Settings chosen on training songs held out by song (`validate`), never on the test split.
# Training windows are played up to this much faster or slower. With the tempo an input, none: the
# tempos that tell cha-cha (115-125 bpm) from tango (125-128) are within any stretch (VALIDATION_METER_TEMPO).
AUG_TEMPO = 0.0

AUG_GAIN = 0.4  # on the onset channel; the beat and downbeat bumps have a fixed height

AUG_NOISE = 0.02

# Validation (conv, 7 training songs held out), sampled activations as input: balanced window accuracy 0.72 after
# 200 steps with chroma blanked in half the windows, 0.54-0.70 over 100-300 steps without (training accuracy 0.84 vs
# 0.93: harmony gets memorised).
AUG_CHROMA_DROP = 0.5

# `train --validate`, 200 steps: balanced accuracy by window (by song) of the conv model with the sampled beat and
# downbeat activations as input (the previous input) and with DBN bumps (this one), and of the baseline with bumps.
VALIDATION = {"activations": "0.72 (0.60)", "bumps": "0.88 (1.00)", "baseline": "0.70 (0.67)"}

# The same, with tango (the extra folder) as a fourth style: 200 steps and 400 steps.
VALIDATION_WITH_TANGO = {"200": "0.55 (0.50)", "400": "0.50 (0.50)"}

# `train --validate` with beats per bar and tempo as input columns, conv model: balanced accuracy by
# window (by song), chroma blanked in half the windows unless said; several runs (training seeds 2020 and 1; the
# stretched ones also on a 16-core machine's CPU) give their range.
VALIDATION_METER_TEMPO = {
    "bumps only (no metre and tempo columns), stretch 12%, 200 steps": "0.50 (0.50)",
    "stretch 12%, 200 steps": "0.50-0.51 (0.50)",
    "stretch 12%, 400 steps": "0.50 (0.50)",
    "stretch 12%, chroma never blanked, 200 steps": "0.50 (0.50)",
    "stretch 8%, 200 steps": "0.50 (0.50)",
    "stretch 4%, 200 steps": "0.50-0.51 (0.50)",
    "stretch 4%, 400 steps": "0.50 (0.50)",
    "stretch 4%, chroma never blanked, 200 steps": "0.50 (0.50)",
    "stretch 4%, chroma blanked in 80%, 200 steps": "0.52 (0.50)",
    "no stretch, 200 steps": "0.59-0.68 (0.50-0.75)",
    "no stretch, chroma never blanked, 200 steps": "0.60 (0.50)",
    "no stretch, 400 steps (shipped)": "0.65-0.75 (0.75)",
    "no stretch, 600 steps": "0.68 (0.75)",
}


@dataclass
class Song:
    seq: str
    style: str
    analysis: MusicAnalysis

def load_songs(rows: Sequence[Recording], seqs: Sequence[str], log: Callable[[str], None]) -> list[Song]:
    """Features of each song's whole audio (not only the danced span), from the feature cache if there."""
    style_of = {r.seq: r.style for r in rows}
    audio_of = {r.seq: r.audio for r in rows}
    songs = []
    for i, seq in enumerate(seqs):
        audio = audio_of[seq]
        if not audio.is_file():
            raise DanceNetError(f"no audio for {seq} at {audio}")
        t = time.time()
        analysis = analyze_music(audio)
        log(f"[{i + 1}/{len(seqs)}] {seq} {style_of[seq]} {analysis.duration_s:.0f} s " f"({time.time() - t:.1f} s)")
        songs.append(Song(seq, style_of[seq], analysis))
    return songs

def transpose_chroma(x: np.ndarray, semitones: int) -> np.ndarray:
    """A copy of [T, >= N_FEATURES] features in another key: the chroma bins rolled, rhythm columns untouched. A key is
    no style cue, and with 4-5 songs of a style the net would otherwise learn their keys."""
    out = x.copy()
    out[:, CHROMA_COLS] = np.roll(x[:, CHROMA_COLS], semitones, axis=1)
    return out

def augment_window(song: MusicAnalysis, window: int, rng: np.random.Generator) -> np.ndarray:
    """A random training window of a song's classifier input: random offset, tempo x U(1 -+ AUG_TEMPO) (window
    * rate frames played back at `rate`; the beat and downbeat bumps, beats per bar and tempo are redrawn from
    the moved beat times, so the bumps keep their height, beats per bar stay as they are and the tempo column
    reads the tempo played), random key, a gain on the onset channel
    (activation heights differ between recordings more than between styles) and Gaussian noise; chroma is
    blanked with probability AUG_CHROMA_DROP so that the net cannot lean on harmony alone."""
    feats = song.features
    span = min(len(feats), int(round(window * rng.uniform(1 - AUG_TEMPO, 1 + AUG_TEMPO))))
    start = int(rng.integers(len(feats) - span + 1))
    x = np.zeros((window, N_INPUTS), np.float32)
    x[:, :N_FEATURES] = transpose_chroma(stretch_frames(feats[start : start + span], window), int(rng.integers(12)))
    scale = (window - 1) / max(1, span - 1)  # source frame start + u lands on window frame u * scale
    draw_rhythm(x, (song.beat_times * song.fps - start) * scale, (song.downbeat_times * song.fps - start) * scale,
                song.fps)
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

def train_style_net(
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
    config = {"hidden": hidden, "dropout": dropout, "inputs": N_INPUTS}
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
                m = score_songs(model.eval_mode(), val)
                bw, bs = balanced_accuracy(m["confusion_window"]), balanced_accuracy(m["confusion_song"])
                history.append({"step": step, "balanced_window": bw, "balanced_song": bs})
                line += f" | validation balanced: window {bw:.3f} song {bs:.3f}"
            log(f"{line} ({time.time() - t0:.0f} s)")
            total, correct = 0.0, 0
    if history:
        model.meta["validation"] = history
    return model.eval_mode()

def score_songs(model: StyleModel, songs: Sequence[Song]) -> dict:
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

def train_style(settings: StyleSettings, log: Callable[[str], None] = print) -> dict:
    """Train the classifier and the baseline the same way on the same fixed song split; write both
    checkpoints and the split to `settings.out`; return the held-out metrics. With `validate`, the
    test songs are not even loaded: a validation split of the training songs (by song, stratified, as
    make_split) is held out instead, the models learn from the rest and are scored on it; nothing is
    shipped from such a run. One torch thread by default: on a small shared machine OpenMP threads that wait
    on each other cost more than they give."""
    data_dir, out_dir, seed = settings.data or default_data_dir(), settings.out, settings.seed
    steps, lr, batch, validate = settings.steps, settings.lr, settings.batch, settings.validate
    rows = read_manifest(data_dir)
    split_file = settings.split or out_dir / SPLIT_FILE.name
    split = load_or_make_split(split_file, rows, seed)
    styles = sorted({r.style for r in rows if r.seq in set(split["train"])})
    train_seqs, test_seqs = split["train"], split["test"]
    if validate:
        test_seqs = validation_songs(split, rows)
        train_seqs = [s for s in train_seqs if s not in set(test_seqs)]
        log(f"validation songs (held out of training): {', '.join(test_seqs)}")
    train = load_songs(rows, train_seqs, log)
    test = load_songs(rows, test_seqs, log)
    torch.set_num_threads(settings.threads)
    results = {}
    for arch in settings.arch:
        t0 = time.time()
        model = train_style_net(
            arch, train, styles, steps=steps, lr=lr, batch=batch, seed=seed, log=log, val=test if validate else ()
        )
        metrics = score_songs(model, test)
        metrics["train"] = {k: v for k, v in score_songs(model, train).items() if k.endswith("accuracy")}
        metrics["train_seconds"] = round(time.time() - t0)
        results[arch] = metrics
        log(
            f"{arch}: {'validation' if validate else 'held-out'} window accuracy {metrics['window_accuracy']:.3f} "
            f"(balanced {balanced_accuracy(metrics['confusion_window']):.3f}), song accuracy "
            f"{metrics['song_accuracy']:.3f} (balanced {balanced_accuracy(metrics['confusion_song']):.3f})"
        )
        if validate:
            continue
        model.meta["training"] = {
            "steps": steps,
            "lr": lr,
            "batch": batch,
            "seed": seed,
            "split": split_file.name,
            "threads": settings.threads,
            "metrics": metrics,
        }
        path = out_dir / {"conv": DEFAULT_WEIGHTS, "baseline": BASELINE_WEIGHTS}[arch].name
        model.save(path)
        if arch == "conv":  # what generation runs, without torch
            style_to_runtime(model).save(path.with_suffix(".npz"))
    return results

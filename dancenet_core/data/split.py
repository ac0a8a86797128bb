"""The song split (`weights/song_split.json`): which sequences train, which test, which validate, by song and
stratified by style, so no test song's music is ever learnt. Fixed once written; new data is placed
without moving anything already placed."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..atomic import write_text
from ..environment import WEIGHTS_DIR
from ..errors import DanceNetError
from .dance_with_melody import Recording

SPLIT_FILE = WEIGHTS_DIR / "song_split.json"
SPLIT_SEED = 2020

TEST_FRACTION = 0.2


def load_split(path: Path = SPLIT_FILE) -> dict:
    if not path.is_file():
        raise DanceNetError(f"song split {path} is missing; it ships with the package (reinstall)")
    return json.loads(path.read_text())


def make_split(rows: Sequence[Recording], seed: int = SPLIT_SEED, test_fraction: float = TEST_FRACTION) -> dict:
    """By song, stratified by style: round(test_fraction * n) songs of each style (at least one) are held
    out. A style with a single song can't be both learnt and tested, so it is excluded, with the reason."""
    rng = np.random.default_rng(seed)
    by_style: dict[str, list[str]] = {}
    for r in rows:
        by_style.setdefault(r.style, []).append(r.seq)
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

def extend_split(split: dict, rows: Sequence[Recording], excluded: dict[str, str]) -> dict:
    """The split with sequences it has not seen placed by the same by-song rule, nothing already placed moved.

    A new sequence of a style the split already holds trains (the test songs stay as they were); a new
    style's songs are split as `make_split` does, keeping sequences danced to one song on the same side.
    `excluded` names sequences to leave out, with the reason (e.g. data found to be unusable).
    """
    placed = set(split["train"]) | set(split["test"]) | set(split["excluded"])
    new = [r for r in rows if r.seq not in placed]
    out = {k: (dict(v) if isinstance(v, dict) else list(v) if isinstance(v, list) else v) for k, v in split.items()}
    out["excluded"].update({s: why for s, why in excluded.items() if s not in placed or s in split["excluded"]})
    for s in excluded:
        for side in ("train", "test"):
            if s in out[side]:
                out[side].remove(s)
    new = [r for r in new if r.seq not in excluded]
    known = {r.style for r in rows if r.seq in set(out["train"])}
    out["train"] += [r.seq for r in new if r.style in known]
    rng = np.random.default_rng(split["seed"])
    for style in sorted({r.style for r in new} - known):
        songs: dict[str, list[str]] = {}
        for r in sorted((r for r in new if r.style == style), key=lambda r: _seq_order(r.seq)):
            songs.setdefault(r.song, []).append(r.seq)
        keys = list(songs)
        n_test = max(1, int(round(split["test_fraction"] * len(keys))))
        test = set(rng.permutation(keys)[:n_test].tolist())
        out["test"] += [s for k in keys if k in test for s in songs[k]]
        out["train"] += [s for k in keys if k not in test for s in songs[k]]
    return out

def load_or_make_split(path: Path, rows: Sequence[Recording], seed: int) -> dict:
    """The split is fixed once written: later runs (and the dance model) reuse the same file."""
    if path.is_file():
        split = json.loads(path.read_text())
        known = {r.seq for r in rows}
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

def validation_songs(split: dict, rows: Sequence[Recording]) -> list[str]:
    """The training songs that `train --validate` holds out."""
    return make_split([r for r in rows if r.seq in set(split["train"])], split["seed"])["test"]

"""How much the dances follow their own music, printed as JSON: (1) the real dancers' BAS against their own song's
beats over their BAS against the other songs' beats, by part of the song split and by alignment folder; (2) for each
DanceNet weights file given, the held-out NLL on the validation windows with each window's own music and with
another window's (rolled across the batch), the input frames whole or a quarter of them hidden in stretches of 12.

    .venv/bin/python scripts/music_control.py [WEIGHTS.pt ...]

Why: a model can only learn to follow the beat that its training pairs show, and a model that ignores its music
predicts as well with another song's.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import torch

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from dancenet_core.data.dance_with_melody import read_manifest  # noqa: E402
from dancenet_core.environment import default_data_dir  # noqa: E402
from dancenet_core.evaluation.metrics import own_song_bas_ratio  # noqa: E402
from dancenet_core.evaluation.test_split import split_with_beats  # noqa: E402
from dancenet_core.nets.bundle import DanceNetBundle  # noqa: E402
from dancenet_core.representation import FeatureLayout  # noqa: E402
from dancenet_core.training.dancenet import held_out_windows, hide_history  # noqa: E402


def real_ratios() -> dict:
    data = default_data_dir()
    alignment = {s.seq: s.alignment for s in read_manifest(data)}
    out = {}
    for part in ("train", "validation", "test"):
        split, pairs, beats = split_with_beats(data, part=part)
        ids = [s for s in split[part] if s in pairs]
        out[part] = {"songs": len(ids), "ratio": own_song_bas_ratio([pairs[s].positions for s in ids], 25.0,
                                                                    [beats[s] for s in ids])}
        for folder in sorted({alignment[s] for s in ids}):
            sub = [s for s in ids if alignment[s] == folder]
            out[part][f"{folder} ({len(sub)} songs)"] = own_song_bas_ratio(
                [pairs[s].positions for s in sub], 25.0, [beats[s] for s in sub])
    return out


def music_swap(path: str) -> dict:
    torch.manual_seed(0)
    split, pairs, _ = split_with_beats(default_data_dir(), part="validation")
    bundle = DanceNetBundle.load(path)
    model = bundle.model.eval()
    w = held_out_windows([pairs[s] for s in split["validation"]], bundle.normalizer, bundle.styles,
                         FeatureLayout(55, 5), 200, 0)
    x, music, style, target = (torch.tensor(a) for a in (w.motion, w.music, w.style, w.target))
    out = {}
    with torch.no_grad():
        for hidden in (0.0, 0.25):
            frames = hide_history(x, hidden, 12) if hidden else x
            for name, m in (("own music", music), ("other music", torch.roll(music, 7, 0))):
                nll = model.loss(model(frames, m, style), target[:, 1:], m[:, 1:])[1]["nll"]
                out[f"{name}, {hidden:.0%} of frames hidden"] = round(float(nll), 4)
    return out


def main() -> None:
    print(json.dumps({"real_dances_bas_own_over_other": real_ratios(),
                      "held_out_nll": {p: music_swap(p) for p in sys.argv[1:]}}, indent=1))


if __name__ == "__main__":
    main()

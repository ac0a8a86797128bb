"""Training of the match of music and movement (training/match.py) on made-up bars: it learns a pairing, and the
numpy scorer the engine runs gives the trained networks' embeddings."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from dancenet_core.library.match import MatchModel  # noqa: E402
from dancenet_core.training.configs import MatchSettings  # noqa: E402
from dancenet_core.training.match import SongBars, retrieval, style_transfer, train_match  # noqa: E402


def made_up_songs(n_songs: int = 8, bars: int = 40, seed: int = 0) -> list[SongBars]:
    """Songs of two styles whose music and motion bars share a hidden code (plus noise), the style shifting both."""
    rng = np.random.default_rng(seed)
    mix_music, mix_motion = rng.normal(size=(6, 20)), rng.normal(size=(6, 30))
    songs = []
    for k in range(n_songs):
        style = ("a", "b")[k % 2]
        code = rng.normal(size=(bars, 6)) + (2.0 if style == "b" else -2.0)
        motion = code @ mix_motion + 0.3 * rng.normal(size=(bars, 30))
        songs.append(SongBars(f"s{k}", style, (code @ mix_music + 0.3 * rng.normal(size=(bars, 20))).astype(np.float32),
                              motion.astype(np.float32), motion[:, ::-1].copy().astype(np.float32),
                              rng.random(bars), rng.random(bars)))
    return songs


def test_training_learns_the_pairing_and_the_scorer_agrees(tmp_path: Path) -> None:
    train = made_up_songs(seed=0)
    settings = MatchSettings(steps=300, context=0, dropout=0.0, noise=0.0)
    model, curve = train_match(train, settings, log=lambda _m: None)
    assert curve[-1] < 0.6 * curve[0]
    model.save(tmp_path / "m.npz")
    back = MatchModel.load(tmp_path / "m.npz")
    assert back.meta["steps"] == 300 and back.context == 0
    held = made_up_songs(12, seed=0)[8:]  # songs not trained on, made the same way
    r = retrieval(back, held, candidates=16)
    assert r["top1"] > 3 / 16 and r["top5"] > 0.6
    assert style_transfer(back, held, train)["style_mean"] > 0.9


def test_the_train_command_writes_weights_and_card(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                   capsys: pytest.CaptureFixture) -> None:
    """`dancenet train match` from the command line to the weights and their card (made-up bars stand in for the
    paired capture)."""
    from dancenet_core.cli import main
    from dancenet_core.training import match

    songs = made_up_songs(12)
    monkeypatch.setattr(match, "load_bars", lambda context: {s.seq: s for s in songs})
    monkeypatch.setattr(match, "split_songs", lambda bars: (songs[:8], songs[8:10], songs[10:]))
    out = tmp_path / "weights" / "match.npz"
    out.parent.mkdir()
    assert main(["train", "match", "--out", str(out), "--steps", "30", "--context", "0"]) == 0
    assert "test songs: retrieval top-1" in capsys.readouterr().out
    model = MatchModel.load(out)
    assert model.meta["figures"]["held_out_songs"] == ["s10", "s11"]
    card = (out.parent / "MATCH_MODEL_CARD.md").read_text()
    assert "| learned match |" in card and "s10, s11" in card
    assert main(["train", "match", "--validate", "--out", str(tmp_path / "v.npz"), "--steps", "30",
                 "--context", "0"]) == 0
    assert MatchModel.load(tmp_path / "v.npz").meta["figures"]["held_out_songs"] == ["s8", "s9"]
    assert (tmp_path / "v_card.md").is_file()

"""Training of the music style classifier: it learns a separable toy problem, its augmentation keeps rhythm
and beats, and the model card reads the stored metrics."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from made_up import analysis, clicks, peak_frames, peaks

from dancenet_core.data.dance_with_melody import Recording
from dancenet_core.music.style import METER_COL, N_INPUTS, TEMPO_COL
from dancenet_core.training.cards import style_card
from dancenet_core.training.style import AUG_TEMPO, Song, augment_window, score_songs, train_style_net, transpose_chroma

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def test_training_learns_a_separable_toy_problem() -> None:
    rng = np.random.default_rng(0)
    songs = [
        Song(f"s{i}", style, analysis(rng.random((330, 15), dtype=np.float32) * 0.2 + 0.8 * (style == "b")))
        for i, style in enumerate(["a", "b"] * 3)
    ]
    model = train_style_net(
        "conv", songs, ["a", "b"], steps=40, lr=3e-3, batch=8, seed=0, log=lambda _m: None, val=songs[:2], eval_every=20
    )
    assert [h["step"] for h in model.meta["validation"]] == [20, 40]
    assert not model.net.training
    metrics = score_songs(model, songs)
    assert metrics["song_accuracy"] == 1.0
    assert metrics["songs"] == 6
    assert np.array(metrics["confusion_song"]).sum() == 6
    metrics.update(train={"window_accuracy": 1.0}, train_seconds=1)
    model.meta["training"] = {"steps": 40, "lr": 3e-3, "batch": 8, "seed": 0, "metrics": metrics}
    rows = [Recording(s.seq, s.style, 0, 25.0, 0.0, Path(), Path(), song_s=33.0) for s in songs]
    split = {
        "seed": 0,
        "test_fraction": 0.5,
        "train": ["s0", "s1", "s2", "s3"],
        "test": ["s4", "s5"],
        "excluded": {"s5": "a reason"},
    }
    card = style_card(model, model, split, rows)
    assert "| Ours (Temporal Conv + Bi-LSTM) | 100.0% | 100.0% | 100.0% | 100.0% | 100.0% | 1 s |" in card
    assert "| Always the most common style | 50.0% | 50.0% | 50.0% | 50.0% | - | - |" in card
    assert "ours gets 3 of 3 right" in card
    assert "- s5 (b): a reason" in card


def test_transposing_by_an_octave_is_the_identity_and_leaves_rhythm_alone() -> None:
    x = clicks(100, 5, 3)
    np.testing.assert_array_equal(transpose_chroma(x, 12), x)
    y = transpose_chroma(x, 2)
    np.testing.assert_array_equal(y[:, 2], x[:, 0])
    np.testing.assert_array_equal(y[:, 12:], x[:, 12:])
    np.testing.assert_array_equal(transpose_chroma(y, 10), x)


def test_augmented_windows_redraw_the_tracked_beats() -> None:
    """Windows of a 3/4 song at 60 bpm: the bumps come from the tracked beats (the sampled activations are
    zeroed here), at full height; tempo stretch moves them and the tempo column reads the tempo played (from
    the bumps' spacing), while the metre column stays at 3 beats a bar."""
    rng = np.random.default_rng(0)
    feats = clicks(900, 10, 3)
    feats[:, 12:14] = 0.0
    song = analysis(feats, beat_s=1.0, bar=3)
    tempos = []
    for _ in range(20):
        w = augment_window(song, 300, rng)
        assert w.shape == (300, N_INPUTS)
        assert w.dtype == np.float32
        beats, downbeats = peaks(w[:, 12]), peaks(w[:, 13])
        assert 30 * (1 - AUG_TEMPO) - 2 <= beats <= 30 * (1 + AUG_TEMPO) + 2
        assert beats / max(1, downbeats) == pytest.approx(3, abs=0.5)
        assert w[:, 12].max() > 0.8
        assert w[:, 13].max() > 0.8
        assert np.abs(w[:, METER_COL]).max() < 0.1  # 3 beats a bar (noise only)
        spacing = np.diff(peak_frames(w[:, 12])).mean()
        assert w[:, TEMPO_COL].mean() == pytest.approx(np.log2(600 / spacing / 120), abs=0.03)
        tempos.append(w[:, TEMPO_COL].mean())
    assert 2 ** (max(tempos) - min(tempos)) >= 1 + AUG_TEMPO

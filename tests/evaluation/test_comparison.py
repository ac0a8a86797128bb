"""The comparison's models (DanceNet, its ablations, the paper's baselines) and its segmenting."""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from scipy.spatial.distance import pdist

from dancenet_core.errors import DanceNetError
from dancenet_core.evaluation import comparison
from dancenet_core.evaluation.comparison import DanceSet, measure, reference_features, segments
from dancenet_core.motion import Motion
from dancenet_core.nets.variants import VARIANTS, build_model, sample_normalized
from dancenet_core.representation import FeatureLayout

LAYOUT = FeatureLayout(55, 5)


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_every_model_learns_a_window_and_dances(variant: str) -> None:
    """Each model fits one fixed batch (its loss falls by half) and then dances any length of music."""
    torch.manual_seed(0)
    model = build_model(variant, LAYOUT.size, LAYOUT.continuous.stop, ["a", "b"], window=64)
    rng = np.random.default_rng(0)
    t = np.linspace(0, 4 * np.pi, 48)
    motion = np.sin(t[None, :, None] + rng.uniform(0, 6, (2, 1, LAYOUT.size))).astype(np.float32)
    motion[..., LAYOUT.contacts] = (motion[..., LAYOUT.contacts] > 0).astype(np.float32)
    music = rng.normal(size=(2, 48, model.cfg.music_dim)).astype(np.float32)
    x, m, s = torch.tensor(motion), torch.tensor(music), torch.tensor([0, 1])
    opt = torch.optim.Adam(model.parameters(), lr=2e-3)
    losses = []
    for _ in range(40):
        loss, _ = model.loss(model(x, m, s), x[:, 1:], m[:, 1:])
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    assert losses[-1] < losses[0] - 0.5 * abs(losses[0]), (variant, losses[0], losses[-1])

    model.eval()
    song = rng.normal(size=(150, model.cfg.music_dim)).astype(np.float32)
    a = sample_normalized(model, song, 1, motion[0, 0], 0.1, np.random.default_rng(3))
    b = sample_normalized(model, song, 1, motion[0, 0], 0.1, np.random.default_rng(3))
    assert a.shape == (150, LAYOUT.size)
    assert np.isfinite(a).all()
    assert np.array_equal(a, b)  # same seed, same dance
    assert set(np.unique(a[1:, LAYOUT.contacts])) <= {0.0, 1.0}


def test_mse_models_dance_their_mean_whatever_the_temperature() -> None:
    model = build_model("dancenet_mse", LAYOUT.size, LAYOUT.continuous.stop, ["a"], window=64).eval()
    song = np.random.default_rng(0).normal(size=(30, 15)).astype(np.float32)
    first = np.zeros(LAYOUT.size, np.float32)
    hot = sample_normalized(model, song, 0, first, 5.0, np.random.default_rng(1))
    cold = sample_normalized(model, song, 0, first, 0.0, np.random.default_rng(2))
    np.testing.assert_array_equal(hot, cold)


def test_segments_are_whole_and_do_not_overlap() -> None:
    pos = np.arange(26 * 10 * 3 * 2, dtype=float).reshape(-1, 2, 3)  # 260 frames
    segs = segments(pos, fps=25.0, seconds=4.0)
    assert [len(s) for s in segs] == [100, 100]  # the 60-frame tail is dropped
    np.testing.assert_array_equal(segs[1][0], pos[100])


class _OneStyleNet:
    """A style classifier stand-in that names every segment 'waltz' and embeds it by its mean height."""

    styles = ["rumba", "waltz"]

    def describe(self, seg: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
        return np.array([seg[..., 1].mean(), seg[..., 0].std()]), np.array([0.1, 0.9])


def _dance(seed: int, frames: int = 500) -> Motion:
    from dancenet_core.skeleton import DEFAULT_SKELETON

    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None, None] / 25.0
    rot = 0.3 * np.sin(2 * np.pi * rng.uniform(0.5, 2, (1, 55, 3)) * t + rng.uniform(0, 6, (1, 55, 3)))
    root = np.stack([np.sin(t[:, 0, 0]), 0.9 + 0.02 * np.cos(3 * t[:, 0, 0]), 0.1 * t[:, 0, 0]], -1)
    return Motion(rot, root, 25.0, DEFAULT_SKELETON)


def test_identical_sets_score_fid_zero_and_style_consistency_counts_named_segments() -> None:
    dances = [_dance(s) for s in range(4)]
    row = DanceSet("x", "x", dances, ["waltz", "waltz", "rumba", "waltz"], [np.arange(0, 20, 0.5)] * 4)
    net = _OneStyleNet()
    reference = reference_features([m.positions() for m in dances], 25.0, net)
    r = measure([row], reference, 25.0, net)["x"]
    assert r["replay_m"] == pytest.approx(0, abs=1e-6)  # the dances are their own training data
    assert r["segments"] == 8  # two whole 10-s segments per 20-s dance
    assert r["fid_k"] == pytest.approx(0, abs=1e-4)
    assert r["fid_g"] == pytest.approx(0, abs=1e-4)
    assert r["fid_style"] == pytest.approx(0, abs=1e-4)
    assert r["style_consistency"] == pytest.approx(6 / 8)  # the rumba's two segments are called waltz
    kinetic = reference["k"][:, reference["k"].std(axis=0) > 1e-6].astype(np.float64)
    standard = (kinetic - kinetic.mean(axis=0)) / kinetic.std(axis=0)
    assert r["div_k"] == pytest.approx(pdist(standard).mean(), rel=1e-4)  # Bailando's, in the reference's units
    assert r["joint_speed_m_s"] > 0
    assert r["root_extent_m"] > 0.5


def test_replay_distance_tells_a_copy_from_a_new_dance() -> None:
    from dancenet_core.evaluation.metrics import body_relative_segments, nearest_segment_distance

    train = _dance(0, 1000).positions()
    library = body_relative_segments(train, 25.0, hop_s=0.04)
    moved = train[200:450] + np.array([3.0, 0.0, -2.0])  # the same 10 s somewhere else on the floor
    copy = nearest_segment_distance(body_relative_segments(moved, 25.0, hop_s=1.0), library)
    new = nearest_segment_distance(body_relative_segments(_dance(7, 250).positions(), 25.0, hop_s=1.0), library)
    assert copy.max() < 1e-6
    assert new.min() > 0.02


FAKE_PYTHON = """#!/bin/sh
case "$*" in
  *"--variant bad"*) echo "training failed" >&2; exit 3 ;;
  *) echo $$ > "$PID_FILE"; exec sleep 60 ;;
esac
"""


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="needs Linux /proc")
def test_a_failed_training_stops_the_others_and_closes_their_logs(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """Two models train at once; one fails: the command says which, and the other's training is stopped (not
    left running for hours) and every log file is closed."""
    python = tmp_path / "python"
    python.write_text(FAKE_PYTHON)
    python.chmod(0o755)
    monkeypatch.setattr(sys, "executable", str(python))
    monkeypatch.setenv("PID_FILE", str(tmp_path / "slow.pid"))
    monkeypatch.setattr(comparison, "POLL_S", 0.1, raising=False)
    with pytest.raises(DanceNetError, match="training bad failed"):
        comparison.train_variants(["slow", "bad"], tmp_path / "runs", steps=10, seed=0, jobs=2, data=None)
    slow = int((tmp_path / "slow.pid").read_text())
    stat = Path(f"/proc/{slow}/stat")
    alive = stat.is_file() and stat.read_text().rsplit(")", 1)[1].split()[0] != "Z"
    if alive:  # end it, so a failure here leaves nothing running
        os.kill(slow, signal.SIGKILL)
    assert not alive
    open_logs = [p for p in Path("/proc/self/fd").iterdir() if os.path.realpath(p).startswith(str(tmp_path))]
    assert open_logs == []

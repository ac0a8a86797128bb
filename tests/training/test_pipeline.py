"""End to end on data the test makes itself: train a tiny DanceNet, then `dancenet generate` with it."""

from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from made_up import click_song

from dancenet_core.cli import main as cli_main
from dancenet_core.data.build import PairedSequence
from dancenet_core.data.windows import WindowSampler
from dancenet_core.generate import generate_dance
from dancenet_core.motion import Motion
from dancenet_core.nets.bundle import DanceNetBundle
from dancenet_core.representation import encode
from dancenet_core.request import DanceRequest
from dancenet_core.skeleton import BODY_JOINTS
from dancenet_core.training.configs import TrainSettings
from dancenet_core.training.dancenet import train
from dancenet_core.training.tensor_windows import TensorWindows


def _pair(seed: int, style: str, frames: int = 300) -> PairedSequence:
    rng = np.random.default_rng(seed)
    tt = np.arange(frames) / 25
    rot = 0.3 * np.sin(tt[:, None, None] * rng.uniform(0.5, 3, (1, 55, 3)) * 2 * np.pi)
    rot[:, 25:] = 0.0
    root = np.stack([0.2 * np.sin(tt), 0.95 + 0.02 * np.sin(6 * tt), 0.2 * np.cos(tt)], -1)
    m = Motion(rot, root, 25.0)
    music = rng.normal(size=(frames, 15)).astype(np.float32)
    return PairedSequence(f"SEQ_{seed}", style, encode(m), encode(m.mirrored()), music,
                          m.positions()[:, :BODY_JOINTS].astype(np.float32), m.skeleton.offsets, 0.0, 0.0)


@pytest.fixture(scope="module")
def tiny_weights(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("run")
    settings = TrainSettings(out=out, minutes=5, steps=4, batch=2, window=100, log_every=2, checkpoint_every=2,
                             snapshot_every=2)
    path = train(settings, *_tiny_dataset())
    log = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    assert log[-1]["done"]
    assert np.isfinite(log[-1]["test_loss"])
    assert (out / "checkpoint.pt").is_file()
    # A snapshot carries its step's held-out loss, so one chosen for shipping has its card's figures.
    snapshot = DanceNetBundle.load(out / "snapshots" / "step000004.pt")
    assert snapshot.info["steps"] == 4 and snapshot.info["test_loss"] == pytest.approx(log[-1]["test_loss"])
    return path


def _tiny_dataset() -> tuple[list[PairedSequence], dict]:
    pairs = [_pair(0, "rumba"), _pair(1, "rumba"), _pair(2, "waltz"), _pair(3, "waltz"), _pair(4, "waltz")]
    return pairs, {"train": ["SEQ_0", "SEQ_1", "SEQ_2", "SEQ_3"], "test": ["SEQ_4"]}


def test_training_resumes_from_its_plain_checkpoint(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """The checkpoint holds plain tensors (read with weights_only=True) and carries the run on where it stopped."""
    settings = TrainSettings(out=tmp_path, minutes=5, steps=2, batch=2, window=100, log_every=1, checkpoint_every=2)
    train(settings, *_tiny_dataset())
    train(replace(settings, steps=4, resume=True), *_tiny_dataset())
    assert "resumed at step 2" in capsys.readouterr().out
    steps = [json.loads(line)["step"] for line in (tmp_path / "log.jsonl").read_text().splitlines()]
    assert steps[-1] == 4


def test_a_resumed_run_is_the_same_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Stopped right after its checkpoint and resumed, a run draws the windows (with their noise) an
    uninterrupted run draws, on this machine's device: on a GPU they come from the CUDA generator, which the
    checkpoint carries too. On the CPU the weights come out the same too (a GPU's backward pass is not bitwise
    reproducible even run to run)."""
    from dancenet_core.training import dancenet

    drawn: list[torch.Tensor] = []
    sampler = TensorWindows if torch.cuda.is_available() else WindowSampler
    original = sampler.batch

    def recorded(self: object, *args: object, **kwargs: object) -> object:
        b = original(self, *args, **kwargs)
        if len(b.motion) == settings.batch:  # a training batch, not the held-out windows
            drawn.append(torch.as_tensor(b.motion).cpu().clone())
        return b

    def saved_then_stopped(obj: dict, path: Path) -> None:
        dancenet_save(obj, path)
        raise KeyboardInterrupt

    monkeypatch.setattr(sampler, "batch", recorded)
    settings = TrainSettings(minutes=5, steps=4, batch=2, window=100, log_every=1, checkpoint_every=2,
                             own_inputs=0.3)
    whole = train(replace(settings, out=tmp_path / "whole"), *_tiny_dataset())
    dancenet_save = dancenet.save_weights
    with monkeypatch.context() as patched:
        patched.setattr(dancenet, "save_weights", saved_then_stopped)
        with pytest.raises(KeyboardInterrupt):
            train(replace(settings, out=tmp_path / "parts"), *_tiny_dataset())
    parts = train(replace(settings, out=tmp_path / "parts", resume=True), *_tiny_dataset())
    assert len(drawn) == 8 and all(torch.equal(a, b) for a, b in zip(drawn[:4], drawn[4:], strict=True))
    if not torch.cuda.is_available():
        a, b = DanceNetBundle.load(whole).model.state_dict(), DanceNetBundle.load(parts).model.state_dict()
        assert all(torch.equal(a[k], b[k]) for k in a)


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="needs Linux /proc")
def test_the_training_log_is_closed_when_training_stops(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A run that stops with an error (here its checkpoint cannot be written) leaves its log closed, also while
    its caller keeps the error (and with it the run's frames) to report it."""
    from dancenet_core.training import dancenet

    def full_disk(*_args: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(dancenet, "save_weights", full_disk)
    settings = TrainSettings(out=tmp_path, minutes=5, steps=4, batch=2, window=100, log_every=1, checkpoint_every=2)
    with pytest.raises(OSError, match="No space left") as kept:
        train(settings, *_tiny_dataset())
    log = (tmp_path / "log.jsonl").resolve()
    assert [fd for fd in Path("/proc/self/fd").iterdir() if Path(os.path.realpath(fd)) == log] == [], kept.value


@pytest.fixture(scope="module")
def clicks(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return click_song(tmp_path_factory.mktemp("song") / "clicks.wav", 8.0)


def test_training_writes_what_generation_runs(tiny_weights: Path, clicks: Path) -> None:
    """Beside its checkpoint, training writes the plain arrays generation runs without torch: the same dance."""
    kw = dict(style="waltz", seed=3, footfix=False)
    a = generate_dance(DanceRequest(clicks, weights=str(tiny_weights.with_suffix(".npz")), **kw))
    b = generate_dance(DanceRequest(clicks, weights=str(tiny_weights), **kw))
    np.testing.assert_array_equal(a.motions[0].rotations, b.motions[0].rotations)


def test_bundle_round_trip(tiny_weights: Path) -> None:
    b = DanceNetBundle.load(tiny_weights)
    assert b.styles == ["rumba", "waltz"]  # read from the weights, not hard-coded
    assert b.info["train_sequences"] == ["SEQ_0", "SEQ_1", "SEQ_2", "SEQ_3"]


def test_generate_is_seeded_and_song_length(tiny_weights: Path, clicks: Path) -> None:
    kw = dict(style="waltz", temperature=0.5, takes=2, footfix=False, weights=str(tiny_weights))
    a = generate_dance(DanceRequest(clicks, seed=3, **kw))
    b = generate_dance(DanceRequest(clicks, seed=3, **kw))
    c = generate_dance(DanceRequest(clicks, seed=4, **kw))
    assert len(a.motions) == 2
    assert a.motions[0].num_frames == round(a.duration_s * 25)
    np.testing.assert_array_equal(a.motions[0].rotations, b.motions[0].rotations)
    assert not np.array_equal(a.motions[0].rotations, c.motions[0].rotations)
    assert not np.array_equal(a.motions[0].rotations, a.motions[1].rotations)
    assert a.style == "waltz"
    assert len(a.beat_times) > 5


def test_cli_generate_writes_files_and_same_seed_same_bytes(tiny_weights: Path, clicks: Path,
                                                          tmp_path: Path) -> None:
    for out in ("a", "b"):
        rc = cli_main(["generate", str(clicks), "-o", str(tmp_path / out), "--style", "rumba", "--seed", "9",
                       "--no-footfix", "--weights", str(tiny_weights)])
        assert rc == 0
    assert (tmp_path / "a" / "clicks.bvh").read_bytes() == (tmp_path / "b" / "clicks.bvh").read_bytes()
    summary = json.loads((tmp_path / "a" / "clicks.json").read_text())
    assert summary["style"] == "rumba"
    assert summary["frames"] == Motion.load(tmp_path / "a" / "clicks.npz").num_frames
    assert set(summary["timings_s"]) >= {"analysis_s", "generation_s", "total_s"}


def test_cli_reports_bad_input_in_one_line(tiny_weights: Path, tmp_path: Path, capsys) -> None:
    rc = cli_main(["generate", str(tmp_path / "missing.mp3"), "-o", str(tmp_path / "o"),
                   "--weights", str(tiny_weights)])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert err.startswith("dancenet: error:")
    assert "\n" not in err
    rc = cli_main(["generate", str(tmp_path / "missing.mp3"), "-o", str(tmp_path / "o"), "--style", "tango",
                   "--weights", str(tiny_weights)])
    assert rc == 2

"""Issue 18 on the command line with the shipped model: frame rates, a part of the song, root motion and
continuing a dance from a frame (the add-on's side is in test_addon_animator.py)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from dancenet_core.bvh import read_bvh
from dancenet_core.cli import main as cli_main
from dancenet_core.motion import FRAME_RATES, Motion


@pytest.fixture(scope="module")
def song(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """12 s of a 110-BPM click over a tone, with the feature cache in the test's own folder."""
    folder = tmp_path_factory.mktemp("song")
    os.environ["DANCENET_CACHE"] = str(folder / "cache")
    sr = 22050
    t = np.arange(int(12.0 * sr)) / sr
    y = 0.1 * np.sin(2 * np.pi * 220 * t) + 0.5 * (np.mod(t, 60.0 / 110) < 0.01)
    sf.write(folder / "clicks.wav", y.astype(np.float32), sr)
    return folder / "clicks.wav"


def generate(song: Path, out: Path, *extra: str) -> Motion:
    assert cli_main(["generate", str(song), "-o", str(out), "--seed", "5", *extra]) == 0
    return Motion.load(out / f"{song.stem}.npz")


def test_fps_resamples_the_same_dance_with_slerp(song: Path, tmp_path: Path) -> None:
    own = generate(song, tmp_path / "own")
    assert own.fps == 25.0
    for fps in (24, 60):
        m = generate(song, tmp_path / str(fps), "--fps", str(fps))
        bvh = read_bvh(tmp_path / str(fps) / "clicks.bvh")
        assert m.fps == fps and bvh.frame_time == pytest.approx(1 / fps, abs=1e-8)
        assert m.num_frames == round(own.duration * fps) == bvh.num_frames
        ref = own.resampled(fps)  # the one resampler the add-on and batch mode use too
        np.testing.assert_allclose(m.positions(), ref.positions(), atol=1e-4)
    # At 60 fps every 12th frame is a 25-fps frame (t = k/5 s): the same pose, not a blend.
    m60 = Motion.load(tmp_path / "60" / "clicks.npz")
    np.testing.assert_allclose(m60.positions()[::12], own.positions()[::5][: len(m60.positions()[::12])], atol=1e-4)
    assert set(FRAME_RATES) == {24, 25, 30, 50, 60}


def test_fps_outside_the_offered_rates_is_one_line(song: Path, tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit) as e:
        cli_main(["generate", str(song), "-o", str(tmp_path), "--fps", "23"])
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2 and "--fps" in err[-1] and "invalid choice" in err[-1]

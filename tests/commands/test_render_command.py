"""`dancenet render`: a contact sheet and a video of a generated dance, and one line (exit 2) for what it refuses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from made_up import read_video

from dancenet_core.cli import main


@pytest.fixture(scope="module")
def dance(short_song: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("dance")
    assert main(["generate", str(short_song), "-o", str(out), "--style", "waltz"]) == 0
    return out / "short_song"


def test_sheet_and_video(dance: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    capsys.readouterr()
    assert main(["render", str(dance.with_suffix(".bvh")), "--sheet", str(tmp_path / "s.png"), "--width", "320",
                 "--height", "180"]) == 0
    assert (tmp_path / "s.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert capsys.readouterr().out.startswith("200 frames at 25 fps")
    assert main(["render", str(dance.with_suffix(".npz")), "-o", str(tmp_path / "v.mp4"), "--audio",
                 str(dance.parent / "short_song.json"), "--fps", "10", "--width", "160", "--height", "90"]) == 2
    assert "short_song.json" in capsys.readouterr().err  # the music is read before a frame is drawn
    assert main(["render", str(dance.with_suffix(".npz")), "-o", str(tmp_path / "v.mp4"), "--fps", "10",
                 "--width", "160", "--height", "90"]) == 0
    assert capsys.readouterr().out.startswith("80 frames at 10 fps")
    meta, frames = read_video(tmp_path / "v.mp4")
    assert (meta["size"], meta["fps"], frames.shape) == ((160, 90), 10, (80, 90, 160, 3))
    moving = np.abs(np.diff(frames.astype(np.int16), axis=0)).max(axis=(1, 2, 3))
    assert (moving > 40).mean() > 0.9  # the dancer moves from frame to frame
    assert (frames.std(axis=(1, 2, 3)) > 10).all()  # a figure on a floor, never a blank frame


@pytest.mark.parametrize(("args", "says"), [
    ([], "nothing to write"),
    (["--sheet", "s.png", "--audio", "a.wav"], "--audio goes into a video"),
    (["-o", "v.mp4", "--fps", "0"], "--fps must be positive"),
])
def test_bad_input_is_one_line_and_exit_2(args: list[str], says: str, dance: Path,
                                          capsys: pytest.CaptureFixture) -> None:
    capsys.readouterr()
    assert main(["render", str(dance.with_suffix(".bvh")), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("dancenet: error: ") and says in err[0], err


def test_not_a_motion_is_one_line(dance: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["render", str(dance.parent / "short_song.json"), "--sheet", "s.png"]) == 2
    assert "is not a motion file" in capsys.readouterr().err

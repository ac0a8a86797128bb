"""`dancenet generate`: the files and the JSON summary it writes, and one line (exit 2) for what it refuses."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dancenet_core.bvh import read_bvh
from dancenet_core.cli import main


def _error_line(capsys: pytest.CaptureFixture) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("dancenet: error: "), err
    return err[0]


def test_summary_records_the_request_and_the_files(short_song: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "out"
    assert main(["generate", str(short_song), "-o", str(out), "--seed", "3", "--takes", "2", "--style", "waltz",
                 "--energy", "lively", "--fps", "30", "--root-motion", "in-place"]) == 0
    assert capsys.readouterr().out.strip().startswith("waltz dance, 240 frames at 30 fps")
    summary = json.loads((out / "short_song.json").read_text())
    assert {k: summary[k] for k in ("style", "seed", "takes", "energy", "temperature", "fps", "frames",
                                    "root_motion", "footfix", "style_probabilities")} == {
        "style": "waltz", "seed": 3, "takes": 2, "energy": "lively", "temperature": 1.0, "fps": 30.0, "frames": 240,
        "root_motion": "in-place", "footfix": True, "style_probabilities": {}}
    assert summary["files"] == ["short_song_take1.bvh", "short_song_take1.npz", "short_song_take2.bvh",
                                "short_song_take2.npz"]
    assert sorted(p.name for p in out.iterdir()) == sorted([*summary["files"], "short_song.json"])
    bvh = read_bvh(out / "short_song_take1.bvh")
    assert (bvh.num_frames, round(1 / bvh.frame_time)) == (240, 30)
    assert abs(summary["duration_s"] - 8.0) < 0.05
    assert summary["tempo_bpm"] == pytest.approx(84, abs=1.5)  # scripts/make_example_song.py: a waltz at 84 BPM
    assert set(summary["timings_s"]) >= {"analysis_s", "generation_s", "writing_s", "total_s"}


@pytest.mark.parametrize(("args", "says"), [
    (["--style", "polka"], "unknown style 'polka'"),
    (["--at", "2"], "--at goes with --continue"),
    (["--takes", "0"], "takes must be from 1 to"),
    (["--start", "7.5"], "(the song lasts 8.0 s)"),  # found after the analysis
])
def test_bad_input_is_one_line_and_exit_2(args: list[str], says: str, short_song: Path, tmp_path: Path,
                                          capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "out"
    assert main(["generate", str(short_song), "-o", str(out), *args]) == 2
    assert says in _error_line(capsys)
    assert not out.exists() or not any(out.iterdir())  # nothing written


def test_missing_song_and_existing_outputs_are_refused(short_song: Path, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture) -> None:
    assert main(["generate", str(tmp_path / "none.ogg"), "-o", str(tmp_path / "a")]) == 2
    assert "none.ogg" in _error_line(capsys)
    out = tmp_path / "b"
    assert main(["generate", str(short_song), "-o", str(out), "--style", "tango"]) == 0
    capsys.readouterr()
    before = (out / "short_song.bvh").read_bytes()
    assert main(["generate", str(short_song), "-o", str(out), "--style", "tango", "--seed", "5"]) == 2
    assert "--overwrite" in _error_line(capsys)
    assert (out / "short_song.bvh").read_bytes() == before

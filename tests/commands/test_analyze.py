"""`dancenet analyze`: the printed summary and the JSON of a song, and one line (exit 2) for a file that is not one."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dancenet_core.cli import main
from dancenet_core.music.features import FEATURE_SPEC


def test_prints_and_writes_the_songs_beats_and_style(short_song: Path, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture) -> None:
    assert main(["analyze", str(short_song), "--json", str(tmp_path / "a.json")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(":")[0] for line in lines] == ["song", "tempo", "style", "beats", "downbeats", "form", "time"]
    out = json.loads((tmp_path / "a.json").read_text())
    assert out["features"] == {"shape": [80, FEATURE_SPEC.dim], "fps": FEATURE_SPEC.fps}
    beats = np.array(out["beat_times"])
    assert len(beats) >= 8 and (np.diff(beats) > 0).all() and 0 <= beats[0] <= beats[-1] <= out["duration_s"]
    assert set(out["downbeat_times"]) <= set(out["beat_times"])
    assert abs(out["tempo_bpm"] - 60 / np.median(np.diff(beats))) < 1.0  # the JSON rounds the beats to ms
    assert f"beats:     {len(beats)}" in lines
    assert out["style"]["style"] in out["style"]["probabilities"]
    (section,) = out["form"]["sections"]  # 8 s of a click track: too short for a return
    assert out["form"]["labels"] == "A" and section == {"name": "A1", "label": "A", "start_s": 0.0,
                                                        "end_s": out["duration_s"], "bars": 4, "match": 1.0}
    assert "form:      A1 0.0s" in lines


def test_not_a_song_is_one_line_and_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    text = tmp_path / "notes.wav"
    text.write_text("not audio")
    assert main(["analyze", str(text)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("dancenet: error: ") and "notes.wav" in err[0], err

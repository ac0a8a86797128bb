"""The song split: by song, stratified by style, fixed by its seed."""

from __future__ import annotations

from pathlib import Path

from dancenet_core.data.dance_with_melody import Recording
from dancenet_core.data.split import make_split


def _recording(seq: str, style: str) -> Recording:
    return Recording(seq, style, frames=0, fps=25.0, music_offset_s=0.0, npz=Path(), audio=Path(), song=seq)


ROWS = (
    [_recording(f"DANCE_W_{i}", "waltz") for i in range(1, 11)]
    + [_recording(f"DANCE_C_{i}", "cha-cha") for i in range(1, 6)]
    + [_recording("DANCE_T_1", "tango")]
)


def test_split_is_by_song_stratified_and_fixed() -> None:
    split = make_split(ROWS, seed=7)
    assert split == make_split(ROWS, seed=7)
    assert not set(split["train"]) & set(split["test"])
    assert sorted(split["train"] + split["test"] + list(split["excluded"])) == sorted(r.seq for r in ROWS)
    assert sum(s.startswith("DANCE_W") for s in split["test"]) == 2
    assert sum(s.startswith("DANCE_C") for s in split["test"]) == 1
    assert list(split["excluded"]) == ["DANCE_T_1"]
    assert "only song" in split["excluded"]["DANCE_T_1"]

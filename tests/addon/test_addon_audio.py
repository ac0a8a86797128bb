"""Inside Blender the extension has no imageio-ffmpeg (build_addon leaves its 23-68 MB wheel out): an m4a or an
mp4's audio, which a sound strip plays, is decoded by Blender's own audio module (`aud`) instead."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from made_up import encoded_click_track
from scene_helpers import bpy

from dancenet_core.errors import DanceNetError
from dancenet_core.music.audio import load_audio


@pytest.mark.parametrize("ext", ["m4a", "mp4"])
def test_blender_decodes_aac_without_imageio_ffmpeg(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    ext: str) -> None:
    assert bpy.app.version  # `aud` is importable once bpy is
    wav, (song,) = encoded_click_track(tmp_path, (ext,))
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # as in the extension
    got, expected = load_audio(song), load_audio(wav)
    assert (got.source_sample_rate, got.source_channels) == (44100, 2)
    assert 0 <= len(got.samples) - len(expected.samples) < 2048  # aud keeps the encoder's padding at the end
    n = len(expected.samples)
    lag = np.argmax(np.correlate(got.samples[: 3 * 44100], expected.samples[: 3 * 44100], "full")) - 3 * 44100 + 1
    assert lag == 0
    assert np.sqrt(np.mean((got.samples[:n] - expected.samples) ** 2) / np.mean(expected.samples**2)) < 0.5


def test_a_broken_m4a_is_one_line_in_blender(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _, (song,) = encoded_click_track(tmp_path, ("m4a",))
    song.write_bytes(song.read_bytes()[:2000])
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)
    with pytest.raises(DanceNetError) as err:
        load_audio(song)
    assert "cannot decode clicks.m4a" in str(err.value) and "\n" not in str(err.value)

"""What the command tests share: a short excerpt of the example song (analysed in seconds, not a minute)."""

from __future__ import annotations

from pathlib import Path

import pytest
import soundfile as sf

ROOT = Path(__file__).resolve().parents[2]
SONG = ROOT / "examples" / "example_song.ogg"
EXCERPT_S = 8.0


@pytest.fixture(scope="session")
def short_song(tmp_path_factory: pytest.TempPathFactory) -> Path:
    audio, rate = sf.read(SONG, frames=int(EXCERPT_S * sf.info(SONG).samplerate), always_2d=True)
    path = tmp_path_factory.mktemp("song") / "short song.wav"
    sf.write(path, audio, rate)
    return path

"""What `dancenet generate` tells its user: the styles it dances in --help, and a summary line of its own after the
progress bar (on a line of its own, not `100% 00:02cha-cha dance`, where stderr and stdout share a log)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from dancenet_core.cli import main
from dancenet_core.generate import available_styles

ROOT = Path(__file__).resolve().parents[1]
SONG = ROOT / "examples" / "example_song.ogg"


def test_generate_help_lists_the_shipped_styles(capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit):
        main(["generate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"the shipped one: {', '.join(available_styles())}" in text


def test_summary_line_is_a_line_of_its_own_in_a_shared_log(tmp_path: Path) -> None:
    """A cold cache makes the run long enough for the bar to draw (it waits half a second)."""
    log = tmp_path / "log"
    env = os.environ | {"DANCENET_CACHE": str(tmp_path / "cache")}
    with log.open("w") as f:
        subprocess.run([sys.executable, "-m", "dancenet_core.cli", "generate", str(SONG), "-o", str(tmp_path / "out"),
                        "--end", "12", "--style", "waltz"], stdout=f, stderr=subprocess.STDOUT, env=env, check=True)
    *before, last, end = log.read_text(encoding="utf-8").split("\n")
    assert end == "" and last.startswith("waltz dance, 300 frames at 25 fps"), (before[-1:], last)
    assert all("waltz dance" not in line for line in before)

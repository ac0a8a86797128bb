"""The dance request: its energy preset scales the temperature the engine samples at, and reaches every
front-end from the request's options alone."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pytest

from dancenet_core.errors import DanceNetError
from dancenet_core.generate import generate_dance
from dancenet_core.request import DanceRequest, add_options, options_from, panel_options

SONG = Path(__file__).resolve().parents[1] / "examples" / "example_song.ogg"


def test_energy_scales_the_sampling_temperature_within_the_limit() -> None:
    assert DanceRequest(SONG, temperature=0.5).sampling_temperature == 0.5
    assert DanceRequest(SONG, temperature=0.5, energy="calm").sampling_temperature == pytest.approx(0.3)
    assert DanceRequest(SONG, temperature=3.0, energy="lively").sampling_temperature == 3.0
    with pytest.raises(DanceNetError, match="unknown energy 'wild'; choose one of: calm, as-danced, lively"):
        DanceRequest(SONG, energy="wild").check()


def test_energy_is_an_option_of_the_command_line_and_the_panel() -> None:
    parser = argparse.ArgumentParser()
    add_options(parser)
    assert options_from(parser.parse_args(["--energy", "calm"]))["energy"] == "calm"
    assert "energy" in [name for name, _default, _option in panel_options()]


def test_a_calm_dance_moves_less_than_a_lively_one() -> None:
    """Same seeds, same song part: the calm preset's joints travel less per second than the lively one's (here
    0.94 against 1.55 m/s over seeds 2 and 3 with the moves scaled; by the temperature alone 1.24 against 1.36, which
    this bound would not pass)."""
    def speed(energy: str) -> float:
        takes = [generate_dance(DanceRequest(SONG, seed=seed, end_s=20.0, footfix=False, energy=energy)).motions[0]
                 for seed in (2, 3)]
        return float(np.mean([np.linalg.norm(np.diff(m.positions(), axis=0), axis=-1).mean() * m.fps for m in takes]))

    calm, lively = speed("calm"), speed("lively")
    assert calm < 0.9 * lively, (calm, lively)

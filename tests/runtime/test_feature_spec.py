"""The weights say which music features they were trained on, and generation refuses others in one line."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from dancenet_core.engines.styles import load_style_model
from dancenet_core.errors import DanceNetError
from dancenet_core.generate import check_request
from dancenet_core.music.features import FEATURE_SPEC, N_FEATURES, FeatureSpec
from dancenet_core.request import DanceRequest
from dancenet_core.runtime.config import DanceNetConfig
from dancenet_core.runtime.weights import DEFAULT_RUNTIME, STYLE_RUNTIME, RuntimeBundle, RuntimeStyleModel, read_arrays

REPO = Path(__file__).resolve().parents[2]
SONG = REPO / "examples" / "example_song.ogg"
OTHER_VERSION = replace(FEATURE_SPEC, version="music-features-0")
SWAPPED = replace(FEATURE_SPEC, columns=(*FEATURE_SPEC.columns[:-2], FEATURE_SPEC.columns[-1],
                                         FEATURE_SPEC.columns[-2]))


def test_shipped_weights_carry_the_feature_spec() -> None:
    """Written in the files themselves, not filled in on loading."""
    _, dancenet = read_arrays(DEFAULT_RUNTIME, "DanceNet weights", "")
    _, style = read_arrays(STYLE_RUNTIME, "style classifier weights", "")
    assert dancenet["config"]["music_spec"] == FEATURE_SPEC.to_dict()
    assert dancenet["config"]["music_dim"] == FEATURE_SPEC.dim == N_FEATURES
    assert style["meta"]["music_spec"] == FEATURE_SPEC.to_dict()


def test_weights_without_a_spec_read_as_this_versions() -> None:
    config = RuntimeBundle.load().model.cfg.to_dict()
    del config["music_spec"]
    assert FeatureSpec.from_dict(DanceNetConfig(**config).music_spec) == FEATURE_SPEC
    assert FeatureSpec.from_dict(None) == FEATURE_SPEC


def _dancenet_trained_on(spec: FeatureSpec, path: Path) -> Path:
    bundle = RuntimeBundle.load()
    bundle.model.cfg = replace(bundle.model.cfg, music_spec=spec.to_dict())
    bundle.save(path)
    return path


@pytest.mark.parametrize(("spec", "shown"), [
    (OTHER_VERSION, ["music-features-0 (15 columns at 10 fps)"]),
    (SWAPPED, ["chroma_B, beat, onset, downbeat)", "chroma_B, beat, downbeat, onset)"]),  # columns: all that differ
])
def test_dancenet_weights_on_other_features_are_refused_in_one_line(spec: FeatureSpec, shown: list[str],
                                                                    tmp_path: Path) -> None:
    weights = _dancenet_trained_on(spec, tmp_path / "other.npz")
    with pytest.raises(DanceNetError) as e:
        check_request(DanceRequest(song=SONG, weights=str(weights)))
    message = str(e.value)
    assert "\n" not in message
    assert message.startswith("these DanceNet weights were trained on music features")
    assert f"this version computes {FEATURE_SPEC.version}" in message
    assert all(s in message for s in shown), message


def test_style_weights_on_other_features_are_refused_in_one_line(tmp_path: Path) -> None:
    model = RuntimeStyleModel.load()
    model.music_spec = OTHER_VERSION
    model.save(tmp_path / "style.npz")
    with pytest.raises(DanceNetError, match=r"^these style classifier weights were trained on music features "
                                            r"music-features-0 .*; this version computes music-features-1"):
        load_style_model(str(tmp_path / "style.npz"))


def test_the_command_line_says_it_in_one_line(tmp_path: Path) -> None:
    weights = _dancenet_trained_on(OTHER_VERSION, tmp_path / "other.npz")
    run = subprocess.run([sys.executable, "-m", "dancenet_core.cli", "generate", str(SONG), "--weights",
                          str(weights), "-o", str(tmp_path / "out")], capture_output=True, text=True, timeout=300)
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "trained on music features music-features-0" in lines[0], run.stderr

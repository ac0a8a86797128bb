"""Style classifier: shapes, window aggregation, names from metadata, the fixed split, the beat-bump input and its
augmentation, the shipped weights on a held-out real song and on the example song, and `dancenet analyze`."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
import torch
from made_up import analysis, peak_frames, peaks
from scipy.special import softmax
from torch import nn

from dancenet_core import cli
from dancenet_core.data.dance_with_melody import read_manifest
from dancenet_core.data.split import SPLIT_FILE
from dancenet_core.errors import DanceNetError
from dancenet_core.music import style as S
from dancenet_core.music.audio import Audio, load_audio
from dancenet_core.music.features import analyze_audio, analyze_music
from dancenet_core.nets import style_torch as T
from dancenet_core.nets.export import style_to_runtime
from dancenet_core.runtime.weights import RuntimeStyleModel

REPO = Path(__file__).resolve().parents[2]
DATA = Path(os.environ.get("DANCENET_DATA", REPO.parent / "shared" / "data")) / "dance_with_melody"
needs_data = pytest.mark.skipif(not (DATA / "manifest.csv").is_file(), reason=f"no Dance with Melody data at {DATA}")
pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.mark.parametrize("arch", S.ARCHS)
@pytest.mark.parametrize("frames", [300, 37])
def test_forward_shapes(arch: str, frames: int) -> None:
    net = T.build_net(arch, 3).eval()
    assert net(torch.randn(4, frames, S.N_INPUTS)).shape == (4, 3)


def test_conv_layers_follow_the_paper() -> None:
    convs = [m for m in T.StyleConvNet(2).modules() if isinstance(m, nn.Conv2d)]
    assert [(c.in_channels, c.out_channels, c.kernel_size) for c in convs] == [
        (1, 16, (2, 1)),
        (16, 24, (2, 1)),
        (24, 32, (2, 1)),
    ]
    assert len([m for m in T.StyleConvNet(2).modules() if isinstance(m, nn.BatchNorm2d)]) == 3
    assert T.StyleConvNet(2).lstm.bidirectional


def test_window_starts() -> None:
    np.testing.assert_array_equal(S.window_starts(1000, 300, 50), list(range(0, 701, 50)))
    np.testing.assert_array_equal(S.window_starts(1020, 300, 50), [*range(0, 701, 50), 720])
    np.testing.assert_array_equal(S.window_starts(300, 300, 50), [0])
    np.testing.assert_array_equal(S.window_starts(120, 300, 50), [0])


class _MeanOfColumn(nn.Module):
    """Logits (m, -m) from the mean of feature 0: a model whose window outputs are known in advance."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        m = x[:, :, 0].mean(dim=1, keepdim=True)
        return torch.cat([m, -m], dim=1)


def test_song_style_is_mean_of_window_probabilities() -> None:
    model = T.StyleModel(_MeanOfColumn(), "conv", ["slow", "fast"], {})
    feats = np.zeros((1000, 15), np.float32)
    feats[:500, 0] = 3.0
    feats[500:, 0] = -1.0
    r = model.classify(analysis(feats))
    assert r.window_probabilities.shape == (15, 2)
    np.testing.assert_allclose(r.window_starts_s, np.arange(0, 71, 5))
    np.testing.assert_allclose(r.probabilities, r.window_probabilities.mean(axis=0), rtol=1e-6)
    assert r.window_styles()[0] == "slow"
    assert r.window_styles()[-1] == "fast"
    assert r.style == ("slow" if r.probabilities[0] > 0.5 else "fast")
    assert r.to_dict()["windows"][0]["style"] == "slow"
    short = model.classify(analysis(feats[:120]))  # shorter than a window: one shorter window
    assert short.window_probabilities.shape == (1, 2)
    assert short.window_s == 12.0


def test_style_names_come_from_metadata(tmp_path: Path) -> None:
    for arch in S.ARCHS:
        config = {"hidden": 16, "dropout": 0.2}
        model = T.StyleModel(T.build_net(arch, 2, **config), arch, ["polka", "tango"], config)
        model.save(tmp_path / f"{arch}.pt")
        loaded = T.StyleModel.load(tmp_path / f"{arch}.pt")
        assert loaded.styles == ("polka", "tango")
        assert loaded.arch == arch
        song = analysis(np.random.default_rng(0).random((400, 15), dtype=np.float32))
        assert loaded.classify(song).style in ("polka", "tango")
        np.testing.assert_allclose(model.classify(song).probabilities, loaded.classify(song).probabilities)


def test_weights_from_before_the_meter_and_tempo_columns_still_run(tmp_path: Path) -> None:
    """A checkpoint whose config has no "inputs" (trained on the 15 columns before metre and tempo) loads, in
    torch and in numpy, and reads the first 15 columns of today's classifier input."""
    net = T.build_net("conv", 2, hidden=8, dropout=0.1, inputs=15)
    old = T.StyleModel(net, "conv", ["polka", "tango"], {"hidden": 8, "dropout": 0.1})
    old.save(tmp_path / "old.pt")
    loaded = T.StyleModel.load(tmp_path / "old.pt")
    assert loaded.inputs == 15
    song = analysis(np.random.default_rng(0).random((400, 15), dtype=np.float32))
    x = S.classifier_input(song)[:, :15]
    np.testing.assert_allclose(loaded.classify(song).window_probabilities[0],
                               softmax(old.logits(x[None, :300]), axis=1)[0], rtol=1e-5)
    style_to_runtime(loaded).save(tmp_path / "old.npz")
    runtime = RuntimeStyleModel.load(tmp_path / "old.npz")
    assert runtime.inputs == 15
    np.testing.assert_allclose(runtime.classify(song).probabilities, loaded.classify(song).probabilities, atol=1e-5)


def test_meter_and_tempo_columns() -> None:
    """Beats every 5 frames (120 bpm at 10 fps), bars of 3 then of 4: the metre column is 0 in the 3-beat bars
    and 1 in the 4-beat ones (frames outside take the nearest bar), the tempo column log2(120 / 120) = 0
    everywhere, and one beat tracked a frame late moves neither; too few beats leave both columns 0."""
    beats = np.arange(0, 100, 5.0)
    downbeats = np.array([0, 15, 30, 50, 70.0])  # bars of 3, 3, 4, 4 beats
    beats[8] += 1.0
    x = S.meter_tempo(beats, downbeats, 110, 10)
    assert x.shape == (110, 2)
    assert x.dtype == np.float32
    np.testing.assert_array_equal(x[:30, 0], 0.0)
    np.testing.assert_array_equal(x[30:, 0], 1.0)
    np.testing.assert_allclose(x[:, 1], 0.0, atol=1e-6)
    np.testing.assert_array_equal(S.meter_tempo(np.array([3.0]), np.array([3.0]), 20, 10), 0.0)
    slow = S.meter_tempo(beats * 2, downbeats * 2, 200, 10)  # 60 bpm
    np.testing.assert_allclose(slow[:, 1], -1.0, atol=1e-6)


def test_load_errors_are_user_facing(tmp_path: Path) -> None:
    with pytest.raises(DanceNetError, match="not found"):
        T.StyleModel.load(tmp_path / "missing.pt")
    torch.save({"something": 1}, tmp_path / "other.pt")
    with pytest.raises(DanceNetError, match="not a dancenet style model"):
        T.StyleModel.load(tmp_path / "other.pt")
    (tmp_path / "broken.pt").write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(DanceNetError, match="cannot read the style model"):
        T.StyleModel.load(tmp_path / "broken.pt")


def test_bump_track_has_full_height_at_every_beat_whatever_the_grid() -> None:
    track = S.bump_track(np.array([2.0, 7.5, 12.25]), 16)
    assert track[2] == pytest.approx(1.0)
    assert track[7] == track[8] == pytest.approx(np.exp(-0.125))
    assert track[12] > 0.95
    assert peaks(track) == 3
    assert track.dtype == np.float32
    assert not S.bump_track(np.array([]), 5).any()


def test_classifier_input_of_a_waltz_click_track() -> None:
    """A 3/4 click track through the real analysis: the classifier input has one full-height beat bump per
    tracked beat and a downbeat bump on every third beat, however low the sampled activations are."""
    sr, beat_s = 44100, 0.5
    x = np.zeros(20 * sr, np.float32)
    t = np.arange(int(0.03 * sr)) / sr
    for i, when in enumerate(np.arange(0.5, 19.9, beat_s)):
        amp, freq = (0.9, 1500) if i % 3 == 0 else (0.4, 1000)
        s = int(when * sr)
        x[s : s + len(t)] += amp * np.exp(-t / 0.004) * np.sin(2 * np.pi * freq * t)
    analysis = analyze_audio(Audio(x, sr, sr, 1, Path("waltz.wav")), workers=1)
    assert len(analysis.beat_times) >= 30
    assert 3 * len(analysis.downbeat_times) == pytest.approx(
        len(analysis.beat_times), abs=3
    )
    bars = np.diff(np.searchsorted(analysis.beat_times, analysis.downbeat_times))
    assert (bars == 3).all()
    x_in = S.classifier_input(analysis)
    np.testing.assert_array_equal(x_in[:, :12], analysis.features[:, :12])
    np.testing.assert_array_equal(x_in[:, 14], analysis.features[:, 14])
    beat_frames, downbeat_frames = peak_frames(x_in[:, 12]), peak_frames(x_in[:, 13])
    assert len(beat_frames) == len(analysis.beat_times)
    assert len(downbeat_frames) == len(analysis.downbeat_times)
    assert x_in[beat_frames, 12].min() > 0.85
    assert x_in[downbeat_frames, 13].min() > 0.85
    on_downbeats = np.flatnonzero(np.isin(beat_frames, downbeat_frames))
    assert len(on_downbeats) == len(downbeat_frames)
    assert (np.diff(on_downbeats) == 3).all()
    assert x_in.shape == (len(analysis.features), S.N_INPUTS)
    np.testing.assert_array_equal(x_in[:, S.METER_COL], 0.0)  # 3 beats a bar
    np.testing.assert_allclose(x_in[:, S.TEMPO_COL], 0.0, atol=0.02)  # a beat every 0.5 s: 120 bpm


# --------------------------------------------------------------------------- shipped weights and real data


def test_shipped_models_load() -> None:
    for path, arch in ((S.DEFAULT_WEIGHTS, "conv"), (S.BASELINE_WEIGHTS, "baseline")):
        model = T.StyleModel.load(path)
        assert model.arch == arch
        assert len(model.styles) >= 2
        assert model.window == 300
        assert model.fps == 10
        assert path.stat().st_size < 5_000_000


def test_shipped_split_file() -> None:
    split = json.loads(SPLIT_FILE.read_text())
    assert {"seed", "train", "test", "excluded"} <= set(split)
    assert not set(split["train"]) & set(split["test"])
    assert not set(split["excluded"]) & set(split["test"])


@needs_data
def test_shipped_split_covers_the_data_and_model_styles() -> None:
    split = json.loads(SPLIT_FILE.read_text())
    style_of = {r.seq: r.style for r in read_manifest(DATA)}
    assert sorted(split["train"] + split["test"] + list(split["excluded"])) == sorted(style_of)
    train_styles = {style_of[s] for s in split["train"]}
    assert {style_of[s] for s in split["test"]} == train_styles
    for path in (S.DEFAULT_WEIGHTS, S.BASELINE_WEIGHTS):
        assert T.StyleModel.load(path).styles == tuple(sorted(train_styles))


@needs_data
def test_shipped_model_on_held_out_song() -> None:
    """The first 40 s of the shortest held-out song (a waltz): the shipped model names its style, surely, in every
    window (0.997 here)."""
    split = json.loads(SPLIT_FILE.read_text())
    rows = {r.seq: r for r in read_manifest(DATA)}
    seq = min(split["test"], key=lambda s: rows[s].song_s)
    audio = load_audio(DATA / f"{seq}.ogg")
    audio.samples = audio.samples[: 40 * audio.sample_rate]
    model = T.StyleModel.load()
    result = model.classify(analyze_audio(audio))
    assert result.style == rows[seq].style
    assert result.probabilities.max() > 0.9
    assert result.window_styles() == [rows[seq].style] * 3
    assert result.probabilities.sum() == pytest.approx(1.0, abs=1e-5)
    assert len(result.window_starts_s) == 3  # 0, 5 and 10 s


def test_shipped_model_calls_the_example_song_a_waltz(tmp_path: Path) -> None:
    """The demo's promise (README): the bundled example song, a synthesised waltz, is classified waltz."""
    analysis = analyze_music(REPO / "examples" / "example_song.ogg", cache_dir=tmp_path)
    assert T.StyleModel.load().classify(analysis).style == "waltz"


def test_analyze_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    song = tmp_path / "clicks.wav"
    t = np.arange(8 * 44100) / 44100
    sf.write(str(song), (0.5 * np.sin(2 * np.pi * 880 * t) * (t % 0.5 < 0.03)).astype(np.float32), 44100)
    out = tmp_path / "analysis.json"
    rc = cli.main(["analyze", str(song), "--json", str(out), "--cache-dir", str(tmp_path / "cache")])
    printed = capsys.readouterr().out
    assert rc == 0
    for word in ("tempo:", "style:", "beats:", "downbeats:", "time:"):
        assert word in printed
    data = json.loads(out.read_text())
    assert data["features"]["shape"] == [80, 15]
    assert len(data["beat_times"]) >= 10
    assert data["tempo_bpm"] == pytest.approx(120, rel=0.05)
    assert data["style"]["style"] in T.StyleModel.load().styles
    assert data["style"]["windows"]


def test_analyze_command_error_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "song.mp3"
    bad.write_bytes(b"\x00garbage" * 1000)
    assert cli.main(["analyze", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("dancenet: error:")
    assert "\n" not in err

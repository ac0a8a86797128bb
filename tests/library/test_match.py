"""The learned match of music and movement (library/match.py): its bar features, its weights file, the plan's use of
it and the library engine's choice of when to use it."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from made_up import click_song
from scipy.spatial.transform import Rotation
from test_library import FPS, _cli, dancer, library_of, song

from dancenet_core.bvh import write_bvh
from dancenet_core.errors import DanceNetError
from dancenet_core.library import build, engine
from dancenet_core.library.choreography import Settings, choreograph
from dancenet_core.library.figures import beat_index
from dancenet_core.library.match import (
    SAMPLES,
    FigureMatch,
    MatchModel,
    bar_points,
    frames_of,
    library_frames,
    motion_bars,
    motion_frames,
    music_bars,
)
from dancenet_core.library.store import MotionLibrary, library_path
from dancenet_core.skeleton import BODY_JOINTS


@pytest.fixture(scope="module")
def library() -> MotionLibrary:
    return library_of(*[(f"clip{k}", dancer(40, bpm, amplitude=0.3 + 0.1 * k, phase=k))
                        for k, bpm in enumerate((100, 110, 120, 104))])


def test_motion_features_do_not_depend_on_where_the_dancer_stands_or_faces() -> None:
    pos = dancer(8, 110).positions()[:, :BODY_JOINTS]
    turned = Rotation.from_euler("y", 70, degrees=True).apply(pos.reshape(-1, 3)).reshape(pos.shape)
    turned += np.array([3.0, 0.0, -2.0])
    a, b = motion_frames(pos, FPS), motion_frames(turned, FPS)
    assert np.allclose(a, b, atol=1e-4)
    moved = motion_frames(pos * np.array([1.0, 1.0, 1.5]), FPS)  # a different motion is read differently
    assert not np.allclose(a, moved, atol=1e-2)


def test_a_bars_points_are_spread_evenly_over_its_beats() -> None:
    pts = bar_points(np.array([[0.0, 10.0, 30.0]]))[0]  # two beats: the first 10 frames long, the second 20
    half = SAMPLES // 2
    assert np.allclose(pts[:half], np.arange(half) * 10.0 / half)
    assert np.allclose(pts[half:], 10.0 + np.arange(half) * 20.0 / half)


def test_a_bar_of_music_reads_its_neighbours() -> None:
    music = song(20, 120)
    bars = [music.beat_times[k : k + 5] for k in range(0, 24, 4)]
    alone, wide = music_bars(music.features, bars, 0), music_bars(music.features, bars, 1)
    d = alone.shape[1]
    assert wide.shape == (len(bars), 3 * d)
    assert np.array_equal(wide[2], np.concatenate([alone[1], alone[2], alone[3]]))
    assert np.array_equal(wide[0, :d], alone[0])  # the song's first bar stands in for the one before it


def _made_up_model(music_dim: int, motion_dim: int, seed: int = 0) -> MatchModel:
    rng = np.random.default_rng(seed)

    def layers(dim: int) -> list[tuple[np.ndarray, np.ndarray]]:
        return [(rng.normal(0, 0.1, (16, dim)).astype(np.float32), np.zeros(16, np.float32)),
                (rng.normal(0, 0.3, (8, 16)).astype(np.float32), np.zeros(8, np.float32))]

    return MatchModel(np.zeros(music_dim, np.float32), np.ones(music_dim, np.float32),
                      np.zeros(motion_dim, np.float32), np.ones(motion_dim, np.float32),
                      layers(music_dim), layers(motion_dim), {"context": 0})


def test_weights_are_read_back_and_a_bad_file_is_one_line(tmp_path: Path) -> None:
    model = _made_up_model(5, 7)
    model.save(tmp_path / "m.npz")
    back = MatchModel.load(tmp_path / "m.npz")
    x = np.random.default_rng(1).normal(size=(4, 7)).astype(np.float32)
    assert np.allclose(back.embed_motion(x), model.embed_motion(x), atol=2e-3)  # weights stored as float16
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(DanceNetError) as e:
        MatchModel.load(tmp_path / "bad.npz")
    assert "dancenet train match" in str(e.value) and "\n" not in str(e.value)


def test_the_shipped_weights_embed_a_song_and_a_dance() -> None:
    model = MatchModel.load()
    music = song(30, 110)
    bars = [music.beat_times[k : k + 5] for k in range(0, 40, 4)]
    em = model.embed_music(music_bars(music.features, bars, model.context))
    frames = motion_frames(dancer(30, 110).positions()[:, :BODY_JOINTS], FPS)
    beat_frames = np.array([(b - 0.3) * FPS + 5 for b in bars])
    ed = model.embed_motion(motion_bars(frames, beat_frames, FPS))
    assert em.shape == ed.shape == (10, model.meta["dim"])
    assert np.allclose(np.linalg.norm(em, axis=1), 1.0, atol=1e-5)
    assert np.allclose(np.linalg.norm(ed, axis=1), 1.0, atol=1e-5)
    assert model.meta["figures"]["held_out"] == "test"  # the card's figures travel with the weights


class _Prefers:
    """A stand-in for the match that likes one clip's figures only."""

    def __init__(self, library: MotionLibrary, clip: int) -> None:
        self.library, self.clip = library, clip

    def fit(self, bar: int, starts: np.ndarray, ratios: np.ndarray, beats: int) -> np.ndarray:
        return np.where(self.library.beat_clip[beat_index(starts)] == self.clip, 1.0, -1.0)

    def style_away(self, starts: np.ndarray, ratios: np.ndarray, beats: int) -> np.ndarray:
        return np.zeros(len(starts))


def test_the_plan_takes_the_figures_the_match_prefers(library: MotionLibrary, monkeypatch: pytest.MonkeyPatch
                                                      ) -> None:
    music = song(40, 110)
    plain = choreograph(library, music, seed=0)[0]
    assert len({f["clip"] for f in plain.report.figures}) > 1
    monkeypatch.setattr("dancenet_core.library.choreography.FigureMatch", lambda *a: _Prefers(library, 2))
    model = _made_up_model(1, 1)  # not read by the stand-in
    matched = choreograph(library, music, seed=0, settings=Settings(match=20.0, match_style=0.0), match=model)[0]
    assert {f["clip"] for f in matched.report.figures} == {"clip2"}


class _OfStyle(_Prefers):
    """A stand-in for the match whose part sounds like one clip's style only."""

    def style_away(self, starts: np.ndarray, ratios: np.ndarray, beats: int) -> np.ndarray:
        return np.where(self.library.beat_clip[beat_index(starts)] == self.clip, 0.0, 1.0)


def test_the_plan_keeps_to_the_style_the_match_hears(library: MotionLibrary, monkeypatch: pytest.MonkeyPatch
                                                     ) -> None:
    monkeypatch.setattr("dancenet_core.library.choreography.FigureMatch", lambda *a: _OfStyle(library, 1))
    dance = choreograph(library, song(40, 110), seed=0, match=_made_up_model(1, 1))[0]  # the default settings
    assert {f["clip"] for f in dance.report.figures} == {"clip1"}


def test_the_real_match_scores_every_figure(library: MotionLibrary) -> None:
    model = MatchModel.load()
    music = song(20, 110)
    bars = [music.beat_times[k : k + 5] for k in range(0, 28, 4)]
    fit = FigureMatch(model, library, music.features, bars)
    starts = np.flatnonzero(library.downbeat)[:-4]
    ratios = np.ones(len(starts))
    s = fit.fit(3, starts, ratios, 4)
    assert s.shape == (len(starts),) and np.all(np.abs(s) <= 1.0 + 1e-6) and np.ptp(s) > 0
    assert np.array_equal(fit.fit(3, starts, ratios, 4), s)
    away = fit.style_away(starts, ratios, 4)  # 1 - the part's probability of the clip's style over its top one
    assert np.all(away >= -1e-9) and np.all(away <= 1.0 + 1e-9)
    clips = library.beat_clip[starts]
    assert all(np.ptp(away[clips == c]) < 1e-9 for c in set(clips))  # a clip's figures share its style
    assert fit.song_style.max() == 1.0 and len(fit.song_style) == len(model.meta["styles"])


def test_the_engine_matches_a_library_without_style_labels_only(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                                                  ) -> None:
    """A folder of unsorted clips is danced with the shipped match (the real weights, end to end to the files); a
    folder sorted by style is danced as before, without it."""
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    used = []
    real = engine._load_match

    def counted() -> MatchModel:
        used.append(1)
        return real()

    monkeypatch.setattr(engine, "_load_match", counted)
    wav = click_song(tmp_path / "song.wav", 12, 110, bar=4)
    for name, sub in (("unsorted", ""), ("sorted", "salsa")):
        folder = tmp_path / name / sub
        folder.mkdir(parents=True)
        for k, bpm in enumerate((100, 110, 120)):
            write_bvh(folder / f"clip{k}.bvh", dancer(30, bpm, amplitude=0.3 + 0.1 * k, phase=k))
        assert _cli("library", "build", str(tmp_path / name)) == 0
        with np.load(library_path(tmp_path / name)) as built:  # the match's motion features, from the build
            assert ("match_frames" in built.files) == (name == "unsorted")
        out = tmp_path / f"out_{name}"
        assert _cli("generate", str(wav), "-o", str(out), "--engine", "library", "--library",
                    str(tmp_path / name)) == 0
        assert json.loads((out / "song.json").read_text())["takes_details"]
        assert len(used) == 1  # the unsorted folder, not the sorted one


def test_a_library_without_styles_is_loaded_with_the_matchs_motion_features(library: MotionLibrary,
                                                                            tmp_path: Path) -> None:
    """The build stores the match's features of a library whose clips name no style (the first dance from it
    skips the forward kinematics of the whole library); a sorted library, which the match never dances, does
    not carry them."""
    for styles, stored in (([""] * library.num_clips, True), (["salsa"] * library.num_clips, False)):
        path = tmp_path / f"{stored}.npz"
        build._saved(dataclasses.replace(library, styles=styles, match_frames=None), path)
        loaded = MotionLibrary.load(path)
        assert (loaded.match_frames is not None) == stored  # read from the file, not computed
        np.testing.assert_allclose(frames_of(loaded), library_frames(loaded), atol=1e-6)
        assert loaded.match_frames is not None  # computed once where the build did not store them, then kept


def test_the_own_style_share_counts_the_figures_seconds(library: MotionLibrary) -> None:
    from dancenet_core.evaluation.library_row import library_note
    from dancenet_core.evaluation.style_share import hidden, own_style_seconds

    labelled = dataclasses.replace(library, styles=["waltz", "tango", "waltz", "rumba"])
    assert hidden(labelled).styles == [""] * 4 and labelled.styles[0] == "waltz"
    figures = [{"clip": "clip0", "song_s": [0.0, 2.0]}, {"clip": "clip1", "song_s": [2.0, 3.0]},
               {"clip": "clip2", "song_s": [3.0, 6.0]}]
    style_of = dict(zip(labelled.names, labelled.styles, strict=True))
    assert own_style_seconds(figures, style_of, "waltz") == (5.0, 6.0)
    note = library_note({"library_unsorted": {"own_style_share": 0.5},
                         "library_unsorted_match": {"own_style_share": 0.8}})
    assert "energy matching alone 50.0%" in note and "learned match 80.0%" in note

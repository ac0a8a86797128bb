"""The clips users download, made up: clips of a few seconds (their tempo assumed), loops (danced around the loop),
in-place clips beside travelling ones, floor work (the floor under the body's lowest point), and a clip danced at
2/3 of the song's beats carried on from bar to bar; and how many clips a dance uses, and how evenly."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_clip_tempo import stepping
from test_library import dancer, song

from dancenet_core.bvh import write_bvh
from dancenet_core.commands.library import clip_table
from dancenet_core.library.analysis import MIN_READ_S, analyze_clip
from dancenet_core.library.build import build_library
from dancenet_core.library.choreography import (
    Settings,
    choreograph,
    clip_usage,
    clips_energy,
    dance_energy,
    plan,
    plan_at_clips_energy,
    song_grid,
)
from dancenet_core.library.loops import around_loop, loop_period
from dancenet_core.library.store import MotionLibrary
from dancenet_core.library.transitions import CUT_BLEND_S
from dancenet_core.motion import Motion
from dancenet_core.music.features import ONSET_COL
from dancenet_core.shaping.floor import floor_track, lowest_point
from dancenet_core.shaping.takes import shape_take
from dancenet_core.skeleton import BODY_JOINTS, JOINT_INDEX, TOE_ENDS

FPS = 25.0


def _library(*clips: tuple[str, Motion]) -> MotionLibrary:
    return MotionLibrary.from_clips([(name, "", m, analyze_clip(m)) for name, m in clips])


def test_a_clip_too_short_to_read_takes_the_librarys_tempo_and_says_so() -> None:
    short = stepping(3.0, 137, 4, seed=2)
    library = _library(("long_a", stepping(31, 96, 4)), ("long_b", stepping(31, 100, 4, seed=1)), ("short", short))
    c = library.names.index("short")
    assert short.duration < MIN_READ_S
    assert "tempo: assumed (the library's" in library.source[c] and library.confidence[c] == 0.0
    long_tempi = library.tempo_bpm[[library.names.index("long_a"), library.names.index("long_b")]]
    assert long_tempi.min() - 1e-6 <= library.tempo_bpm[c] <= long_tempi.max() + 1e-6
    assert library.meter[c] == 4 and "assumed" in clip_table(library).splitlines()[1 + c]
    for n in ("long_a", "long_b"):  # clips long enough keep what their motion says
        assert library.source[library.names.index(n)] == "tempo: motion, meter: motion"
    alone = _library(("short", short))  # no clip to take a tempo from: the reading's prior, said so
    assert alone.tempo_bpm[0] == pytest.approx(110.0) and "no clip long enough" in alone.source[0]


def _loop() -> Motion:
    """Two seconds of a dancer whose legs swing a cycle a second (two beats at 120 BPM) as she travels and turns
    slowly: her pose one frame after the last is the first (a clip that loops)."""
    return dancer(2.0, 120)


def test_a_loop_is_danced_around_the_loop() -> None:
    loop = _loop()
    assert loop_period(loop) == loop.num_frames
    repeated = Motion(np.concatenate([loop.rotations, loop.rotations[:1]]),
                      np.concatenate([loop.root_positions, loop.root_positions[-1:] + 0.014]), FPS)
    assert loop_period(repeated) == loop.num_frames  # an exporter's repeated last frame is dropped
    assert loop_period(dancer(2.3, 120)) is None  # a clip cut mid-figure is no loop
    around, turns = around_loop(loop, loop.num_frames)
    assert turns >= 2 and around.duration >= 16.0
    step = np.linalg.norm(np.diff(around.positions()[:, :BODY_JOINTS], axis=0), axis=-1).max(axis=1)
    own = np.linalg.norm(np.diff(loop.positions()[:, :BODY_JOINTS], axis=0), axis=-1).max(axis=1)
    assert step.max() <= 1.2 * own.max()  # no jump where one turn meets the next
    def path(m: Motion) -> float:
        return float(np.linalg.norm(np.diff(m.root_positions[:, [0, 2]], axis=0), axis=-1).sum())

    assert path(around) == pytest.approx(turns * path(loop), rel=0.05)  # it goes on travelling
    library = _library(("loop", loop), ("other", stepping(20, 118, 4, seed=3)))
    c = library.names.index("loop")
    assert "a loop of 2.0 s, danced" in library.source[c]
    assert library.clip(c).duration >= 16.0 and library.tempo_bpm[c] == pytest.approx(120, rel=0.08)
    dance = choreograph(library, song(30, 120), seed=0)[0]
    assert dance.report.max_warp <= 0.15 + 1e-6


def _on_the_hands(seconds: float) -> Motion:
    """Steps, then a handstand (upside down, arms straight down to the floor, the legs swinging), each with its lowest
    point on the floor: in the handstand the toes are the highest points, the hands the lowest."""
    steps = stepping(0.75 * seconds, 100, 4)
    t = np.arange(steps.num_frames) / FPS
    t = t[: int(0.25 * seconds * FPS)]
    rot = np.zeros((len(t), *steps.rotations.shape[1:]))
    rot[:, 0, 0] = np.pi
    rot[:, JOINT_INDEX["left_shoulder"], 2] = 1.3
    rot[:, JOINT_INDEX["right_shoulder"], 2] = -1.3
    rot[:, JOINT_INDEX["left_hip"], 0] = 0.4 * np.sin(2 * np.pi * t)
    root = np.stack([np.zeros_like(t), np.full_like(t, 1.0), steps.root_positions[-1, 2] + 0.1 * t], axis=1)
    hands = Motion(rot, root, FPS)
    for m in (steps, hands):
        m.root_positions[:, 1] -= lowest_point(m).min()
    return Motion(np.concatenate([steps.rotations, hands.rotations]),
                  np.concatenate([steps.root_positions, hands.root_positions]), FPS)


def test_floor_work_stays_on_the_floor(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The floor under a library clip is where the body's lowest point is: a handstand stands on its hands (by the
    toes, the body would be pushed under the floor); the paired dataset's floor stays the toes'."""
    clip = _on_the_hands(8.0)
    toes = clip.end_effectors()[:, list(TOE_ENDS), 1].min(axis=1)
    upside_down = slice(int(0.75 * clip.num_frames) + 1, None)
    assert (lowest_point(clip)[upside_down] < toes[upside_down] - 1.0).all()
    assert floor_track(clip)[upside_down].mean() > 0.8  # by the toes, the floor would be up at the feet
    assert np.abs(floor_track(clip, body=True)).max() < 0.03
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "clips"
    folder.mkdir()
    write_bvh(folder / "handstand.bvh", clip)
    write_bvh(folder / "steps.bvh", stepping(20, 100, 4))
    library, _ = build_library(folder, report=lambda _line: None)
    for c in range(library.num_clips):
        low = lowest_point(library.clip(c))
        assert low.min() > -0.03 and np.percentile(low, 5) < 0.02, library.names[c]


def _in_place(seconds: float, bpm: float) -> Motion:
    """A dancer stepping with the feet while the root stays over one spot (a clip exported "in place")."""
    m = dancer(seconds, bpm, amplitude=0.4)
    m.root_positions[:, [0, 2]] = 0.0
    return m


def test_in_place_and_travelling_clips_dance_together_in_either_root_mode() -> None:
    library = _library(("here", _in_place(30, 110)), ("there", dancer(30, 110, amplitude=0.35, phase=1.0)))
    dance = choreograph(library, song(40, 110, loud_from=20), seed=2)[0]
    assert {f["clip"] for f in dance.report.figures} == {"here", "there"}
    # no jump where one meets the other: each cut's steps within 20% of the clips' 99th percentile (or the clip's own)
    assert max(dance.report.cut_steps, default=0.0) <= 1.2
    travelled = shape_take(dance.motion, None, "travel")
    assert np.ptp(travelled.root_positions[:, [0, 2]], axis=0).max() > 1.0
    stayed = shape_take(dance.motion, None, "in-place")
    assert np.ptp(stayed.root_positions[:, [0, 2]], axis=0).max() < 0.05


def test_a_clip_at_two_thirds_of_the_songs_beats_is_carried_on_across_bars() -> None:
    """A clip stepped at 80 a minute on a 4/4 song at 120: two clip beats to three song beats, 8/3 clip beats a bar;
    the next bar carries on from between two of its beats instead of cutting every bar."""
    library = _library(("eighty", stepping(60, 80, 4)))
    dance = choreograph(library, song(40, 120), seed=0)[0]
    assert all(f["ratio"] == pytest.approx(2 / 3, abs=1e-3) for f in dance.report.figures)
    assert dance.report.longest_run_bars >= 3  # 8/3, 16/3, 8: only a figure started between two beats carries on
    assert dance.report.max_warp <= 0.15 + 1e-6


def test_how_many_clips_a_dance_uses_and_how_evenly() -> None:
    rows = [{"clip": c, "song_s": [a, b]} for c, a, b in (("a", 0, 2), ("b", 2, 4), ("a", 4, 6), ("b", 6, 8))]
    assert clip_usage(rows) == {"clips": 2, "effective_clips": 2.0}
    rows.append({"clip": "c", "song_s": [8, 8.2]})
    usage = clip_usage(rows)
    assert usage["clips"] == 3 and 2.0 < usage["effective_clips"] < 2.3  # a clip danced briefly counts little
    library = _library(*[(f"c{k}", dancer(30, 100 + 4 * k, amplitude=0.3 + 0.05 * k, phase=k)) for k in range(4)])
    summary = choreograph(library, song(40, 104), seed=1)[0].report.summary()
    assert 1.0 <= summary["effective_clips"] <= summary["clips"] <= 4


def test_the_dance_moves_as_fast_as_the_clips() -> None:
    """A library of calm clips and one lively one: with `energy_match` the plan's energy ranks are shifted until the
    dance's mean joint speed is the clips' (within 3%, or the nearest of its tries), whatever the joins prefer."""
    library = _library(*[(f"calm{k}", dancer(30, 100 + 5 * k, amplitude=0.2, phase=k)) for k in range(3)],
                       ("lively", dancer(30, 110, amplitude=0.7)))
    music = song(40, 108, loud_from=20)
    grid = song_grid(music, 0.0, 40.0)
    onset = music.features[:, ONSET_COL]
    target = clips_energy(library)
    for seed in range(3):
        fixed = plan(library, grid, onset, np.random.default_rng(seed), settings=Settings(energy_match=False))
        matched = plan_at_clips_energy(library, grid, onset, np.random.default_rng(seed), None,
                                       Settings(energy_match=True), None, None, None, None)
        off = abs(np.log(dance_energy(library, grid.beats, grid.bars, matched) / target))
        assert off <= abs(np.log(dance_energy(library, grid.beats, grid.bars, fixed) / target)) + 1e-9
        assert off <= np.log(1.06), (seed, off)


def _glitchy(seconds: float) -> Motion:
    """A dancer whose right forearm is thrown half a turn for one frame twice in the clip (a capture's glitch)."""
    m = dancer(seconds, 110, amplitude=0.5, phase=2.0)
    for at in (0.3, 0.7):
        m.rotations[int(at * m.num_frames), JOINT_INDEX["right_elbow"], 1] += 1.6
    return m


def test_no_joint_moves_faster_than_the_dancers_ever_do(monkeypatch: pytest.MonkeyPatch) -> None:
    """Figures whose joints, as the warp plays them, pass `PEAK_LIMIT` times their 99.9th percentile in the library
    are danced only where nothing else fits: the dance keeps every joint within 1.5 times it."""
    library = _library(*[(f"c{k}", dancer(40, 104 + 3 * k, amplitude=0.4 + 0.05 * k, phase=k)) for k in range(4)],
                       ("glitchy", _glitchy(40)))
    steps = library.joint_steps[library.joint_steps.sum(axis=1) > 0]
    p999 = np.percentile(steps, 99.9, axis=0)

    def fastest(seed: int) -> float:
        dance = choreograph(library, song(60, 110, loud_from=30), seed=seed)[0]
        made = np.linalg.norm(np.diff(dance.motion.positions()[:, :BODY_JOINTS], axis=0), axis=-1)
        return float((made / p999).max())

    assert max(fastest(s) for s in range(4)) <= 1.5
    monkeypatch.setattr("dancenet_core.library.choreography.PEAK_LIMIT", np.inf)
    assert max(fastest(s) for s in range(4)) > 1.5  # without the limit, the glitches are danced


def test_no_cut_in_the_last_frames_of_a_part() -> None:
    """A part that ends just after a downbeat: the figure before carries on into that last sliver of a bar rather
    than a cut the blend has no frames to fade (the dance would jump in its last frame), at one speed over both bars
    within the speed limit."""
    library = _library(*[(f"c{k}", dancer(30, 104 + 4 * k, amplitude=0.3 + 0.1 * k, phase=k)) for k in range(4)])
    music = song(20, 120)
    end = float(music.downbeat_times[4]) + 0.05
    for seed in range(4):
        dance = choreograph(library, music, seed=seed, end_s=end, settings=Settings(noise=2.0, cut=0.0))[0]
        frames = dance.motion.num_frames
        assert all(c < frames - CUT_BLEND_S * FPS for c in dance.report.cuts), (seed, dance.report.cuts, frames)
        assert dance.report.max_warp <= 0.15 + 1e-6  # the figure carried on within its speed limit

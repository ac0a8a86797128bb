"""The motion library engine on clips the tests make: a dancer swinging legs and arms and stepping
forward at a known tempo, so the beats, bars and cuts are known; and bad libraries, which answer in one line."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from made_up import click_song

from dancenet_core.beats import kinematic_velocity
from dancenet_core.bvh import BvhData, write_bvh, write_bvh_data
from dancenet_core.cli import main
from dancenet_core.evaluation.metrics import foot_sliding
from dancenet_core.generate import generate_dance
from dancenet_core.library.analysis import analyze_clip
from dancenet_core.library.build import build_library
from dancenet_core.library.choreography import LONG_RUN_BARS, LibraryDance, Settings, choreograph, song_grid
from dancenet_core.library.store import MotionLibrary, library_path
from dancenet_core.library.transitions import SINK_M, Figure, cut_steps, hold_stance, render
from dancenet_core.motion import Motion
from dancenet_core.music.features import FPS as MUSIC_FPS
from dancenet_core.music.features import N_FEATURES, ONSET_COL, MusicAnalysis
from dancenet_core.request import DanceRequest
from dancenet_core.shaping.floor import floor_track, lowest_point
from dancenet_core.shaping.takes import shape_takes
from dancenet_core.skeleton import BODY_JOINTS, DEFAULT_SKELETON, JOINT_INDEX, TOE_ENDS

FPS = 25.0


def dancer(seconds: float, bpm: float, fps: float = FPS, amplitude: float = 0.5, phase: float = 0.0) -> Motion:
    """Legs and arms swinging a full cycle every two beats (their speed dips at each beat), the pelvis bobbing and
    stepping forward with each beat."""
    t = np.arange(int(round(seconds * fps))) / fps
    w = np.pi * bpm / 60.0  # a cycle every two beats
    s = np.sin(w * t + phase)
    rot = np.zeros((len(t), DEFAULT_SKELETON.num_joints, 3))
    rot[:, JOINT_INDEX["left_hip"], 0] = amplitude * s
    rot[:, JOINT_INDEX["right_hip"], 0] = -amplitude * s
    rot[:, JOINT_INDEX["left_knee"], 0] = 0.3 * amplitude * (1 + s)
    rot[:, JOINT_INDEX["left_shoulder"], 2] = -1.2 + 0.4 * s
    rot[:, JOINT_INDEX["right_shoulder"], 2] = 1.2 + 0.4 * s
    rot[:, 0, 1] = 0.2 * np.sin(0.3 * t)  # a slow turn
    root = np.stack([0.05 * np.sin(w * t), 0.9 + 0.02 * np.cos(2 * w * t + 2 * phase),
                     0.4 * t - 0.4 / (2 * w) * np.sin(2 * w * t + 2 * phase)], axis=1)
    return Motion(rot, root, fps)


def song(seconds: float, bpm: float, meter: int = 4, loud_from: float | None = None) -> MusicAnalysis:
    """A song's analysis: beats from 0.3 s, a downbeat every `meter` beats, onsets on the beats (louder after
    `loud_from` seconds)."""
    beats = np.arange(0.3, seconds, 60.0 / bpm)
    n = int(seconds * MUSIC_FPS)
    features = np.zeros((n, N_FEATURES), np.float32)
    frames = (beats * MUSIC_FPS).astype(int)
    features[frames[frames < n], ONSET_COL] = 1.0
    if loud_from is not None:
        features[int(loud_from * MUSIC_FPS) :, ONSET_COL] *= 3.0
    return MusicAnalysis(features, beats, beats[::meter], 60.0 / float(np.median(np.diff(beats))), seconds)


def library_of(*clips: tuple[str, Motion]) -> MotionLibrary:
    return MotionLibrary.from_clips([(name, "", m, analyze_clip(m)) for name, m in clips])


@pytest.fixture(scope="module")
def library() -> MotionLibrary:
    return library_of(*[(f"clip{k}", dancer(40, bpm, amplitude=0.3 + 0.1 * k, phase=k))
                        for k, bpm in enumerate((100, 110, 120, 104))])


def test_a_clips_beats_and_tempo_are_its_own() -> None:
    m = dancer(30, 120)
    a = analyze_clip(m)
    # its legs swing a cycle in two beats and nothing marks a bar: 120 or its half, which the plan dances alike
    assert min(abs(a.tempo_bpm / 120 * k - 1) for k in (1, 2)) <= 0.05
    speed = np.convolve(kinematic_velocity(m.positions()[:, :BODY_JOINTS]), np.ones(3) / 3, "same")
    at = np.round(a.beats[1:-1]).astype(int)
    assert (speed[at] < np.median(speed)).mean() > 0.9  # cut where the dancer's speed dips
    assert a.meter in (3, 4) and a.downbeat[a.downbeat.argmax() :: a.meter].all()
    assert a.features.shape == (len(a.beats), a.features.shape[1]) and np.isfinite(a.features).all()


def test_figures_start_on_the_songs_downbeats(library: MotionLibrary) -> None:
    music = song(60, 108)
    dance = choreograph(library, music, seed=1, start_s=0.0, end_s=60.0)[0]
    assert dance.motion.num_frames == 60 * FPS
    downs = music.downbeat_times
    starts = np.array([f["song_s"][0] for f in dance.report.figures[1:]])  # the first starts with the part
    assert np.abs(starts[:, None] - downs[None]).min(axis=1).max() <= 1.0 / FPS
    assert dance.report.max_warp <= 0.15 + 1e-6


def test_no_joint_jumps_at_a_cut(library: MotionLibrary) -> None:
    dance = choreograph(library, song(90, 112), seed=3, settings=Settings(noise=1.0))[0]
    assert dance.report.cuts, "the plan should cut between clips"
    steps = [np.linalg.norm(np.diff(library.clip(c).positions()[:, :BODY_JOINTS], axis=0), axis=-1)
             for c in range(library.num_clips)]
    p99 = np.percentile(np.concatenate(steps), 99, axis=0)
    step = np.linalg.norm(np.diff(dance.motion.positions()[:, :BODY_JOINTS], axis=0), axis=-1)
    at_cuts = np.concatenate([step[c - 1 : c + 11] for c in dance.report.cuts])
    assert (at_cuts <= 1.2 * p99).all()  # the capture's 99th percentile, with a 20% margin for the warp


def test_the_cut_report_sees_a_jump(library: MotionLibrary) -> None:
    """Each cut's reported step (`cut_steps`): about the percentile or the source clip's own step at most for the
    dances the engine plans (5% margin: the blend's search stops at 1 before the hold and another CPU's rounding);
    a jump of the body at a cut shows."""
    dance = choreograph(library, song(90, 112), seed=3, settings=Settings(noise=1.0))[0]
    assert dance.report.cuts and max(dance.report.cut_steps) <= 1.05
    rendered = render(library, [Figure(s, 4, 0.3 + np.arange(5) * 60 / 112 + 4 * k * 60 / 112)
                                for k, s in enumerate((0, 40, 90, 8))], 0.3, 8.0)
    assert len(rendered.cuts) == 3 and max(cut_steps(rendered)) < 1.5
    rendered.motion.root_positions[rendered.cuts[1] :, 2] += 0.1  # 10 cm forward in one frame
    assert cut_steps(rendered)[1] > 2.0


def test_without_blending_a_cut_would_jump(library: MotionLibrary) -> None:
    """The test above can fail: the clips differ enough that a hard cut jumps past the capture's steps."""
    a, b = library.clip(0).positions()[:, :BODY_JOINTS], library.clip(3).positions()[:, :BODY_JOINTS]
    p99 = np.percentile(np.linalg.norm(np.diff(a, axis=0), axis=-1), 99, axis=0)
    rel = (b[200] - b[200, :1]) - (a[100] - a[100, :1])
    assert (np.linalg.norm(rel, axis=-1) > 1.2 * p99).any()


def test_seeds_give_different_dances_and_a_seed_the_same(library: MotionLibrary) -> None:
    music = song(40, 110)
    one, again = (choreograph(library, music, seed=5)[0] for _ in range(2))
    other = choreograph(library, music, seed=6)[0]
    assert np.array_equal(one.motion.rotations, again.motion.rotations)
    assert not np.allclose(one.motion.rotations, other.motion.rotations)


def test_the_copied_run_report_adds_up(library: MotionLibrary) -> None:
    one_clip = library_of(("long", dancer(120, 110)))
    # no noise, and no energy to match (a click track's bars differ only by rounding, which ranks would spread)
    dance = choreograph(one_clip, song(60, 110), seed=0, settings=Settings(noise=0.0, energy=0.0))[0]
    r = dance.report
    assert r.longest_run_bars > LONG_RUN_BARS and r.long_run_share > 0.8  # one clip, played straight through
    mixed = choreograph(library, song(60, 110), seed=0, settings=Settings(noise=2.0))[0].report
    assert mixed.long_run_share < r.long_run_share
    assert len(mixed.figures) == len(song_grid(song(60, 110), 0.0, 60.0).bars)
    for rep in (r, mixed):  # the figures listed add up to the runs reported
        runs = _runs(rep.figures)
        assert rep.long_run_share == pytest.approx(sum(s for b, s in runs if b > LONG_RUN_BARS) / 60.0, abs=1e-3)
        longest = max(runs, key=lambda run: run[1])
        assert (rep.longest_run_bars, rep.longest_run_s) == (longest[0], pytest.approx(longest[1], abs=1e-3))
        assert 0.0 < rep.max_warp <= 0.15  # the engine's cap (choreography.WARP_RANGE)


def _runs(figures: list[dict]) -> list[tuple[int, float]]:
    """(figures, song seconds) of each run of one clip: a figure runs on where the one before it ended in the clip."""
    runs: list[tuple[int, float]] = []
    for k, f in enumerate(figures):
        seconds = f["song_s"][1] - f["song_s"][0]
        if k and f["clip"] == figures[k - 1]["clip"] and f["clip_s"][0] == figures[k - 1]["clip_s"][1]:
            runs[-1] = (runs[-1][0] + 1, runs[-1][1] + seconds)
        else:
            runs.append((1, seconds))
    return runs


def test_the_dance_follows_the_musics_energy(library: MotionLibrary) -> None:
    """Loud bars take the library's energetic figures."""
    dance = choreograph(library, song(80, 110, loud_from=40), seed=0, settings=Settings(noise=0.0))[0]
    speed = kinematic_velocity(dance.motion.positions()[:, :BODY_JOINTS])
    half = dance.motion.num_frames // 2
    assert speed[half:].mean() > speed[:half].mean()


def test_the_root_path_carries_on_across_cuts(library: MotionLibrary) -> None:
    dance = choreograph(library, song(60, 110), seed=2, settings=Settings(noise=1.0))[0]
    step = np.linalg.norm(np.diff(dance.motion.root_positions[:, [0, 2]], axis=0), axis=-1)
    assert step.max() < 3 * np.percentile(step, 95)
    assert np.linalg.norm(dance.motion.root_positions[-1, [0, 2]]) > 5.0  # it travels, cut after cut


def _cli(*args: str) -> int:
    return main(list(args))


def test_bad_libraries_answer_in_one_line_or_dance(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                   capsys: pytest.CaptureFixture) -> None:
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    empty = tmp_path / "empty"
    empty.mkdir()
    assert _cli("library", "build", str(empty)) == 2
    assert "no BVH clips" in capsys.readouterr().err

    short = tmp_path / "short"
    short.mkdir()
    write_bvh(short / "two_seconds.bvh", dancer(2, 110))
    assert _cli("library", "build", str(short)) == 0  # built; too short for a figure is said when dancing
    library, _ = build_library(short)
    with pytest.raises(Exception, match="no clip with 5 beats or more"):
        choreograph(library, song(20, 110))

    odd = tmp_path / "odd"
    odd.mkdir()
    write_bvh_data(odd / "snake.bvh", BvhData(("a", "b", "c"), (-1, 0, 1), np.eye(3), (
        ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"),
        ("Zrotation", "Xrotation", "Yrotation"), ("Zrotation", "Xrotation", "Yrotation")), (), 0.04,
        np.zeros((50, 12))))
    capsys.readouterr()
    assert _cli("library", "build", str(odd)) == 2
    err = capsys.readouterr().err
    assert "snake.bvh: not a humanoid skeleton (3 bones: a, b, c): no legs; no arms; no bone for pelvis, neck, " \
           "head; name its bones in a bone map" in err and len(err.strip().splitlines()) == 1

    mixed = tmp_path / "mixed"
    (mixed / "waltz").mkdir(parents=True)
    write_bvh(mixed / "waltz" / "at30.bvh", dancer(20, 100).resampled(30))
    write_bvh(mixed / "waltz" / "at60_cm.bvh", dancer(20, 100, phase=1.0).resampled(60), scale=100.0)
    write_bvh_data(mixed / "snake.bvh", BvhData(("a", "b"), (-1, 0), np.eye(3)[:2], (
        ("Xposition", "Yposition", "Zposition"), ("Zrotation",)), (), 0.04, np.zeros((5, 4))))
    assert _cli("library", "build", str(mixed)) == 0
    library, _ = build_library(mixed)
    assert library.num_clips == 2 and library.styles == ["waltz", "waltz"] and len(library.notes) == 1
    assert library.fps == FPS and library.duration_s == pytest.approx(40, abs=0.2)
    heights = library.root_positions[:, 1]
    assert heights.min() > 0.7 and heights.max() < 1.1  # the centimetre clip read in metres
    dance = choreograph(library, song(30, 100, meter=3), seed=0, style="waltz")[0]
    assert dance.motion.num_frames == 30 * FPS


def test_a_z_up_clip_is_turned_upright(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    m = dancer(10, 110)
    rot = m.rotations.copy()
    from scipy.spatial.transform import Rotation

    turn = Rotation.from_euler("x", 90, degrees=True)  # Y up -> Z up
    rot[:, 0] = (turn * Rotation.from_rotvec(rot[:, 0])).as_rotvec()
    (tmp_path / "z").mkdir()
    write_bvh(tmp_path / "z" / "z_up.bvh", Motion(rot, turn.apply(m.root_positions), m.fps))
    library, _ = build_library(tmp_path / "z")
    pos = library.clip(0).positions()
    assert (pos[:, JOINT_INDEX["head"], 1] > pos[:, 0, 1]).all()


def test_a_dance_from_the_real_capture(shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Two training waltzes of Dance with Melody as the library, one of its songs' analysis as the music."""
    pytest.importorskip("torch")  # the capture's skeleton fit (data/fit.py); Blender 5.2's stack has none
    from dancenet_core.beats import motion_beats
    from dancenet_core.data.dance_with_melody import load_positions, read_manifest
    from dancenet_core.data.fit import fit_sequence

    seqs = {s.seq: s for s in read_manifest(shared_data)}
    clips = []
    for seq in ("DANCE_W_1", "DANCE_W_4"):
        motion, _ = fit_sequence(load_positions(seqs[seq])[:750], seqs[seq].fps, steps=20)
        clips.append((seq, "waltz", motion, analyze_clip(motion, "waltz")))
    library = MotionLibrary.from_clips(clips)
    music = song(30, 88, meter=3)
    dance = choreograph(library, music, seed=0)[0]
    beats = motion_beats(dance.motion.positions()[:, :BODY_JOINTS], FPS) / FPS
    assert dance.motion.num_frames == 30 * FPS and len(beats) > 10


def stander(seconds: float, bpm: float, drift_mps: float, phase: float = 0.0, lean: float = 0.0) -> Motion:
    """Arms swinging a full cycle every two beats while both feet stand, the legs leaning `lean` rad forward, the
    whole body creeping forward at `drift_mps` (a capture whose standing feet slide)."""
    t = np.arange(int(round(seconds * FPS))) / FPS
    s = np.sin(np.pi * bpm / 60.0 * t + phase)
    rot = np.zeros((len(t), DEFAULT_SKELETON.num_joints, 3))
    rot[:, JOINT_INDEX["left_shoulder"], 2] = -1.0 + 0.6 * s
    rot[:, JOINT_INDEX["right_shoulder"], 2] = 1.0 + 0.6 * s
    rot[:, JOINT_INDEX["left_elbow"], 1] = 0.8 * s
    rot[:, [JOINT_INDEX["left_hip"], JOINT_INDEX["right_hip"]], 0] = lean
    root = np.stack([np.zeros_like(t), np.full_like(t, 0.9), drift_mps * t], axis=1)
    return Motion(rot, root, FPS)


def slide_ratio(motion: Motion) -> float:
    return foot_sliding(motion.end_effectors()[:, list(TOE_ENDS)], motion.fps).slide_ratio


def test_a_standing_foot_is_held() -> None:
    m = stander(10, 110, drift_mps=0.4)
    assert slide_ratio(m) > 0.9  # the capture's feet slide (the test can fail)
    stance = np.ones((m.num_frames - 1, 2), bool)
    held = Motion(m.rotations, hold_stance(m, stance), m.fps, m.skeleton)
    assert slide_ratio(held) < 0.05
    assert np.allclose(held.root_positions[:, 1], m.root_positions[:, 1])  # only moved on the floor


def test_the_hold_moves_no_joint_past_its_limit() -> None:
    """Carrying the body after a creeping foot adds the creep to every joint's step: with a limit per joint, the
    hold gives up just enough of its correction at the frames where that would pass the limit."""
    m = stander(10, 110, drift_mps=0.0)
    t = np.arange(m.num_frames) / FPS
    for hip in ("left_hip", "right_hip"):  # both legs swing the standing feet to and fro
        m.rotations[:, JOINT_INDEX[hip], 0] = 0.3 * np.sin(2 * np.pi * t)
    stance = np.ones((m.num_frames - 1, 2), bool)
    own = np.linalg.norm(np.diff(m.positions()[:, :BODY_JOINTS], axis=0), axis=-1)
    limit = np.maximum(own.max(axis=0), 0.02)  # the motion itself stays within it
    held = Motion(m.rotations, hold_stance(m, stance), m.fps, m.skeleton)
    free = np.linalg.norm(np.diff(held.positions()[:, :BODY_JOINTS], axis=0), axis=-1)
    assert (free / limit).max() > 1.2  # unlimited, the hold passes it (the test can fail)
    limited = Motion(m.rotations, hold_stance(m, stance, limit), m.fps, m.skeleton)
    steps = np.linalg.norm(np.diff(limited.positions()[:, :BODY_JOINTS], axis=0), axis=-1)
    assert (steps / limit).max() <= 1.0 + 1e-9
    # and it still holds the feet as far as the limit lets it: a quarter of their travel taken away
    assert toe_travel(limited) < 0.8 * toe_travel(m)


def toe_travel(motion: Motion) -> float:
    toes = motion.end_effectors()[:, list(TOE_ENDS)]
    return float(np.linalg.norm(np.diff(toes[:, :, [0, 2]], axis=0), axis=-1).sum())


def standers_dance(drift_mps: float) -> tuple[MotionLibrary, LibraryDance]:
    """A library of three standers (`stander`: other tempi, legs leaning differently, the body creeping at
    `drift_mps`) and a dance from it whose plan cuts between them."""
    lib = library_of(*[(f"stand{k}", stander(30, bpm, drift_mps=drift_mps, phase=2.0 * k, lean=0.15 * k))
                       for k, bpm in enumerate((100, 112, 120))])
    dance = choreograph(lib, song(40, 108), seed=2, settings=Settings(noise=1.0))[0]
    assert dance.report.cuts, "the plan should cut between clips"
    return lib, dance


def test_standing_feet_stay_put_across_cuts() -> None:
    """A dance cut from clips whose feet stand still (hand-keyed: not a millimetre) and whose legs lean differently (a
    blend moves the feet): the feet stay put, through the blends too."""
    _lib, dance = standers_dance(drift_mps=0.0)
    toes = dance.motion.end_effectors()[:, list(TOE_ENDS)]
    speed = np.linalg.norm(np.diff(toes[:, :, [0, 2]], axis=0), axis=-1) * FPS
    blends = np.concatenate([np.arange(c - 1, min(c + 10, len(speed))) for c in dance.report.cuts])
    assert slide_ratio(dance.motion) < 0.1
    assert np.percentile(speed[blends], 90) < 0.25  # the metric's sliding speed


def test_a_clips_own_creep_is_kept() -> None:
    """A standing foot that creeps in its clip (a dancer's swivel, the capture's drift) creeps as much in the dance:
    the hold takes back only what a blend adds, so away from the cuts the body travels with the clip."""
    lib, dance = standers_dance(drift_mps=0.4)
    assert min(slide_ratio(lib.clip(c)) for c in range(lib.num_clips)) > 0.9
    root = dance.motion.root_positions[:, [0, 2]]
    speed = np.linalg.norm(np.diff(root, axis=0), axis=-1) * FPS
    away = np.ones(len(speed), bool)
    for c, m in zip(dance.report.cuts, dance.report.blends, strict=True):
        away[max(c - 5, 0) : c + m + 5] = False
    assert away.sum() > 0.3 * len(speed)
    # the clips' 0.4 m/s, played within the time-warp's range (held still, it would be near 0)
    assert 0.3 < np.median(speed[away]) < 0.5


def test_a_blend_does_not_take_the_body_through_the_floor() -> None:
    """Two clips on the floor, one upright and one leaning its legs far forward: halfway through a blend the root
    stands between the two heights while the legs lean half as far, a foot some centimetres under the floor that
    neither clip puts there. The body is lifted where it sinks past `SINK_M`."""
    clips = []
    for k, lean in enumerate((0.0, 0.8)):
        m = stander(30, 110, drift_mps=0.0, phase=2.0 * k, lean=lean)
        m.root_positions[:, 1] -= floor_track(m, body=True)
        clips.append((f"lean{k}", m))
    lib = library_of(*clips)
    assert min(lowest_point(lib.clip(c)).min() for c in range(lib.num_clips)) > -0.01
    # poses weigh nothing at a cut: the plan cuts between the two
    dance = choreograph(lib, song(40, 110), seed=2, settings=Settings(noise=1.0, pose=0.0, velocity=0.0))[0]
    assert {f["clip"] for f in dance.report.figures} == {"lean0", "lean1"}
    assert lowest_point(dance.motion).min() >= -SINK_M - 1e-6


def test_generate_reports_the_copied_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                          capsys: pytest.CaptureFixture) -> None:
    """`dancenet generate --engine library` prints and records each take's copied-run figures."""
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "clips"
    folder.mkdir()
    write_bvh(folder / "long.bvh", dancer(60, 110))
    assert _cli("library", "build", str(folder)) == 0
    wav = click_song(tmp_path / "song.wav", 12, 110, bar=4)
    out = tmp_path / "out"
    capsys.readouterr()
    assert _cli("generate", str(wav), "-o", str(out), "--engine", "library", "--library", str(folder),
                "--takes", "2") == 0
    printed = capsys.readouterr().out
    details = json.loads((out / "song.json").read_text())["takes_details"]
    assert len(details) == 2
    bar_s = 4 * 60 / 110
    for k, d in enumerate(details, 1):  # what is recorded is what is printed, and the figures agree
        assert d["long_run_bars"] == LONG_RUN_BARS
        longest_share = d["longest_run_s"] / 12.0 if d["longest_run_bars"] > LONG_RUN_BARS else 0.0
        assert longest_share <= d["long_run_share"] <= (1.0 if longest_share else 0.0)  # the longest run counts
        assert d["longest_run_s"] == pytest.approx(d["longest_run_bars"] * bar_s, rel=0.06)  # bars of the song
        assert 0.0 < d["max_warp"] <= 0.15  # the engine's cap (choreography.WARP_RANGE)
        assert (f"song_take{k}: {d['long_run_share']:.0%} of frames from runs of one clip longer than 4 bars; "
                f"longest run {d['longest_run_bars']} bars ({d['longest_run_s']:.1f} s); played within "
                f"{d['max_warp']:.0%} of its captured speed") in printed


def test_continue_from_here_keeps_the_kept_frames_and_joins_without_a_jump(tmp_path: Path,
                                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """A library take continued at 6 s: its frames before 6 s unchanged, no joint jumps at the join (the cut
    test's bound), and different seeds dance the rest differently."""
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "clips"
    folder.mkdir()
    for k, bpm in enumerate((100, 110, 120, 104)):
        write_bvh(folder / f"clip{k}.bvh", dancer(40, bpm, amplitude=0.3 + 0.1 * k, phase=k))
    library, _ = build_library(folder)
    wav = click_song(tmp_path / "song.wav", 20, 110, bar=4)

    def takes(seed: int, kept: Motion | None = None, at_s: float = 0.0) -> list[Motion]:
        request = DanceRequest(wav, engine="library", library=folder, seed=seed, continue_from=kept, at_s=at_s)
        return shape_takes(generate_dance(request).motions, request)

    (first,) = takes(0)
    one, other = (takes(seed, first, 6.0)[0] for seed in (1, 2))
    j = int(round(6.0 * first.fps))
    for m in (one, other):
        assert m.num_frames == first.num_frames
        assert np.array_equal(m.rotations[:j], first.rotations[:j])
        assert np.array_equal(m.root_positions[:j], first.root_positions[:j])
    steps = [np.linalg.norm(np.diff(library.clip(c).positions()[:, :BODY_JOINTS], axis=0), axis=-1)
             for c in range(library.num_clips)]
    largest = np.concatenate(steps).max(axis=0)
    for m in (one, other):
        step = np.linalg.norm(np.diff(m.positions()[:, :BODY_JOINTS], axis=0), axis=-1)
        assert (step[j - 2 : j + 12] <= 1.2 * largest).all()
    assert not np.allclose(one.rotations[j:], other.rotations[j:])
    assert not np.allclose(one.rotations[j:], first.rotations[j:])


@pytest.mark.skipif(os.name != "posix" or sys.platform == "darwin", reason="a name that is not UTF-8 needs a file "
                    "system that stores bytes")
def test_a_clip_whose_name_is_not_utf8_is_built_and_named_as_it_is(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """A Latin-1 `caf\\xe9.bvh` from an old archive: the folder's content key hashes the name's bytes (no
    UnicodeEncodeError), and the clip keeps its name."""
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "old archive"
    folder.mkdir()
    write_bvh(folder / os.fsdecode(b"caf\xe9.bvh"), dancer(20, 100))
    write_bvh(folder / "two.bvh", dancer(20, 110, phase=1.0))
    library, path = build_library(folder, report=lambda _line: None)
    assert sorted(library.names) == sorted([os.fsdecode(b"caf\xe9.bvh"), "two.bvh"]) and path.is_file()
    (folder / os.fsdecode(b"caf\xe9.bvh")).rename(folder / "cafe.bvh")  # another name: another library
    assert not library_path(folder).is_file()


@pytest.mark.skipif(os.name != "posix" or sys.platform == "darwin", reason="a name that is not UTF-8 needs a file "
                    "system that stores bytes")
def test_a_clip_left_out_is_named_by_its_own_bytes(tmp_path: Path) -> None:
    """In a terminal whose output is strict UTF-8, the line about a Latin-1 clip that cannot be read shows its
    name's bytes as `ls` would, not a UnicodeEncodeError traceback."""
    folder = tmp_path / "old archive"
    folder.mkdir()
    (folder / os.fsdecode(b"caf\xe9.bvh")).write_text("not a clip")
    write_bvh(folder / "two.bvh", dancer(20, 110))
    env = os.environ | {"DANCENET_CACHE": str(tmp_path / "cache"), "PYTHONIOENCODING": "utf-8:strict"}
    out = subprocess.run([sys.executable, "-m", "dancenet_core.cli", "library", "build", str(folder)], env=env,
                         capture_output=True)
    assert out.returncode == 0 and b"Traceback" not in out.stderr, out.stderr.decode(errors="replace")
    assert b"left out " + os.fsencode(folder) + b"/caf\xe9.bvh" in out.stdout

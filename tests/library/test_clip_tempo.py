"""A clip's tempo and meter read from its motion alone, and a figure danced at its captured speed whatever the song's
tempo: made-up stepping figures at known tempi and meters, a song at twice a clip's tempo, and the manifest's
`bpm` and `meter`, which override what the motion says."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d
from test_library import song

from dancenet_core.bvh import write_bvh
from dancenet_core.cli import main
from dancenet_core.evaluation.metrics import mean_joint_speed
from dancenet_core.library.analysis import POSE_DIM, UNSURE, analyze_clip, bar_octave, frame_features, pose_return
from dancenet_core.library.build import build_library
from dancenet_core.library.choreography import WARP_RANGE, choreograph
from dancenet_core.library.store import MotionLibrary
from dancenet_core.motion import Motion
from dancenet_core.skeleton import BODY_JOINTS, DEFAULT_SKELETON, JOINT_INDEX

FPS = 25.0


def stepping(seconds: float, bpm: float, meter: int, seed: int = 0) -> Motion:
    """A step on every beat (the legs swing a full cycle in two beats, so the body's speed dips at each beat), the
    first of each bar the longest, and a figure of the arms and the body's rise and fall that takes one bar of
    `meter` beats: the pose comes back every bar (the legs every two beats), as a dancer's does."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(seconds * FPS))) / FPS
    beat = t * bpm / 60.0
    bar = 2 * np.pi * beat / meter
    legs = np.sin(np.pi * beat) * (1.0 + 0.3 * np.cos(bar))
    rot = np.zeros((len(t), DEFAULT_SKELETON.num_joints, 3))
    rot[:, JOINT_INDEX["left_hip"], 0] = 0.5 * legs
    rot[:, JOINT_INDEX["right_hip"], 0] = -0.5 * legs
    rot[:, JOINT_INDEX["left_knee"], 0] = 0.3 * (1 + np.abs(legs))
    rot[:, JOINT_INDEX["right_knee"], 0] = 0.3 * (1 + np.abs(legs))
    rot[:, JOINT_INDEX["left_shoulder"], 2] = -1.0 + 0.5 * np.sin(bar)
    rot[:, JOINT_INDEX["right_shoulder"], 2] = 1.0 + 0.5 * np.cos(bar)
    rot[:, JOINT_INDEX["left_elbow"], 1] = 0.6 * np.sin(bar + 1.0)
    rot[:, JOINT_INDEX["spine1"], 1] = 0.3 * np.sin(bar)
    rot += 0.01 * rng.standard_normal(rot.shape)
    step = 0.35 * bpm / 60.0  # 35 cm a beat
    root = np.stack([0.05 * np.sin(np.pi * beat), 0.9 - 0.04 * np.cos(bar), step * t], axis=1)
    return Motion(rot, root, FPS)


def same_tempo(read: float, bpm: float) -> bool:
    """Within 8% of `bpm`, its half or its double: a reading the plan's 2:1 and 1:2 figures dance at speed."""
    return min(abs(np.log(read / bpm * k)) for k in (0.5, 1.0, 2.0)) <= np.log(1.08)


def right_tempo(read: float, bpm: float) -> bool:
    """Within 8% of `bpm` itself: the octave right too."""
    return abs(np.log(read / bpm)) <= np.log(1.08)


def beatless(seconds: float, seed: int) -> Motion:
    """Joints turning smoothly at random (no step, no bar): a motion with no tempo to read."""
    rng = np.random.default_rng(seed)
    like = stepping(seconds, 90, 4)
    return Motion(gaussian_filter1d(rng.standard_normal(like.rotations.shape), 6, axis=0) * 2.0,
                  like.root_positions, FPS)


def test_stepping_figures_come_back_with_their_meter_and_tempo() -> None:
    """From the motion alone, and with the style's meter (a folder named waltz, rumba...), every figure's meter is
    its own and its tempo its own, the octave too: the steps fall once a beat and the arms' figure and the body's
    rise and fall take one bar. The 3/4 figures are the hard case: their pose comes back whole only every two bars
    (six beats), as a 4/4 bar at two thirds of the tempo would; the steps, one a beat, and the half-weighted return
    after one bar tell them apart. The one octave the motion leaves open: a 4/4 figure at 120 steps a minute is as
    well a figure of two bars at 60 with a step on every half beat (a cha-cha's "cha-cha"), and is read so; the plan
    lays either at the dancers' speed (`test_a_song_at_twice_a_clips_tempo_dances_it_at_its_own_speed`)."""
    for bpm in (60, 90, 120):
        for meter in (3, 4):
            clip = stepping(40, bpm, meter)
            tempo_ok = same_tempo if (bpm, meter) == (120, 4) else right_tempo
            told = analyze_clip(clip, style="waltz" if meter == 3 else "rumba")
            assert told.meter == meter and tempo_ok(told.tempo_bpm, bpm), (bpm, meter, told.tempo_bpm)
            free = analyze_clip(clip)
            assert free.meter == meter and tempo_ok(free.tempo_bpm, bpm), (bpm, meter, free.tempo_bpm)
            assert free.source == "tempo: motion, meter: motion"


def test_the_confidence_tells_a_steady_dancer_from_one_without_a_beat() -> None:
    """With the meter known (the clip's style), a steady stepping figure's tempo is sure (`UNSURE` or more: not
    named for the manifest) and a motion with no beat's is not."""
    for bpm, meter in ((60, 3), (90, 4), (120, 3)):
        style = "waltz" if meter == 3 else "rumba"
        steady = analyze_clip(stepping(40, bpm, meter), style=style)
        assert steady.confidence >= UNSURE, (bpm, meter, steady.confidence)
    for seed in range(3):
        for style in ("waltz", "rumba"):
            assert analyze_clip(beatless(40, seed), style=style).confidence < UNSURE, (seed, style)


def test_a_styles_meter_is_taken_and_said() -> None:
    a = analyze_clip(stepping(40, 90, 4), style="Waltz")
    assert a.meter == 3 and a.source == "tempo: motion, meter: style (Waltz)"


def test_a_song_at_twice_a_clips_tempo_dances_it_at_its_own_speed() -> None:
    clip = stepping(60, 60, 4)
    library = MotionLibrary.from_clips([("slow", "", clip, analyze_clip(clip))])
    dance = choreograph(library, song(40, 120), seed=0)[0]
    assert dance.report.max_warp <= WARP_RANGE + 1e-6
    played = {f["ratio"] for f in dance.report.figures}
    assert played <= {0.5, 1.0} and same_tempo(library.tempo_bpm[0] / min(played), 120)
    own = mean_joint_speed(clip.positions()[:, :BODY_JOINTS], FPS)
    danced = mean_joint_speed(dance.motion.positions()[:, :BODY_JOINTS], FPS)
    assert danced / own == pytest.approx(1.0, abs=WARP_RANGE)  # played two-for-one, it would be 2x


def test_the_manifest_gives_the_tempo_and_meter(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                capsys: pytest.CaptureFixture) -> None:
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "clips"
    folder.mkdir()
    write_bvh(folder / "a.bvh", stepping(30, 90, 4))
    write_bvh(folder / "b.bvh", stepping(30, 120, 4, seed=1))
    (folder / "manifest.csv").write_text("file,style,bpm,meter\na.bvh,rumba,100,3\nb.bvh,,,\n")
    assert main(["library", "build", str(folder)]) == 0
    out = capsys.readouterr().out
    assert "tempo: manifest, meter: manifest" in out and "tempo: motion, meter: motion" in out
    library, _ = build_library(folder)
    a, b = library.names.index("a.bvh"), library.names.index("b.bvh")
    assert library.meter[a] == 3 and library.tempo_bpm[a] == pytest.approx(100, rel=0.05)
    assert library.styles[a] == "rumba" and library.source[b] == "tempo: motion, meter: motion"
    assert same_tempo(library.tempo_bpm[b], 120)

    (folder / "manifest.csv").write_text("file,bpm\na.bvh,fast\n")
    assert main(["library", "build", str(folder)]) == 2
    err = capsys.readouterr().err.strip()
    assert "line 2: bpm 'fast' is not beats per minute" in err and len(err.splitlines()) == 1


def test_a_dancer_in_the_mirror_of_the_pose_one_bar_on_comes_back_as_the_mirror() -> None:
    """A figure led by the left leg one bar and the right the next (LRL, RLR): after one bar the legs' pose is the
    mirror of what it was, after two the pose itself, and `pose_return` says so (its mirror curve is how the
    analysis counts the one-bar return)."""
    bar_s = 2.0
    t = np.arange(int(round(16 * bar_s * FPS))) / FPS
    lead = np.sin(2 * np.pi * t / (2 * bar_s)) ** 3  # one leg leads for a bar, then the other
    rot = np.zeros((len(t), DEFAULT_SKELETON.num_joints, 3))
    for side, sign in (("left", 1.0), ("right", -1.0)):
        rot[:, JOINT_INDEX[f"{side}_hip"], 0] = 0.6 * sign * lead
        rot[:, JOINT_INDEX[f"{side}_knee"], 0] = 0.5 * np.clip(sign * lead, 0.0, None)
    root = np.stack([np.zeros_like(t), np.full_like(t, 0.9), 0.2 * t], axis=1)
    pose = frame_features(Motion(rot, root, FPS))[0][:, :POSE_DIM]
    bar = int(bar_s * FPS)
    same, mirrored = pose_return(pose, 3 * bar)
    assert mirrored[bar] > 0.9 and same[bar] < 0.5  # one bar on: the mirror, far from the pose itself
    assert same[2 * bar] > 0.9 and mirrored[2 * bar] < 0.5  # two bars on: the pose itself


def test_a_body_that_rises_and_falls_once_a_bar_is_read_at_its_bars_speed() -> None:
    """A waltz's rise and fall spans its bar: a reading at twice its tempo (as good to the plan, but with bars half
    the dancers') is halved, one at its tempo kept; a body that bobs once a beat keeps a reading at that beat (not
    halved to a bar of six beats)."""
    t = np.arange(int(40 * FPS)) / FPS
    beat = FPS * 60.0 / 90.0  # frames
    waltz = 0.9 - 0.05 * np.cos(2 * np.pi * t * 90.0 / 60.0 / 3)  # once a bar of three beats at 90 BPM
    assert bar_octave(beat / 2, 3, waltz - waltz.mean(), FPS) == pytest.approx(beat)
    assert bar_octave(beat, 3, waltz - waltz.mean(), FPS) == pytest.approx(beat)
    bob = 0.9 - 0.03 * np.cos(2 * np.pi * t * 90.0 / 60.0)  # once a beat
    assert bar_octave(beat, 3, bob - bob.mean(), FPS) == pytest.approx(beat)

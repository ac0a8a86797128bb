"""The song's form (music/form.py) and returns danced again (shaping/repeats.py), on made-up analyses and motions, and
with both engines on a song arranged A B A C A B from 8-bar sections of real training songs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dancenet_core.evaluation.form import body_poses, return_likeness
from dancenet_core.generate import generate_dance
from dancenet_core.motion import Motion
from dancenet_core.music.features import analyze_music
from dancenet_core.music.form import Section, SongForm, song_form
from dancenet_core.representation import heading_frames
from dancenet_core.request import DanceRequest
from dancenet_core.shaping.repeats import _copies, carry_on, dance_returns
from tests.made_up import analysis, arranged_training_song

BAR_FRAMES = 20  # 2-s bars at 10 fps: four beats of 0.5 s


def arranged_features(form: str, bars: int = 8, seed: int = 0) -> np.ndarray:
    """Features at 10 fps for sections in the order `form` (a letter per section of `bars` bars): each letter's
    bars have chroma and onsets of their own, the same each time the letter comes back (with a little noise)."""
    rng = np.random.default_rng(seed)
    music = {c: rng.random((bars * BAR_FRAMES, 15)) for c in sorted(set(form))}
    x = np.concatenate([music[c] + 0.05 * rng.random(music[c].shape) for c in form]).astype(np.float32)
    return x


def test_form_of_a_made_up_song_finds_its_sections_and_returns():
    form = song_form(analysis(arranged_features("ABACAB")))
    assert form.labels == "ABACAB"
    assert [s.name for s in form.sections] == ["A1", "B1", "A2", "C1", "A3", "B2"]
    assert [s.first_bar for s in form.sections] == [0, 8, 16, 24, 32, 40]
    assert all(s.match > 0.8 for s in form.sections)


def test_a_song_without_returns_is_danced_unchanged():
    form = song_form(analysis(arranged_features("ABCDEF")))
    assert len(set(form.labels)) == len(form.labels)  # nothing returns
    assert all(p.source_bar is None for p in form.phrases)
    motion = wandering_motion(form.bar_starts[-1])
    out, frame_map = dance_returns(motion, form, 0.0, "repeat")
    assert out is motion and np.array_equal(frame_map, np.arange(motion.num_frames))


def wandering_motion(seconds: float, fps: float = 25.0, seed: int = 0) -> Motion:
    """A smooth made-up dance that travels where it faces and turns: every joint's rotation a slow sine."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * fps))[:, None, None] / fps
    rot = 0.3 * np.sin(2 * np.pi * rng.uniform(0.2, 1.5, (1, 55, 3)) * t + rng.uniform(0, 6, (1, 55, 3)))
    tt = t[:, 0, 0]
    heading = 0.3 * tt + 0.5 * np.sin(0.7 * tt)
    rot[:, 0] = [0.0, 1.0, 0.0] * heading[:, None]
    speed = 0.5 + 0.2 * np.sin(1.3 * tt)  # forward, in the dancer's own frame
    step = np.stack([np.sin(heading) * speed, np.zeros_like(tt), np.cos(heading) * speed], -1) / fps
    root = np.cumsum(step, axis=0) + [0.0, 0.9, 0.0]
    root[:, 1] += 0.02 * np.sin(3 * tt)
    return Motion(rot, root, fps)


@pytest.mark.parametrize("mode", ["repeat", "mirror"])
def test_returns_are_danced_as_their_first_hearing_and_the_joins_do_not_jump(mode):
    form = song_form(analysis(arranged_features("ABACAB")))
    motion = wandering_motion(form.bar_starts[-1])
    out, _map = dance_returns(motion, form, 0.0, mode)
    fps = motion.fps
    source = motion.mirrored() if mode == "mirror" else motion
    poses, src_poses = body_poses(out.positions(), heading_frames(out)), body_poses(source.positions(),
                                                                                       heading_frames(source))
    a1, a2 = slice(int(2 * fps), int(14 * fps)), slice(int(34 * fps), int(46 * fps))  # inside, clear of the blends
    assert np.abs(poses[a2] - src_poses[a1]).max() < 1e-6  # A2's bars are A1's, pose for pose
    # The path on the floor and the heading never jump: no frame-to-frame step beyond the dance's own largest
    # (the hips' height follows the feet through a join, and this made-up dancer's feet fly about).
    step = np.linalg.norm(np.diff(out.root_positions[:, [0, 2]], axis=0), axis=1)
    own = np.linalg.norm(np.diff(motion.root_positions[:, [0, 2]], axis=0), axis=1)
    assert step.max() < 1.5 * own.max()
    assert np.abs(np.diff(heading_frames(out))).max() < 1.5 * np.abs(np.diff(heading_frames(motion))).max() + 0.02
    # Different sections stay as danced (B1 before any copy).
    assert np.allclose(out.rotations[int(17 * fps):int(31 * fps)], motion.rotations[int(17 * fps):int(31 * fps)])
    if mode == "repeat":
        assert return_likeness(out.positions(), heading_frames(out), fps, form) < 0.1
        assert return_likeness(motion.positions(), heading_frames(motion), fps, form) > 0.5


def test_a_join_between_dances_that_travel_different_ways_adds_no_slide():
    """Two dances facing the same way, one travelling sideways and one forwards at 1 m/s: through the crossfade
    the root travels no faster than either (a blend of their places would slide at up to 1.3 m/s)."""
    fps, t = 25.0, np.arange(200) / 25.0
    still = np.zeros((200, 55, 3))

    def travelling(direction: list[float]) -> Motion:
        return Motion(still, np.array([0.0, 0.9, 0.0]) + t[:, None] * direction, fps)

    joined = carry_on(travelling([1.0, 0.0, 0.0]), travelling([0.0, 0.0, 1.0]), 100)
    speed = np.linalg.norm(np.diff(joined.root_positions[:, [0, 2]], axis=0), axis=1) * fps
    assert speed.max() < 1.0 + 1e-6
    assert np.allclose(np.diff(joined.root_positions[-50:], axis=0) * fps, [0.0, 0.0, 1.0])  # then on as danced


def test_a_join_between_dances_that_turn_different_ways_adds_no_spin():
    """One dance turning left and one turning right, 1 rad/s each: through the crossfade the dancer turns no faster
    than either (a blend of their headings would spin at up to 1.8 rad/s), then on as the second turns."""
    fps, t = 25.0, np.arange(200) / 25.0

    def turning(rate: float) -> Motion:
        rot = np.zeros((200, 55, 3))
        rot[:, 0, 1] = rate * t
        return Motion(rot, np.tile([0.0, 0.9, 0.0], (200, 1)), fps)

    joined = carry_on(turning(1.0), turning(-1.0), 100)
    rate = np.diff(heading_frames(joined)) * fps
    assert np.abs(rate).max() < 1.0 + 1e-6
    assert np.allclose(rate[-50:], -1.0)
    ends = carry_on(turning(1.0), turning(-1.0), 190)  # the crossfade runs to the dance's last frame
    assert ends.num_frames == 200 and np.abs(np.diff(heading_frames(ends))[-10:] * fps).max() < 1.0 + 1e-6


def test_a_join_between_poses_half_a_turn_apart_turns_smoothly():
    """An elbow held still in one dance and turning through half a turn from it in the other (0.5 rad/s): through
    the crossfade it turns smoothly (choosing the short way frame by frame flipped it the other way round mid-blend,
    nearly a full turn in one frame)."""
    fps, t = 25.0, np.arange(200) / 25.0
    held = Motion(np.zeros((200, 55, 3)), np.tile([0.0, 0.9, 0.0], (200, 1)), fps)
    rot = np.zeros((200, 55, 3))
    rot[:, 18, 0] = np.pi - 0.3 + 0.5 * (t - t[100])  # half a turn from the held pose 0.6 s into the blend
    joined = carry_on(held, Motion(rot, held.root_positions, fps), 100)
    elbow = Rotation.from_rotvec(joined.rotations[:, 18])
    step = (elbow[1:] * elbow[:-1].inv()).magnitude()
    # Half a turn blended over 1.2 s with smoothstep weights: at most about 0.22 rad a frame, plus the dance's 0.02.
    assert step.max() < 0.3


def test_returns_before_a_continued_dances_join_are_left_as_danced():
    form = song_form(analysis(arranged_features("ABACAB")))
    motion = wandering_motion(form.bar_starts[-1])
    out, _map = dance_returns(motion, form, 0.0, "repeat", keep_until_s=40.0)  # A2 (32-48 s) starts before 40 s
    assert np.array_equal(out.rotations[: int(64 * motion.fps)], motion.rotations[: int(64 * motion.fps)])
    assert not np.allclose(out.rotations[int(66 * motion.fps):], motion.rotations[int(66 * motion.fps):])


def test_anew_leaves_the_dance_alone():
    form = song_form(analysis(arranged_features("ABACAB")))
    motion = wandering_motion(form.bar_starts[-1])
    out, _map = dance_returns(motion, form, 0.0, "anew")
    assert out is motion


@pytest.fixture(scope="module")
def arranged_song(tmp_path_factory) -> Path:
    path = arranged_training_song(tmp_path_factory.mktemp("form") / "abacab.wav")
    if path is None:
        pytest.skip("the Dance with Melody songs are not here")
    return path


def test_form_of_real_music_arranged_abacab(arranged_song):
    form = song_form(analyze_music(arranged_song))
    assert form.labels == "ABACAB"
    assert [s.bars for s in form.sections] == [8] * 6


@pytest.mark.parametrize("engine", ["dancenet", "library"])
def test_both_engines_dance_returns_again_with_the_real_model(arranged_song, engine):
    likeness = {}
    for mode in ("repeat", "anew"):
        result = generate_dance(DanceRequest(arranged_song, engine=engine, returns=mode, seed=1))
        m = result.motions[0]
        likeness[mode] = return_likeness(m.positions(), heading_frames(m), m.fps, result.form, result.start_s)
    assert likeness["repeat"] < 0.4, likeness
    assert likeness["anew"] > 0.6, likeness


def test_section_settings_parse_and_bad_ones_are_one_line():
    from dancenet_core.errors import DanceNetError
    from dancenet_core.request import SectionOverride

    assert SectionOverride.parse_many("A2:style=tango, energy=lively;B1:returns=anew") == (
        SectionOverride("A2", style="tango", energy="lively"), SectionOverride("B1", returns="anew"))
    assert str(SectionOverride("A2", energy="calm", returns="mirror")) == "A2:energy=calm,returns=mirror"
    for bad in ("A2", "A2:speed=3", ":style=tango", "A2:style="):
        with pytest.raises(DanceNetError) as info:
            SectionOverride.parse(bad)
        assert "\n" not in str(info.value) and "SECTION:key=value" in str(info.value)
    for sections in ((SectionOverride("A2", energy="wild"),), (SectionOverride("A2", returns="twice"),),
                     (SectionOverride("A2", energy="calm"), SectionOverride("A2", returns="anew"))):
        with pytest.raises(DanceNetError):
            DanceRequest(Path(__file__), sections=sections).check()


def test_a_section_with_settings_of_its_own_and_a_section_danced_again_with_the_real_model(arranged_song):
    from dancenet_core.errors import DanceNetError
    from dancenet_core.request import SectionOverride

    base = generate_dance(DanceRequest(arranged_song, seed=1))
    form, fps = base.form, base.motions[0].fps
    b1, c1 = (next(s for s in form.sections if s.name == n) for n in ("B1", "C1"))
    lively = generate_dance(DanceRequest(arranged_song, seed=1, sections=(SectionOverride("B1", energy="lively"),)))
    m, b = lively.motions[0], base.motions[0]
    before = slice(0, int(b1.start_s * fps))
    assert np.array_equal(m.rotations[before], b.rotations[before])  # A1 as it was
    inside = slice(int(b1.start_s * fps) + 10, int(b1.end_s * fps))
    speed = [np.linalg.norm(np.diff(x.positions()[inside], axis=0), axis=-1).mean() for x in (m, b)]
    assert speed[0] > speed[1]  # danced anew, livelier
    # B2 returns B1: it repeats the section as newly danced, not the old one.
    assert return_likeness(m.positions(), heading_frames(m), fps, form) < 0.4
    # One section danced anew in a kept dance: everything before it kept exactly, the section new.
    redo = generate_dance(DanceRequest(arranged_song, seed=9, continue_from=b, at_s=1.0, redo_section="C1"))
    r = redo.motions[0]
    assert r.num_frames == b.num_frames
    assert np.array_equal(r.rotations[: int(c1.start_s * fps)], b.rotations[: int(c1.start_s * fps)])
    assert not np.allclose(r.rotations[int(c1.start_s * fps) + 10:int(c1.end_s * fps)],
                           b.rotations[int(c1.start_s * fps) + 10:int(c1.end_s * fps)], atol=0.05)
    with pytest.raises(DanceNetError, match="has no section 'Z9'; its sections are A1, B1"):
        generate_dance(DanceRequest(arranged_song, sections=(SectionOverride("Z9", energy="calm"),)))


def test_the_command_line_reads_the_form_and_draws_it(arranged_song, tmp_path, capsys):
    import json

    from dancenet_core.cli import main

    assert main(["analyze", str(arranged_song), "--json", str(tmp_path / "a.json")]) == 0
    assert "form:      A1 0.0s B1 " in capsys.readouterr().out
    form = json.loads((tmp_path / "a.json").read_text())["form"]
    assert form["labels"] == "ABACAB" and [s["bars"] for s in form["sections"]] == [8] * 6
    assert main(["generate", str(arranged_song), "-o", str(tmp_path / "out"), "--form-plot", "--returns",
                 "mirror", "--section", "C1:energy=calm"]) == 0
    summary = json.loads((tmp_path / "out" / "abacab.json").read_text())
    assert (summary["returns"], summary["sections"], summary["form"]["labels"]) == ("mirror", ["C1:energy=calm"],
                                                                                    "ABACAB")
    png = (tmp_path / "out" / "abacab_form.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and "abacab_form.png" in summary["files"]


def test_the_library_engine_lists_each_figure_as_danced_returns_included(arranged_song):
    result = generate_dance(DanceRequest(arranged_song, engine="library", seed=2))
    figures = result.details[0]["danced_figures"]
    starts = [f["song_s"][0] for f in figures]
    ends = [f["song_s"][1] for f in figures]
    assert starts[0] == pytest.approx(result.start_s) and ends[-1] == pytest.approx(result.duration_s, abs=0.05)
    assert starts[1:] == pytest.approx(ends[:-1])  # one after another, the whole dance
    assert all(f["clip"].endswith(".bvh") and f["clip_s"][0] <= f["clip_s"][1] for f in figures)
    assert_whole_figures(figures, float(np.median(np.diff(result.beat_times))))
    assert len(figures) < len(result.form.bar_starts) - 1  # a figure of a bar or more, not pieces of frames
    a1, a2 = (next(s for s in result.form.sections if s.name == n) for n in ("A1", "A2"))

    def inside(section) -> list[dict]:
        return [f for f in figures if section.start_s - 0.05 <= f["song_s"][0] < section.end_s - 0.5]

    assert [(f["clip"], f["clip_s"][0]) for f in inside(a2)] == [(f["clip"], f["clip_s"][0]) for f in inside(a1)]
    assert len(inside(a1)) >= 3  # the return is the same figures, from the same places
    assert [f["repeats"]["song_span"][0] for f in inside(a2)] == [f["song_s"][0] for f in inside(a1)]
    assert all(not f["repeats"]["mirrored"] for f in inside(a2))
    # C1 danced anew in the take: its own figures, listed whole.
    c1 = next(s for s in result.form.sections if s.name == "C1")
    redo = generate_dance(DanceRequest(arranged_song, engine="library", seed=3, continue_from=result.motions[0],
                                       at_s=1.0, redo_section="C1"))
    anew = redo.details[0]["danced_figures"]
    assert anew[0]["song_s"][0] == pytest.approx(c1.start_s, abs=0.05)
    assert anew[-1]["song_s"][1] == pytest.approx(c1.end_s, abs=0.05)
    assert_whole_figures(anew, float(np.median(np.diff(result.beat_times))))


def assert_whole_figures(figures: list[dict], beat_s: float) -> None:
    """Each entry of a figure list a whole figure: at least a beat long but where the dance's start or end cuts
    it, never carrying on the entry before it (the same clip from where that one ends), and a repeat pointing at
    an earlier span of the list danced from the same clip."""
    for k, f in enumerate(figures):
        (s0, s1), (c0, c1) = f["song_s"], f["clip_s"]
        assert s1 - s0 >= beat_s or k in (0, len(figures) - 1), f
        assert f["warp"] == pytest.approx((c1 - c0) / (s1 - s0), abs=0.01)
        if k:
            e = figures[k - 1]
            carried = e["clip"] == f["clip"] and abs(e["clip_s"][1] - c0) < 0.02 and (
                e.get("repeats", {}).get("mirrored") == f.get("repeats", {}).get("mirrored"))
            assert not carried or ("repeats" in e) != ("repeats" in f) or (
                "repeats" in f and e["repeats"]["song_span"][1] != f["repeats"]["song_span"][0]), (e, f)
        if "repeats" in f:
            r0, r1 = f["repeats"]["song_span"]
            assert r1 <= s0 and r1 - r0 == pytest.approx(s1 - s0, rel=0.3)
            assert any(e["clip"] == f["clip"] and e["song_s"][0] - 1e-3 <= r0 and r1 <= e["song_s"][1] + 1e-3
                       for e in figures[:k]), f


def test_a_run_of_returns_is_one_copy_of_the_run_it_repeats():
    """A3 C2 repeat A2 C1, which were heard together: one copy of A2 C1 (no join between A3 and C2), not A1 and
    C1 copied apart."""
    form = song_form(analysis(arranged_features("ABACAC")))
    assert form.labels == "ABACAC"
    assert _copies(form, "repeat", {}) == [(16, 24, 0, "repeat"), (32, 48, 16, "repeat")]
    motion = wandering_motion(form.bar_starts[-1])
    out, _map = dance_returns(motion, form, 0.0, "repeat")
    poses = body_poses(out.positions(), heading_frames(out))
    across = np.arange(int(76 * motion.fps), int(84 * motion.fps))  # A3 into C2 (80 s), clear of the copy's joins
    assert np.abs(poses[across] - poses[across - int(32 * motion.fps)]).max() < 1e-6  # A2 into C1 as danced


def test_a_copy_leaves_out_the_bars_it_would_play_beyond_the_real_time_limit():
    """A downbeat missed where the music returns makes one bar twice its source's length: that bar is danced as
    it was, the bars around it copied."""
    edges = np.arange(33) * 2.0
    edges[21:] += 2.0  # bar 20 lasts 4 s
    sections = (Section("A", 1, 0.0, float(edges[8]), 0, 8, 1.0), Section("B", 1, float(edges[8]), float(edges[16]),
                8, 8, 1.0), Section("A", 2, float(edges[16]), float(edges[24]), 16, 8, 0.9),
                Section("B", 2, float(edges[24]), float(edges[32]), 24, 8, 0.9))
    form = SongForm(edges, (), sections)
    assert _copies(form, "repeat", {}) == [(16, 20, 0, "repeat"), (21, 32, 5, "repeat")]
    assert _copies(form, "repeat", {"A2": "anew"}) == [(24, 32, 8, "repeat")]


def test_a_song_of_more_than_26_sections_labels_each_music_apart():
    """14 groups X Y X of music heard once each: 28 labels. Past Z the labels go on (AA, AB, ...), so the 27th
    new music is not called A again and its return is not danced as a copy of A1."""
    letters = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
    song = "".join(letters[2 * g] + letters[2 * g + 1] + letters[2 * g] for g in range(14))
    form = song_form(analysis(arranged_features(song, bars=4)))
    assert len(form.sections) == len(song)
    music = dict(zip(form.sections, song, strict=True))
    label_of = {}
    for s in form.sections:
        assert label_of.setdefault(music[s], s.label) == s.label  # the same music, the same label
    assert len(set(label_of.values())) == 28 and [label_of[c] for c in letters[26:28]] == ["AA", "AB"]
    assert form.labels.split() == [s.label for s in form.sections]
    for first, _end, source, _how in _copies(form, "repeat", {}):
        target = next(s for s in form.sections if s.first_bar == first)
        assert music[next(s for s in form.sections if s.first_bar == source)] == music[target]

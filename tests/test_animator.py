"""Animating on the command line with the shipped model: frame rates, a part of the song, root motion and
continuing a dance from a frame (the add-on's side is in test_addon_animator.py)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from made_up import click_song

from dancenet_core.bvh import read_bvh
from dancenet_core.cli import main as cli_main
from dancenet_core.constants import FRAME_RATES
from dancenet_core.motion import Motion


@pytest.fixture(scope="module")
def song(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """12 s of a 110-BPM click over a tone, with the feature cache in the test's own folder (for this module)."""
    folder = tmp_path_factory.mktemp("song")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("DANCENET_CACHE", str(folder / "cache"))
        yield click_song(folder / "clicks.wav", 12.0, 110)


def generate(song: Path, out: Path, *extra: str) -> Motion:
    assert cli_main(["generate", str(song), "-o", str(out), "--seed", "5", *extra]) == 0
    return Motion.load(out / f"{song.stem}.npz")


def test_fps_resamples_the_same_dance_with_slerp(song: Path, tmp_path: Path) -> None:
    own = generate(song, tmp_path / "own")
    assert own.fps == 25.0
    for fps in (24, 60):
        m = generate(song, tmp_path / str(fps), "--fps", str(fps))
        bvh = read_bvh(tmp_path / str(fps) / "clicks.bvh")
        assert m.fps == fps
        assert bvh.frame_time == pytest.approx(1 / fps, abs=1e-8)
        assert m.num_frames == round(own.duration * fps) == bvh.num_frames
        ref = own.resampled(fps)  # the one resampler the add-on and batch mode use too
        np.testing.assert_allclose(m.positions(), ref.positions(), atol=1e-4)
    # At 60 fps every 12th frame is a 25-fps frame (t = k/5 s): the same pose, not a blend.
    m60 = Motion.load(tmp_path / "60" / "clicks.npz")
    np.testing.assert_allclose(m60.positions()[::12], own.positions()[::5][: len(m60.positions()[::12])], atol=1e-4)
    assert set(FRAME_RATES) == {24, 25, 30, 50, 60}


def test_fps_outside_the_offered_rates_is_one_line(song: Path, tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit) as e:
        cli_main(["generate", str(song), "-o", str(tmp_path), "--fps", "23"])
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2
    assert "--fps" in err[-1]
    assert "invalid choice" in err[-1]


def test_part_of_the_song_dances_to_the_music_of_that_part(song: Path, tmp_path: Path, monkeypatch) -> None:
    import json

    from dancenet_core.engines import dancenet as core
    from dancenet_core.music.features import FPS, analyze_music, music_at_frames

    heard = []
    real = core.music_conditioning
    monkeypatch.setattr(core, "music_conditioning", lambda model, music, style: heard.append(music) or
                        real(model, music, style))
    m = generate(song, tmp_path, "--start", "4", "--end", "10", "--render")
    assert m.num_frames == 150  # 6 s at 25 fps
    analysis = analyze_music(song)
    np.testing.assert_allclose(heard[0], music_at_frames(analysis.features, FPS, 4 + np.arange(150) / 25), atol=1e-6)
    summary = json.loads((tmp_path / "clicks.json").read_text())
    inside = analysis.beat_times[(analysis.beat_times >= 4) & (analysis.beat_times < 10)]
    assert summary["start_s"] == 4
    assert summary["duration_s"] == 6
    assert summary["beats"] == len(inside)
    # The preview plays the part that was danced: its first click is the song's first after 4 s (4.36 s).
    import subprocess

    raw = subprocess.run(["ffmpeg", "-v", "error", "-i", str(tmp_path / "clicks.mp4"), "-f", "f32le", "-ac", "1",
                          "-ar", "22050", "-"], capture_output=True, check=True).stdout
    audio = np.frombuffer(raw, np.float32)
    first_click = np.argmax(np.abs(audio) > 0.35) / 22050
    assert abs(first_click - (8 * 60 / 110 - 4)) < 0.03, first_click


@pytest.mark.parametrize(("args", "message"), [
    (["--start", "11.5"], "less than 1 s of the song"),
    (["--start", "5", "--end", "4"], "at least 1 s after start"),
    (["--start", "-2"], "start must be 0 or more"),
])
def test_bad_parts_are_one_line_errors(song: Path, tmp_path: Path, capsys, args, message) -> None:
    assert cli_main(["generate", str(song), "-o", str(tmp_path), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err
    assert "\n" not in err
    assert not list(tmp_path.glob("*.bvh"))


def test_root_motion_modes_carry_the_same_dance(song: Path, tmp_path: Path) -> None:
    from dancenet_core.shaping.rootmotion import read_dance_bvh

    travel = generate(song, tmp_path / "travel", "--fps", "30")
    path = np.linalg.norm(np.ptp(travel.root_positions[:, [0, 2]], axis=0))
    assert path > 0.05  # the shipped model's dance does travel, so the modes below differ from it

    flat = generate(song, tmp_path / "flat", "--fps", "30", "--root-motion", "in-place")
    np.testing.assert_allclose(flat.root_positions[:, [0, 2]], 0.0, atol=1e-6)
    np.testing.assert_allclose(flat.root_positions[:, 1], travel.root_positions[:, 1], atol=1e-5)
    np.testing.assert_allclose(flat.rotations, travel.rotations, atol=1e-5)  # heading and turns kept
    np.testing.assert_allclose(read_dance_bvh(tmp_path / "flat" / "clicks.bvh").root_positions[:, [0, 2]], 0.0,
                               atol=1e-5)

    generate(song, tmp_path / "bone", "--fps", "30", "--root-motion", "root-bone")
    data = read_bvh(tmp_path / "bone" / "clicks.bvh")
    assert data.names[:2] == ("root", "pelvis")
    assert data.parents[1] == 0
    assert data.fps == 30
    world = data.world_positions()
    np.testing.assert_allclose(world[:, 0, 1], 0.0, atol=1e-6)  # the root stays on the floor...
    np.testing.assert_allclose(world[:, 0, [0, 2]], travel.root_positions[:, [0, 2]], atol=1e-5)  # ...under the hips
    # Hips and every joint are where the travelling dance puts them (BVH keeps 6 decimals).
    np.testing.assert_allclose(read_dance_bvh(tmp_path / "bone" / "clicks.bvh").positions(), travel.positions(),
                               atol=1e-4)


def join_continuity(motion: Motion, join: int) -> dict[str, float]:
    """At the first new frame `join`: the largest joint step into it and the largest change of joint velocity
    around it, beside the dance's own 95th percentiles of the same (per frame, the worst joint; metres/frame)."""
    p = motion.positions()
    v = np.diff(p, axis=0)
    step = np.linalg.norm(v, axis=-1).max(axis=1)  # step[i]: frame i -> i + 1
    dv = np.linalg.norm(np.diff(v, axis=0), axis=-1).max(axis=1)  # dv[i]: velocity change at frame i + 1
    return {"step": float(step[join - 1]), "step_p95": float(np.percentile(step, 95)),
            "dv": float(dv[join - 2 : join].max()), "dv_p95": float(np.percentile(dv, 95))}


def test_continue_keeps_the_dance_and_joins_without_a_pop(song: Path, tmp_path: Path, capsys) -> None:
    original = generate(song, tmp_path / "a", "--fps", "30")
    kept_bvh = tmp_path / "a" / "clicks.bvh"
    assert cli_main(["generate", str(song), "-o", str(tmp_path / "b"), "--seed", "9", "--continue", str(kept_bvh),
                     "--at", "6"]) == 0
    cont = Motion.load(tmp_path / "b" / "clicks.npz")
    join = 180  # 6 s at the kept dance's 30 fps
    assert cont.fps == 30
    assert cont.num_frames == original.num_frames
    # Up to the join: the kept dance (as read back from its BVH); after it: a new dance.
    np.testing.assert_allclose(cont.positions()[:join], original.positions()[:join], atol=1e-4)
    assert np.abs(cont.positions()[join + 15 :] - original.positions()[join + 15 :]).max() > 0.05
    got = join_continuity(cont, join)
    assert got["step"] <= got["step_p95"], got
    assert got["dv"] <= got["dv_p95"], got

    # The measure does see a pop: the kept dance cut onto another seed's dance at the same frame fails it.
    other = generate(song, tmp_path / "c", "--fps", "30", "--seed", "11")
    cut = Motion(np.concatenate([original.rotations[:join], other.rotations[join:]]),
                 np.concatenate([original.root_positions[:join], other.root_positions[join:]]), 30.0, original.skeleton)
    popped = join_continuity(cut, join)
    assert popped["dv"] > popped["dv_p95"]
    with capsys.disabled():
        print(f"\ncontinue at 6 s: join {got}; plain cut {popped}")


@pytest.mark.parametrize(("args", "message"), [
    (["--at", "3"], "--at goes with --continue"),
    (["--continue", "KEPT"], "--continue needs --at"),
    (["--continue", "KEPT", "--at", "40"], "must start within the kept dance"),
    (["--continue", "SONG", "--at", "2"], "clicks.wav:1: expected"),
])
def test_bad_continue_is_one_line(song: Path, tmp_path: Path, capsys, args, message) -> None:
    generate(song, tmp_path / "kept")
    args = [{"KEPT": str(tmp_path / "kept" / "clicks.bvh"), "SONG": str(song)}.get(a, a) for a in args]
    assert cli_main(["generate", str(song), "-o", str(tmp_path / "o"), *args]) == 2
    assert message in capsys.readouterr().err.strip().splitlines()[-1]
    assert not (tmp_path / "o").exists()  # refused before any work

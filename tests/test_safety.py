"""Never lose a user's work. Weights load without unpickling, files are written whole or not at all,
existing outputs are not overwritten silently, the cache heals itself, bad input gets one line."""

from __future__ import annotations

import contextlib
import errno
import os
import pickle
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import soundfile as sf
import torch
from made_up import as_a_terminal_signals_it, click_song, small_motion

from dancenet_core import generate
from dancenet_core.bvh import write_bvh
from dancenet_core.checkpoint import load_weights
from dancenet_core.cli import main as cli_main
from dancenet_core.commands import analyze as analyze_command
from dancenet_core.errors import DanceNetError
from dancenet_core.nets.bundle import DEFAULT_BUNDLE, DanceNetBundle
from dancenet_core.nets.footfix import WEIGHTS as FOOTFIX_WEIGHTS
from dancenet_core.nets.footfix import FootFixer

SHIPPED = sorted((Path(__file__).resolve().parents[1] / "dancenet_core" / "weights").glob("*.pt"))


def one_line(e: BaseException) -> str:
    msg = str(e)
    assert msg, msg
    assert "\n" not in msg, msg
    assert "Traceback" not in msg, msg
    return msg


# --- safe weights ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_shipped_weights_are_plain_data(path: Path) -> None:
    torch.load(path, map_location="cpu", weights_only=True)


class _Exploit:
    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple:
        return (Path.touch, (self.marker,))


def test_crafted_weights_do_not_run_code(tmp_path: Path) -> None:
    marker, bad = tmp_path / "pwned", tmp_path / "evil.pt"
    torch.save({"config": _Exploit(marker)}, bad)
    for load in (DanceNetBundle.load, FootFixer.load):
        with pytest.raises(DanceNetError) as e:
            load(bad)
        assert "plain weights" in one_line(e.value)
    assert not marker.exists()


@pytest.mark.parametrize("content", [b"", b"\x00" * 7, np.random.default_rng(0).bytes(4096),
                                     pickle.dumps([1, 2, 3]), b"PK\x03\x04truncated zip"],
                         ids=["empty", "zeros", "random", "plain-pickle", "truncated-zip"])
def test_bad_weights_file_gives_one_line(tmp_path: Path, content: bytes) -> None:
    bad = tmp_path / "bad.pt"
    bad.write_bytes(content)
    for load in (DanceNetBundle.load, FootFixer.load):
        with pytest.raises(DanceNetError) as e:
            load(bad)
        assert str(bad) in one_line(e.value)


def test_wrong_dict_gives_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "wrong.pt"
    torch.save({"state_dict": {"w": torch.zeros(2)}}, bad)
    for load in (DanceNetBundle.load, FootFixer.load):
        with pytest.raises(DanceNetError) as e:
            load(bad)
        one_line(e.value)


def test_corrupted_shipped_footfix_gives_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "footfix.pt"
    data = FOOTFIX_WEIGHTS.read_bytes()
    bad.write_bytes(data[: len(data) // 2])
    with pytest.raises(DanceNetError) as e:
        FootFixer.load(bad)
    assert "footfix.pt" in one_line(e.value)


def test_bundle_save_round_trip_is_plain_and_exact(tmp_path: Path) -> None:
    shipped = DanceNetBundle.load(DEFAULT_BUNDLE)
    out = tmp_path / "again.pt"
    shipped.save(out)
    load_weights(out, "DanceNet weights", "")  # weights_only=True
    again = DanceNetBundle.load(out)
    for k, v in shipped.model.state_dict().items():
        assert torch.equal(v, again.model.state_dict()[k])
    for k, v in shipped.start_frames.items():
        assert again.start_frames[k].dtype == v.dtype
        assert np.array_equal(again.start_frames[k], v)
    assert np.array_equal(again.normalizer.constant, shipped.normalizer.constant)
    assert np.array_equal(again.skeleton.offsets, shipped.skeleton.offsets)
    assert list(tmp_path.iterdir()) == [out]  # no temporary left behind


# --- helpers ---------------------------------------------------------------------------------------------------

ROOT = Path(__file__).resolve().parents[1]


def _cli(argv: list[str], capsys: pytest.CaptureFixture) -> tuple[int, str]:
    code = cli_main(argv)
    err = capsys.readouterr().err.strip()
    return code, err


def _no_tmp_left(folder: Path) -> None:
    assert not [p.name for p in folder.iterdir() if ".tmp" in p.name]


# --- files are written whole or not at all ---------------------------------------------------------------------

def _fail_half_way(real: Callable) -> Callable:
    """`real` (np.savetxt or np.savez_compressed) that writes part of its output, then hits a full disk."""
    def write(f: Any, *args: Any, **kwargs: Any) -> None:
        f.write(b"PK\x03\x04 half" if "b" in getattr(f, "mode", "") else "1.0 2.0 3.0 half a li")
        raise OSError(errno.ENOSPC, "No space left on device")
    return write


@pytest.mark.parametrize("kind", ["bvh", "npz"])
def test_full_disk_leaves_the_old_file_and_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    kind: str) -> None:
    target = tmp_path / f"song.{kind}"
    target.write_bytes(b"the previous good file")
    motion = small_motion()
    if kind == "bvh":
        monkeypatch.setattr(np, "savetxt", _fail_half_way(np.savetxt))
        with pytest.raises(DanceNetError) as e:
            write_bvh(target, motion)
    else:
        monkeypatch.setattr(np, "savez_compressed", _fail_half_way(np.savez_compressed))
        with pytest.raises(DanceNetError) as e:
            motion.save(target)
    assert "No space left on device" in one_line(e.value)
    assert target.read_bytes() == b"the previous good file"
    _no_tmp_left(tmp_path)


def test_ctrl_c_while_writing_a_long_bvh_keeps_the_previous_file(tmp_path: Path) -> None:
    target = tmp_path / "song.bvh"
    write_bvh(target, small_motion())
    before = target.read_bytes()
    code = (f"import sys; sys.path.insert(0, 'tests'); from made_up import small_motion; "
            f"from dancenet_core.bvh import write_bvh; write_bvh({str(target)!r}, small_motion(60000))")
    child = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, stderr=subprocess.DEVNULL,
                             preexec_fn=as_a_terminal_signals_it)
    deadline = time.monotonic() + 120
    while not [p for p in tmp_path.iterdir() if ".tmp" in p.name]:
        assert child.poll() is None, "the child never started writing"
        assert time.monotonic() < deadline, "the child never started writing"
        time.sleep(0.02)
    time.sleep(0.2)  # well into the frames
    child.send_signal(signal.SIGINT)
    assert child.wait(60) != 0
    assert target.read_bytes() == before
    _no_tmp_left(tmp_path)


# --- no silent overwrite; arguments checked before any long work ---------------------------------------------

@pytest.fixture
def no_analysis(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail the test if a command gets as far as analysing the music."""
    def analyze(*_a: Any, **_k: Any) -> None:
        raise AssertionError("analysis started")

    monkeypatch.setattr(generate, "analyze_music", analyze)
    monkeypatch.setattr(analyze_command, "analyze_music", analyze)


def test_generate_refuses_to_replace_outputs_unless_asked(tmp_path: Path, capsys: pytest.CaptureFixture,
                                                          no_analysis: None) -> None:
    song, out = click_song(tmp_path / "song.wav", 4.0), tmp_path / "out"
    out.mkdir()
    (out / "song.json").write_text("mine")
    code, err = _cli(["generate", str(song), "-o", str(out)], capsys)
    assert code == 2
    assert "song.json already exists" in err
    assert "--overwrite" in err
    assert "\n" not in err
    assert (out / "song.json").read_text() == "mine"
    with pytest.raises(AssertionError, match="analysis started"):
        cli_main(["generate", str(song), "-o", str(out), "--overwrite"])


@pytest.mark.parametrize(("extra", "message"), [
    (["--seed", "-1"], "seed must be"),
    (["--seed", str(2**40)], "seed must be"),
    (["--temperature", "inf"], "temperature must be"),
    (["--temperature", "nan"], "temperature must be"),
    (["--temperature", "1e9"], "temperature must be"),
    (["--temperature", "-0.5"], "temperature must be"),
    (["--takes", "0"], "takes must be"),
    (["--style", "polka"], "unknown style 'polka'"),
    (["--weights", "RANDOM"], "cannot read the DanceNet weights"),
    (["--weights", "EMPTY"], "cannot read the DanceNet weights"),
    (["--weights", "PICKLE"], "cannot read the DanceNet weights"),
    (["--weights", "MISSING"], "not found"),
    (["-o", "UNDER_A_FILE"], "output folder"),
    (["SONG_IS_A_FOLDER"], "is a folder, not an audio file"),
])
def test_bad_arguments_are_one_line_before_analysis(tmp_path: Path, capsys: pytest.CaptureFixture,
                                                    no_analysis: None, extra: list[str], message: str) -> None:
    song, out = click_song(tmp_path / "song.wav", 4.0), tmp_path / "out"
    (tmp_path / "a_file").write_text("x")
    files = {"RANDOM": np.random.default_rng(1).bytes(1000), "EMPTY": b"", "PICKLE": pickle.dumps({"a": 1})}
    for key, content in files.items():
        (tmp_path / f"{key}.pt").write_bytes(content)
    subst = {**{k: str(tmp_path / f"{k}.pt") for k in [*files, "MISSING"]},
             "UNDER_A_FILE": str(tmp_path / "a_file" / "out")}
    extra = [subst.get(a, a) for a in extra]
    argv = ["generate", str(song), "-o", str(out), *extra]
    if extra == ["SONG_IS_A_FOLDER"]:
        argv = ["generate", str(tmp_path), "-o", str(out)]
    t = time.perf_counter()
    code, err = _cli(argv, capsys)
    assert code == 2, err
    assert message in err, err
    assert err.startswith("dancenet: error: ")
    assert "\n" not in err
    assert "Traceback" not in err
    assert time.perf_counter() - t < 30


# --- the cache heals itself ------------------------------------------------------------------------------------

@pytest.mark.parametrize("damage", ["truncated", "empty", "garbage", "nan"])
def test_damaged_cache_entry_is_recomputed_with_a_notice(tmp_path: Path, capsys: pytest.CaptureFixture,
                                                         damage: str) -> None:
    from dancenet_core.music.features import MusicAnalysis, analyze_music

    song, cache = click_song(tmp_path / "song.wav", 4.0), tmp_path / "cache"
    first = analyze_music(song, cache_dir=cache, workers=1)
    (entry,) = cache.iterdir()
    data = entry.read_bytes()
    if damage == "nan":
        bad = MusicAnalysis.load(entry)
        bad.features[3, 2] = np.nan
        np.savez(entry, features=bad.features, beat_times=bad.beat_times, downbeat_times=bad.downbeat_times,
                 meta=np.load(entry)["meta"])
    else:
        entry.write_bytes({"truncated": data[: len(data) // 2], "empty": b"", "garbage": b"\x00garbage" * 50}[damage])
    capsys.readouterr()
    again = analyze_music(song, cache_dir=cache, workers=1)
    notice = capsys.readouterr().err.strip()
    assert notice.startswith("dancenet: the cached analysis"), notice
    assert "\n" not in notice, notice
    assert np.array_equal(again.features, first.features)
    assert np.array_equal(MusicAnalysis.load(entry).features, first.features)  # replaced by a good entry


def _hammer(entry: str, n: int) -> None:
    from dancenet_core.music.features import MusicAnalysis

    rng = np.random.default_rng()
    for _ in range(n):
        MusicAnalysis(rng.random((2000, 15), dtype=np.float32), np.arange(10.0), np.arange(3.0), 60.0, 200.0,
                      mel=rng.random((2000, 80), dtype=np.float32)).save(entry)


def test_two_processes_writing_one_cache_entry_leave_it_whole(tmp_path: Path) -> None:
    import multiprocessing as mp

    from dancenet_core.music.features import MusicAnalysis

    entry = tmp_path / "entry.npz"
    _hammer(str(entry), 1)
    ctx = mp.get_context("fork")
    writers = [ctx.Process(target=_hammer, args=(str(entry), 40)) for _ in range(2)]
    for w in writers:
        w.start()
    reads = 0
    while any(w.is_alive() for w in writers):
        assert MusicAnalysis.load(entry).features.shape == (2000, 15)
        reads += 1
    assert all(w.exitcode == 0 for w in writers)
    assert reads > 0
    assert [p.name for p in tmp_path.iterdir()] == ["entry.npz"]


# --- signals stop the analysis workers -----------------------------------------------------------------------

def _children(pid: int) -> set[int]:
    out = set()
    for task in Path(f"/proc/{pid}/task").iterdir():
        with contextlib.suppress(OSError):
            out |= {int(c) for c in (task / "children").read_text().split()}
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc")
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP, signal.SIGKILL],
                         ids=["SIGTERM", "SIGINT", "SIGHUP", "SIGKILL"])  # SIGHUP: the terminal closed
def test_signal_during_analysis_leaves_no_worker_behind(tmp_path: Path, sig: signal.Signals) -> None:
    song = click_song(tmp_path / "long.wav", 150.0, rate=11025)
    env = {**os.environ, "DANCENET_WORKERS": "2", "DANCENET_CACHE": str(tmp_path / "cache")}
    with (tmp_path / "stderr").open("w") as log:  # a file, not a pipe: a worker left behind would hold a pipe open
        child = subprocess.Popen([sys.executable, "-m", "dancenet_core.cli", "analyze", str(song), "--no-cache"],
                                 cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=log, text=True,
                                 preexec_fn=as_a_terminal_signals_it)
    deadline = time.monotonic() + 120
    workers: set[int] = set()
    while len(workers) < 2:
        assert child.poll() is None, "no workers started"
        assert time.monotonic() < deadline, "no workers started"
        workers = _children(child.pid)
        time.sleep(0.05)
    time.sleep(0.5)
    child.send_signal(sig)
    code = child.wait(60)
    err = (tmp_path / "stderr").read_text()
    assert code != 0, err
    assert "Traceback" not in err, err
    deadline = time.monotonic() + 10
    while any(_alive(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = [w for w in workers if _alive(w)]
    for w in left:  # end them, so a failure here leaves nothing running
        os.kill(w, signal.SIGKILL)
    assert not left


STOP_IN_THE_POOL = """
import os, sys, time
from pathlib import Path
from dancenet_core.music import features

def block(i):
    time.sleep(0.02)
    return i

def signal_arrives(_fraction):
    raise SystemExit(129)

me = str(os.getpid())
for _ in range(int(sys.argv[1])):
    try:
        with features._executor(2, 40) as ex:
            features._run_all(ex, block, [(i,) for i in range(40)], signal_arrives)
    except SystemExit:
        pass
    left = []
    for p in Path("/proc").glob("[0-9]*"):
        try:
            state, parent = (p / "stat").read_text().rsplit(")", 1)[1].split()[:2]
        except (OSError, ValueError):
            continue
        if parent == me and state != "Z":
            left.append(p.name)
    print("left", left, flush=True)
"""


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc")
def test_a_signal_in_the_pool_stops_it_quietly_and_whole() -> None:
    """The race behind a rare traceback on SIGHUP: the analysis stops its pool (the signal's SystemExit in the
    main thread) while blocks are queued. Every try ends without a traceback from the pool's own thread
    (`InvalidStateError: CANCELLED`) and with no worker left, 30 tries in a row."""
    out = subprocess.run([sys.executable, "-c", STOP_IN_THE_POOL, "30"], cwd=ROOT, capture_output=True, text=True,
                         timeout=240)
    assert out.returncode == 0 and "Traceback" not in out.stderr, out.stderr[-2000:]
    assert out.stdout.splitlines() == ["left []"] * 30


# --- non-finite audio is an error that says so, and nothing is cached -------------------------------------------

@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_audio_is_one_line_and_not_cached(tmp_path: Path, capsys: pytest.CaptureFixture,
                                                      bad: float) -> None:
    from dancenet_core.music.features import analyze_music

    rate = 22050
    y = 0.3 * np.sin(2 * np.pi * 220 * np.arange(5 * rate) / rate)
    y[1000:1010] = bad
    song = tmp_path / "damaged.wav"
    sf.write(song, y.astype(np.float32), rate, subtype="FLOAT")
    with pytest.raises(DanceNetError) as e:
        analyze_music(song, cache_dir=tmp_path / "cache", workers=1)
    assert "not numbers (NaN or infinity)" in one_line(e.value)
    assert not (tmp_path / "cache").exists() or not list((tmp_path / "cache").iterdir())
    code, err = _cli(["generate", str(song), "-o", str(tmp_path / "out")], capsys)
    assert code == 2
    assert "NaN or infinity" in err
    assert "\n" not in err
    assert not (tmp_path / "out" / "damaged.json").exists()


# --- one line, never a traceback ------------------------------------------------------------------------------

def _bvh_text(frames: int = 3) -> str:
    rows = "\n".join(" ".join(["0.0"] * 12) for _ in range(frames))
    return ("HIERARCHY\nROOT hips\n{\n\tOFFSET 0 0 0\n\tCHANNELS 6 Xposition Yposition Zposition Zrotation "
            "Xrotation Yrotation\n\tJOINT knee\n\t{\n\t\tOFFSET 0 -0.4 0\n\t\tCHANNELS 3 Zrotation Xrotation "
            "Yrotation\n\t\tJOINT foot\n\t\t{\n\t\t\tOFFSET 0 -0.4 0\n\t\t\tCHANNELS 3 Zrotation Xrotation "
            "Yrotation\n\t\t\tEnd Site\n\t\t\t{\n\t\t\t\tOFFSET 0 0 0.1\n\t\t\t}\n\t\t}\n\t}\n}\n"
            f"MOTION\nFrames: {frames}\nFrame Time: 0.04\n{rows}\n")


def _deep_bvh(depth: int) -> str:
    opens = "".join(f"JOINT j{k}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n" for k in range(depth))
    return ("HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n" + opens
            + "}\n" * (depth + 1) + f"MOTION\nFrames: 1\nFrame Time: 0.04\n{' '.join(['0'] * 3 * (depth + 1))}\n")


@pytest.mark.parametrize("case", ["nan-values", "inf-frame-time", "npy-as-npz", "deep-bvh"])
def test_bad_motion_files_given_to_render_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture,
                                                       case: str) -> None:
    path = tmp_path / ("motion.npz" if case == "npy-as-npz" else "motion.bvh")
    if case == "nan-values":
        text = _bvh_text().splitlines()
        text[-2] = " ".join(["0.0"] * 5 + ["nan"] + ["0.0"] * 6)
        path.write_text("\n".join(text) + "\n")
    elif case == "inf-frame-time":
        path.write_text(_bvh_text().replace("Frame Time: 0.04", "Frame Time: inf"))
    elif case == "npy-as-npz":
        np.save(tmp_path / "m.npy", np.zeros((10, 3)))
        (tmp_path / "m.npy").rename(path)
    else:
        path.write_text(_deep_bvh(5000))
    code, err = _cli(["render", str(path), "--sheet", str(tmp_path / "sheet.png")], capsys)
    assert code == 2, err
    assert err.startswith("dancenet: error: "), err
    assert "\n" not in err, err
    assert not (tmp_path / "sheet.png").exists()


def test_bone_map_that_is_not_utf8_is_one_line(tmp_path: Path) -> None:
    from dancenet_core import rigmap

    path = tmp_path / "map.json"
    path.write_bytes(b'{"bones": {"pelvis": "Hips\xff\xfe"}}')
    with pytest.raises(DanceNetError) as e:
        rigmap.load_file(path)
    assert "not UTF-8" in one_line(e.value)

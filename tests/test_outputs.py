"""A run's outputs are one consistent set whatever runs share the folder: names of any script and
length, an unwritable cache, a demo that runs twice, and the small output defects.

The dance itself is a stand-in (`_fake_generate`): these tests are about what is written where, not the dance."""

from __future__ import annotations

import errno
import json
import os
import shlex
import subprocess
import sys
import time
import unicodedata
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from made_up import click_song, small_motion

from dancenet_core.atomic import NAME_MAX_BYTES, atomic_path, fit_name, remove_leftovers, write_text
from dancenet_core.bvh import write_bvh
from dancenet_core.cli import main as cli_main
from dancenet_core.commands import generate as generate_command
from dancenet_core.errors import DanceNetError
from dancenet_core.generate import GenerationResult
from dancenet_core.motion import Motion
from dancenet_core.outputs import MAX_STEM_BYTES, safe_stem
from dancenet_core.request import DanceRequest

ROOT = Path(__file__).resolve().parents[1]


def _dance(seed: int) -> Motion:
    """The stand-in dance of `seed`: its root height is the seed, so every file says which run wrote it."""
    motion = small_motion()
    motion.root_positions[:, 1] = seed
    return motion


def _fake_generate(request: DanceRequest, **_kwargs: Any) -> GenerationResult:
    motion = _dance(request.seed)
    return GenerationResult([motion], np.zeros(0), np.zeros(0), 120.0, motion.duration, "waltz", {},
                            start_s=request.start_s)


@pytest.fixture
def fake_generate(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(generate_command, "generate_dance", _fake_generate)


def _cli(argv: list[str], capsys: pytest.CaptureFixture) -> tuple[int, str]:
    code = cli_main(argv)
    return code, capsys.readouterr().err.strip()


def _temporaries(folder: Path) -> list[str]:
    return [p.name for p in folder.iterdir() if ".tmp" in p.name]


# --- concurrent runs into one folder ---------------------------------------------------------------------------

# A `dancenet generate` whose dance is `_dance(seed)`, made only once all `n` runs have passed the early
# "already exists" check: the runs overlap for certain, however slowly each process starts.
_RACER = """
import sys, time
from pathlib import Path
sys.path.insert(0, 'tests')
import test_outputs
from dancenet_core.commands import generate as command
from dancenet_core.cli import main
ready, n = Path(sys.argv[1]), int(sys.argv[2])
def fake(request, **kwargs):
    (ready / str(request.seed)).touch()
    deadline = time.monotonic() + 120
    while len(list(ready.iterdir())) < n and time.monotonic() < deadline:
        time.sleep(0.01)
    return test_outputs._fake_generate(request, **kwargs)
command.generate_dance = fake
sys.exit(main(sys.argv[3:]))
"""


@pytest.mark.parametrize("overwrite", [False, True], ids=["no-overwrite", "overwrite"])
def test_concurrent_runs_into_one_folder_leave_one_consistent_set(tmp_path: Path, overwrite: bool) -> None:
    song, out, ready, n = click_song(tmp_path / "song.wav", 4.0), tmp_path / "out", tmp_path / "ready", 4
    ready.mkdir()
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    runs = [subprocess.Popen([sys.executable, "-c", _RACER, str(ready), str(n), "generate", str(song), "-o",
                              str(out), "--seed", str(seed), *(["--overwrite"] if overwrite else [])],
                             cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
             for seed in range(1, n + 1)]
    results = [(run.wait(180), run.stderr.read() if run.stderr else "") for run in runs]
    codes = [code for code, _ in results]
    if overwrite:
        assert codes == [0] * n, results
    else:
        assert sorted(codes) == [0] + [2] * (n - 1), results
        for code, err in results:
            if code:
                assert "already exists" in err and len(err.strip().splitlines()) == 1, err
    summary = json.loads((out / "song.json").read_text())
    seed = summary["seed"]
    assert Motion.load(out / "song.npz").root_positions[0, 1] == seed
    write_bvh(tmp_path / "expected.bvh", _dance(seed))
    assert (out / "song.bvh").read_bytes() == (tmp_path / "expected.bvh").read_bytes()
    assert sorted(p.name for p in out.iterdir()) == ["song.bvh", "song.json", "song.npz"]


# --- an unwritable cache ---------------------------------------------------------------------------------------

def test_unwritable_cache_carries_on_with_a_one_line_notice(tmp_path: Path, capsys: pytest.CaptureFixture,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    from dancenet_core.music.features import analyze_music

    song, blocker = click_song(tmp_path / "song.wav", 4.0), tmp_path / "a_file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("DANCENET_CACHE", str(blocker))  # as DANCENET_CACHE=/dev/null: no folder can be made
    capsys.readouterr()
    result = analyze_music(song, workers=1)
    assert result.num_frames == 40
    notice = capsys.readouterr().err.strip()
    assert notice.startswith("dancenet: the music analysis is not cached"), notice
    assert "\n" not in notice and "Traceback" not in notice, notice
    assert blocker.read_text() == "not a folder"


# --- names of any length and script ---------------------------------------------------------------------------

@pytest.mark.parametrize("limit", [NAME_MAX_BYTES, MAX_STEM_BYTES, 20])
def test_fitted_names_fit_in_bytes_and_stay_distinct(limit: int) -> None:
    for letter in ("a", "é", "日", "😀"):
        names = {fit_name(letter * k + "x", limit) for k in range(1, 300)}
        assert len(names) == 299  # distinct: the hash tells long names apart
        assert all(len(name.encode()) <= limit for name in names)
    long = fit_name("日本語の長い曲名" * 40, limit)
    assert long.startswith("日本語"[: max(0, (limit - 9) // 3)])


@pytest.mark.parametrize("name", ["a" * 245, "日" * 80, "é" * 120], ids=["245-ascii", "240-bytes-cjk", "accents"])
def test_a_long_song_name_gives_short_recognisable_outputs(tmp_path: Path, capsys: pytest.CaptureFixture,
                                                           fake_generate: None, name: str) -> None:
    song, out = click_song(tmp_path / f"{name}.wav", 4.0), tmp_path / "out"
    code, err = _cli(["generate", str(song), "-o", str(out), "--takes", "1"], capsys)
    assert code == 0, err
    names = sorted(p.name for p in out.iterdir())
    assert len(names) == 3 and all(len(n.encode()) <= NAME_MAX_BYTES for n in names), names
    stem = Path(names[0]).stem
    assert len(stem.encode()) <= MAX_STEM_BYTES and stem.startswith(name[:20])
    assert not _temporaries(out)


def test_any_name_length_is_written_atomically(tmp_path: Path) -> None:
    """Temporary names shorten themselves, so any name the file system takes can be written."""
    for stem_bytes in (1, 200, 240, NAME_MAX_BYTES - 4):
        target = tmp_path / ("b" * stem_bytes + ".bvh")
        write_text(target, "x")
        assert target.read_text() == "x"
    assert not _temporaries(tmp_path)


@pytest.mark.parametrize(("name", "stem"), [
    ("日本語.ogg", "日本語"),
    ("Ave Maria – Schubert.mp3", "Ave_Maria_–_Schubert"),
    (unicodedata.normalize("NFD", "café.wav"), "café"),  # macOS hands names over decomposed
    ("Танго.flac", "Танго"),
    ('a:b?c*d"e<f>g|h.wav', "a_b_c_d_e_f_g_h"),
    ("..wav", "dance"),
    ("...hidden.ogg", "hidden"),
    ("CON.wav", "CON_"),
    ("trailing...wav", "trailing"),
])
def test_song_names_keep_their_letters(name: str, stem: str) -> None:
    assert safe_stem(name) == stem
    assert unicodedata.is_normalized("NFC", safe_stem(name))


def test_non_latin_titles_get_their_own_outputs(tmp_path: Path, capsys: pytest.CaptureFixture,
                                                fake_generate: None) -> None:
    out = tmp_path / "out"
    for title in ("日本語", "中文歌", "café"):
        code, err = _cli(["generate", str(click_song(tmp_path / f"{title}.ogg", 4.0)), "-o", str(out)], capsys)
        assert code == 0, err
    names = {p.name for p in out.iterdir()}
    assert {"日本語.bvh", "中文歌.bvh", "café.bvh", "日本語.json", "中文歌.json", "café.json"} <= names


# --- `make demo` twice -----------------------------------------------------------------------------------------

def test_the_demo_runs_twice(tmp_path: Path, capsys: pytest.CaptureFixture, fake_generate: None,
                             monkeypatch: pytest.MonkeyPatch) -> None:
    """The Makefile's demo command, run twice into one folder (render stood in for): both succeed."""
    recipe = (ROOT / "Makefile").read_text().split("\ndemo:", 1)[1].split("\n\n", 1)[0]
    command = next(line for line in recipe.splitlines() if "dancenet_core.cli" in line)
    argv = shlex.split(command)
    argv = argv[argv.index("dancenet_core.cli") + 1:]
    argv[argv.index("-o") + 1] = str(tmp_path / "out")
    argv = [str(ROOT / a) if a.startswith("examples/") else a for a in argv]

    def render(motion: Motion, path: Path, **_k: Any) -> Path:
        Path(path).write_bytes(b"video")
        return Path(path)

    monkeypatch.setattr(generate_command, "render_motion", render)
    for _ in range(2):
        code, err = _cli(argv, capsys)
        assert code == 0, err
    assert (tmp_path / "out" / "example_song.mp4").read_bytes() == b"video"


# --- the small ones --------------------------------------------------------------------------------------------

def test_a_dangling_link_at_an_output_name_is_not_replaced(tmp_path: Path, capsys: pytest.CaptureFixture,
                                                           fake_generate: None) -> None:
    song, out = click_song(tmp_path / "song.wav", 4.0), tmp_path / "out"
    out.mkdir()
    (out / "song.bvh").symlink_to(tmp_path / "nowhere.bvh")
    code, err = _cli(["generate", str(song), "-o", str(out)], capsys)
    assert code == 2 and "song.bvh already exists" in err, err
    assert (out / "song.bvh").is_symlink() and not (tmp_path / "nowhere.bvh").exists()


def _dead_pid() -> int:
    pid = 4_000_000
    while Path(f"/proc/{pid}").exists():
        pid += 1
    return pid


@pytest.mark.skipif(os.name != "posix", reason="leftovers are told by their process id on POSIX")
def test_a_killed_runs_temporary_files_go_on_the_next_run(tmp_path: Path, capsys: pytest.CaptureFixture,
                                                          fake_generate: None) -> None:
    song, out = click_song(tmp_path / "song.wav", 4.0), tmp_path / "out"
    out.mkdir()
    dead = [out / f".song.{_dead_pid()}.0123abcd.tmp{s}" for s in (".bvh", ".npz", ".mp4")]
    live = out / f".other.{os.getpid()}.0123abcd.tmp.bvh"  # a run still writing
    mine = out / ".notes.txt"
    for p in (*dead, live, mine):
        p.write_text("x")
    code, err = _cli(["generate", str(song), "-o", str(out)], capsys)
    assert code == 0, err
    assert not any(p.exists() for p in dead)
    assert live.exists() and mine.exists()


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="zombies are told from Linux's /proc")
def test_a_zombies_temporary_files_are_leftovers(tmp_path: Path) -> None:
    """A worker killed with its batch is a zombie until init reaps it (a second or more in a container): its
    temporary files are a leftover at once, while a live process' files stay."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    deadline = time.monotonic() + 30
    while Path(f"/proc/{child.pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z":
        assert time.monotonic() < deadline, "the child never ended"
        time.sleep(0.01)
    try:
        zombie = tmp_path / f".song.{child.pid}.0123abcd.tmp.npz"
        live = tmp_path / f".song.{os.getpid()}.0123abcd.tmp.npz"
        for p in (zombie, live):
            p.write_text("x")
        remove_leftovers(tmp_path)
        assert not zombie.exists() and live.exists()
    finally:
        child.wait()


def test_write_errors_say_what_happened(tmp_path: Path) -> None:
    (tmp_path / "a_folder.json").mkdir()
    with pytest.raises(DanceNetError) as e:
        write_text(tmp_path / "a_folder.json", "x")
    assert "free some space" not in str(e.value) and "folder" in str(e.value)
    with pytest.raises(DanceNetError) as e, atomic_path(tmp_path / ("n" * 300 + ".json")) as tmp:
        tmp.write_text("x")
    assert "free some space" not in str(e.value) and "shorter name" in str(e.value)
    assert not _temporaries(tmp_path)


def test_start_minus_zero_is_written_as_zero(tmp_path: Path, capsys: pytest.CaptureFixture,
                                             fake_generate: None) -> None:
    song, out = click_song(tmp_path / "song.wav", 4.0), tmp_path / "out"
    code, err = _cli(["generate", str(song), "-o", str(out), "--start", "-0.0"], capsys)
    assert code == 0, err
    text = (out / "song.json").read_text()
    assert '"start_s": 0.0' in text and "-0.0" not in text


def test_a_losing_run_keeps_the_winners_files_and_leaves_nothing(tmp_path: Path, capsys: pytest.CaptureFixture,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """In one process: a run whose outputs appear while it dances ends with one line, the others' files kept."""
    song, out = click_song(tmp_path / "song.wav", 4.0), tmp_path / "out"

    def meanwhile(request: DanceRequest, **kwargs: Any) -> GenerationResult:
        (out / "song.npz").write_text("another run's")
        return _fake_generate(request, **kwargs)

    monkeypatch.setattr(generate_command, "generate_dance", meanwhile)
    t = time.perf_counter()
    code, err = _cli(["generate", str(song), "-o", str(out)], capsys)
    assert code == 2 and "song.npz already exists" in err and "\n" not in err, err
    assert sorted(p.name for p in out.iterdir()) == ["song.npz"]
    assert (out / "song.npz").read_text() == "another run's"
    assert time.perf_counter() - t < 60


class _Msvcrt:
    """Windows' msvcrt.locking as a stand-in: each call recorded; a lock attempt fails with `error` (after ten
    tries of a second each, as Windows' LK_LOCK does) while `error` is set. A call past 100 means the lock
    spins."""

    LK_UNLCK, LK_LOCK = 0, 1

    def __init__(self, error: OSError | None) -> None:
        self.error, self.calls = error, []

    def locking(self, fd: int, mode: int, nbytes: int) -> None:
        self.calls.append(mode)
        if len(self.calls) > 100:
            raise RecursionError("the lock spins")
        if mode == self.LK_LOCK and self.error is not None:
            raise self.error


def _claim_on_windows(folder: Path, msvcrt: _Msvcrt, monkeypatch: pytest.MonkeyPatch) -> None:
    from dancenet_core import outputs

    monkeypatch.setitem(sys.modules, "msvcrt", msvcrt)
    monkeypatch.setattr(os, "name", "nt")
    try:
        with outputs._folder_lock(folder):
            pass
    finally:
        monkeypatch.setattr(os, "name", "posix")


def test_the_windows_folder_lock_is_released_and_gives_up_on_errors(tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """Taken, the lock is released before its file is closed; a lock that cannot be taken (a permission error,
    a holder that never lets go) ends in one line naming the folder instead of trying for ever."""
    free = _Msvcrt(None)
    _claim_on_windows(tmp_path, free, monkeypatch)
    assert free.calls == [free.LK_LOCK, free.LK_UNLCK]
    for error in (PermissionError(13, "Permission denied"), OSError(errno.EDEADLOCK, "Resource deadlock avoided")):
        held = _Msvcrt(error)
        with pytest.raises(DanceNetError, match=f"cannot lock the output folder {tmp_path}"):
            _claim_on_windows(tmp_path, held, monkeypatch)
        assert held.LK_UNLCK not in held.calls

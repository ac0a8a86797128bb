"""`dancenet batch`: a catalog of 12 made-up songs (one unreadable) danced by worker processes and by a local Ray
cluster gives each song the very bytes `dancenet generate` writes for it; a song that fails, a worker killed and a
batch killed outright leave the others done, whole files only, and the same command finishes the rest."""

from __future__ import annotations

import importlib.util
import json
import multiprocessing as mp
import os
import random
import signal
import socket
import subprocess
import sys
import time
from contextlib import suppress
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

import pytest
import soundfile as sf
from made_up import as_a_terminal_signals_it, music

from dancenet_core.catalog import RECORDS, CatalogSong, read_catalog, request_id, run_catalog
from dancenet_core.catalog.cluster import _ray_song
from dancenet_core.catalog.local import _stop
from dancenet_core.cli import build_parser, main
from dancenet_core.commands.batch import GenerateTask
from dancenet_core.music.audio import MADMOM_SAMPLE_RATE
from dancenet_core.request import options, options_from

ROOT = Path(__file__).resolve().parents[2]
GOOD = 11
BAD = "unreadable.wav"
TEMP_MARK = ".tmp"
HANG_S = 600  # a batch command still running after this hangs (minutes on a loaded machine with cold caches)


@pytest.fixture(scope="module")
def songs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """11 songs of 3.5 to 4.5 s (their own chords and noise each) and a file that is not audio."""
    folder = tmp_path_factory.mktemp("catalog") / "songs"
    folder.mkdir()
    for k in range(GOOD):
        sf.write(folder / f"song {k:02d}.wav", music(3.5 + 0.1 * k, seed=k), MADMOM_SAMPLE_RATE)
    (folder / BAD).write_bytes(b"RIFF\x00\x00\x00\x00WAVE but nothing a decoder can read")
    return folder


def _files(folder: Path) -> dict[str, bytes]:
    """A song folder's files by name; the summary without its timings (they are the run's, not the dance's)."""
    files = {}
    for p in sorted(folder.iterdir()):
        data = p.read_bytes()
        if p.suffix == ".json":
            summary = json.loads(data)
            summary.pop("timings_s")
            data = json.dumps(summary, sort_keys=True).encode()
        files[p.name] = data
    return files


@pytest.fixture(scope="module")
def reference(songs: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, bytes]]:
    """Each good song's files from `dancenet generate` (analysing the songs here fills the shared cache)."""
    out = tmp_path_factory.mktemp("generate")
    files = {}
    for song in sorted(songs.glob("song *.wav")):
        folder = out / song.stem.replace(" ", "_")
        assert main(["generate", str(song), "-o", str(folder), "--seed", "7"]) == 0
        files[folder.name] = _files(folder)
    return files


def _batch(*args: str) -> int:
    return main(["batch", *args, "--seed", "7"])


def _status(out: Path) -> dict[str, str]:
    return {Path(row["song"]).name: row["status"] for row in json.loads((out / "batch.json").read_text())["songs"]}


def _rows(out: Path) -> dict[str, dict]:
    return {Path(row["song"]).name: row for row in json.loads((out / "batch.json").read_text())["songs"]}


def _assert_same_as_generate(out: Path, reference: dict[str, dict[str, bytes]]) -> None:
    for name, files in reference.items():
        assert _files(out / name) == files, name
    assert not any(TEMP_MARK in p.name for p in out.rglob("*")), "a temporary file was left"


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_workers_write_what_generate_writes_and_report_the_bad_song(jobs: str, songs: Path, reference: dict,
                                                                    tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "out"
    assert _batch(str(songs), "-o", str(out), "--jobs", jobs) == 1  # one song failed, after the others
    captured = capsys.readouterr()
    assert f"{GOOD} danced, 0 already done, 1 failed of {GOOD + 1} songs" in captured.out
    failed = [line for line in captured.err.splitlines() if "failed: " in line]
    assert len(failed) == 1 and BAD in failed[0] and "cannot decode" in failed[0], captured.err
    _assert_same_as_generate(out, reference)
    rows = _rows(out)
    assert rows[BAD]["status"] == "failed" and "\n" not in rows[BAD]["error"]
    assert not (out / "unreadable").exists()  # no folder for a song that made nothing
    assert all(rows[f"song {k:02d}.wav"]["status"] == "done" for k in range(GOOD))
    assert rows["song 03.wav"]["frames"] == 95 and rows["song 03.wav"]["style"]
    assert all(0 < rows[n]["peak_memory_mb"] < 4000 for n in rows)
    csv_lines = (out / "batch.csv").read_text().splitlines()
    assert csv_lines[0].startswith("song,folder,status,style,tempo_bpm,frames") and len(csv_lines) == GOOD + 2
    # the same command again dances nothing: every song is there for the same request
    assert _batch(str(songs), "-o", str(out), "--jobs", jobs) == 1
    assert f"0 danced, {GOOD} already done, 1 failed" in capsys.readouterr().out
    assert _batch(str(songs / "song 00.wav"), "-o", str(out), "--force", "--jobs", jobs) == 0
    assert "1 danced, 0 already done" in capsys.readouterr().out
    # another seed is another request: danced again
    assert main(["batch", str(songs / "song 00.wav"), "-o", str(out), "--seed", "8", "--jobs", jobs]) == 0
    assert "1 danced, 0 already done" in capsys.readouterr().out
    assert _files(out / "song_00") != reference["song_00"]


def _children(pid: int) -> list[int]:
    """The batch's worker processes (multiprocessing's resource tracker left out)."""
    kids = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        for child in (task / "children").read_text().split():
            cmdline = Path(f"/proc/{child}/cmdline").read_bytes()
            if b"spawn_main" in cmdline:
                kids.append(int(child))
    return kids


def _command(songs: Path, out: Path) -> list[str]:
    return [sys.executable, "-m", "dancenet_core.cli", "batch", str(songs), "-o", str(out), "--seed", "7",
            "--jobs", "2"]


def _cold(tmp_path: Path) -> dict[str, str]:
    """A music cache of its own (numba's compiled code still shared): each song then takes its analysis' second
    or two, so a kill lands while songs are being danced."""
    return {**os.environ, "DANCENET_CACHE": str(tmp_path / "cache")}


def _wait_for(run: subprocess.Popen, out: Path, done: int) -> None:
    """Until the batch's table (written once its songs are planned) counts `done` songs danced, or the run ends
    (or hangs: `HANG_S`)."""
    deadline = time.monotonic() + HANG_S
    while run.poll() is None and time.monotonic() < deadline:
        with suppress(OSError, ValueError):
            if json.loads((out / "batch.json").read_text())["counts"]["done"] >= done:
                return
        time.sleep(0.02)


@dataclass(frozen=True)
class KilledOn:
    """The command's own task, but the worker process that takes song `folder` is killed (SIGKILL, what the
    system's out-of-memory killer sends) as it renames the song's first file into place: the kill lands
    mid-song, its record begun and its files written under their temporary names, however fast the machine is.
    At module level: each spawned worker unpickles it."""

    task: GenerateTask
    folder: str

    def settings(self, song: CatalogSong) -> dict[str, Any]:
        return self.task.settings(song)

    def outputs_key(self) -> dict[str, Any]:
        return self.task.outputs_key()

    def __call__(self, song: CatalogSong, folder: Path) -> dict[str, Any]:
        if song.folder == self.folder:
            rename = os.replace

            def killed_on_rename(source: str | Path, target: str | Path) -> None:
                if Path(source).parent == folder and TEMP_MARK in Path(source).name:
                    os.kill(os.getpid(), signal.SIGKILL)
                rename(source, target)

            os.replace = killed_on_rename  # this worker's alone: it is killed with this song
        return self.task(song, folder)


def test_a_killed_worker_fails_its_song_only_and_the_rerun_finishes_the_missing_ones(
        songs: Path, reference: dict, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "out"
    command = _command(songs, out)[3:]  # `dancenet batch ... --jobs 2`
    args = build_parser(command).parse_args(command)
    # song 01 is the second worker's first song: the batch starts a worker in its place for the songs queued
    task = KilledOn(GenerateTask(options_from(args)), "song_01")
    run_catalog(read_catalog(args.songs), out, task, jobs=args.jobs)
    rows = _rows(out)
    assert rows["song 01.wav"]["status"] == "failed", rows
    assert "killed by SIGKILL" in rows["song 01.wav"]["error"] and "run the batch again" in rows["song 01.wav"]["error"]
    assert rows[BAD]["status"] == "failed" and "cannot decode" in rows[BAD]["error"]
    done_first = {n for n, r in rows.items() if r["status"] == "done"}
    assert done_first == {f"song {k:02d}.wav" for k in range(GOOD)} - {"song 01.wav"}
    assert [p.name for p in (out / "song_01").iterdir()] == []  # no final name, no temporary file left
    assert main(command) == 1  # the same command again
    assert f"1 danced, {GOOD - 1} already done, 1 failed" in capsys.readouterr().out
    status = _status(out)
    assert {n for n, s in status.items() if s == "skipped"} == done_first
    assert {n for n, s in status.items() if s == "done"} == {"song 01.wav"}  # only the missing song danced
    assert status[BAD] == "failed"
    _assert_same_as_generate(out, reference)


def test_kill_9_of_the_whole_batch_then_the_same_command_gives_the_uninterrupted_outputs(
        songs: Path, reference: dict, tmp_path: Path) -> None:
    out = tmp_path / "out"
    seed = int.from_bytes(os.urandom(4), "little")
    # a random point of the batch's own progress, whatever the machine's speed: after 0 to 4 of the 11 songs
    # (from the workers' start to mid-run), then up to half a song's time
    rng = random.Random(seed)
    after, delay = rng.randrange(GOOD // 2), rng.uniform(0.0, 0.5)
    run = subprocess.Popen(_command(songs, out), cwd=ROOT, env=_cold(tmp_path), stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL, start_new_session=True)
    _wait_for(run, out, after)
    time.sleep(delay)
    os.killpg(run.pid, signal.SIGKILL)  # the batch and its workers at once, as `kill -9 -PGID` does
    assert run.wait() == -signal.SIGKILL, f"the batch ended before the kill (seed {seed})"
    # whatever was under a final name is whole: the very bytes of the song's file
    for folder in (p for p in out.glob("song_*") if p.is_dir()):
        for p in folder.iterdir():
            if TEMP_MARK not in p.name:
                assert _files(folder)[p.name] == reference[folder.name][p.name], (p, f"seed {seed}")
    rerun = subprocess.run(_command(songs, out), cwd=ROOT, env=_cold(tmp_path), capture_output=True, text=True,
                           timeout=HANG_S)
    assert rerun.returncode == 1, (rerun.stderr, f"seed {seed}")
    assert set(_status(out).values()) <= {"done", "skipped", "failed"}
    assert [n for n, s in _status(out).items() if s == "failed"] == [BAD]
    _assert_same_as_generate(out, reference)
    assert not any(TEMP_MARK in p.name for p in (out / RECORDS).iterdir())


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="finds the workers through /proc")
def test_ctrl_c_stops_the_batch_and_its_workers_and_keeps_what_was_done(songs: Path, reference: dict,
                                                                       tmp_path: Path) -> None:
    out = tmp_path / "out"
    run = subprocess.Popen(_command(songs, out), cwd=ROOT, env=_cold(tmp_path), stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True, start_new_session=True,
                           preexec_fn=as_a_terminal_signals_it)
    _wait_for(run, out, 1)
    workers = _children(run.pid)
    os.killpg(run.pid, signal.SIGINT)  # what Ctrl-C in its terminal sends
    _stdout, stderr = run.communicate(timeout=30)
    assert run.returncode == 130 and stderr.strip().splitlines()[-1] == "dancenet: interrupted", stderr
    assert workers and not any(Path(f"/proc/{pid}").exists() for pid in workers)
    assert "Traceback" not in stderr
    done = {n for n, s in _status(out).items() if s == "done"}
    assert done and [p for p in out.rglob("*") if TEMP_MARK in p.name] == []
    rerun = subprocess.run(_command(songs, out), cwd=ROOT, env=_cold(tmp_path), capture_output=True, text=True,
                           timeout=HANG_S)
    assert rerun.returncode == 1, rerun.stderr
    assert {n for n, s in _status(out).items() if s == "skipped"} == done
    _assert_same_as_generate(out, reference)


def _stopped_worker(conn: Connection, row: tuple | None) -> None:
    """A worker still running when the batch stops, which has sent its song's row (`row`) or not (None)."""
    if row is not None:
        conn.send(row)
    time.sleep(HANG_S)


def test_a_stop_reports_the_row_a_worker_sent_and_kills_the_workers(tmp_path: Path) -> None:
    """What Ctrl-C meets when two workers end their first songs together: one row read, the other still in its
    pipe. That song's files are all written, so the table calls it done, as the next run finds it."""
    spawn = mp.get_context("spawn")
    busy = {}
    for i, row in ((3, {"status": "done", "frames": 95}), (4, None)):
        ours, theirs = spawn.Pipe()
        worker = spawn.Process(target=_stopped_worker, args=(theirs, None if row is None else (i, row)))
        worker.start()
        theirs.close()
        song = CatalogSong(f"song {i:02d}.wav", tmp_path / f"song {i:02d}.wav", f"song_{i:02d}")
        busy[ours] = (worker, (i, song, "request"))
    assert next(iter(busy)).poll(HANG_S)  # the row is in the pipe, unread
    ended = []
    _stop(tmp_path, busy, lambda i, row: ended.append((i, row)))
    assert ended == [(3, {"status": "done", "frames": 95})]
    assert [worker.exitcode for worker, _item in busy.values()] == [-signal.SIGKILL] * 2


def test_the_csv_gives_each_song_its_settings(songs: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    listing = tmp_path / "list" / "catalog.csv"
    listing.parent.mkdir()
    listing.write_text("song,style,seed,start,end,takes,fps,root-motion\n"
                       f"{songs / 'song 01.wav'},waltz,3,,,,,\n"
                       f"../{songs.name}/song 02.wav,,,0.5,3.5,2,30,in-place\n"
                       f"{songs / 'song 03.wav'},,,,,,,\n")
    (tmp_path / songs.name).symlink_to(songs)  # the CSV's relative path: from its own folder
    out = tmp_path / "out"
    assert main(["batch", str(listing), "-o", str(out), "--jobs", "2", "--seed", "5"]) == 0
    capsys.readouterr()
    runs = {"song_01": ["--style", "waltz", "--seed", "3"],
            "song_02": ["--seed", "5", "--start", "0.5", "--end", "3.5", "--takes", "2", "--fps", "30",
                        "--root-motion", "in-place"],
            "song_03": ["--seed", "5"]}
    for name, flags in runs.items():
        alone = tmp_path / "alone" / name
        song = songs / f"{name.replace('_', ' ')}.wav"
        if name == "song_02":  # the summary names the song as the list does
            song = listing.parent / f"../{songs.name}/song 02.wav"
        assert main(["generate", str(song), "-o", str(alone), *flags]) == 0
        assert _files(out / name) == _files(alone), name
    capsys.readouterr()
    assert json.loads((out / "song_01" / "song_01.json").read_text())["style"] == "waltz"
    assert sorted(p.name for p in (out / "song_02").iterdir()) == [
        "song_02.json", "song_02_take1.bvh", "song_02_take1.npz", "song_02_take2.bvh", "song_02_take2.npz"]


@pytest.mark.parametrize(("text", "says"), [
    ("song,colour\nx.wav,red\n", "unknown column 'colour'"),
    ("song,seed\nx.wav,three\n", "line 2: seed must be a whole number, got 'three'"),
    ("title\nx.wav\n", "has no 'song' column"),
])
def test_a_bad_csv_is_one_line(text: str, says: str, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    listing = tmp_path / "catalog.csv"
    listing.write_text(text)
    assert main(["batch", str(listing), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("dancenet: error: ") and says in err[0], err
    assert not (tmp_path / "out").exists()


def _distinct(name: str, kind: type, choices: tuple) -> tuple[str, Any]:
    """A cell for the setting `name` and the value it must give, distinct from every other setting's."""
    if choices:
        cell = choices[-1][0]
        return cell, kind(cell)
    number = 10 + sorted(n for n, _d, o in options() if o.flag).index(name)  # each setting its own number
    if kind is bool:  # the switches (on by default): every other one turned off
        switches = [n for n, _d, o in options() if o.flag and o.kind is bool]
        return ("no", False) if switches.index(name) % 2 == 0 else ("yes", True)
    cells = {int: str(number), float: f"{number}.5", str: f"value-{name}"}
    if kind in cells:
        return cells[kind], kind(cells[kind])
    return None, None


def test_every_request_option_is_a_csv_column(tmp_path: Path) -> None:
    """Each column's own value lands in its own setting (a column read into another field fails)."""
    columns, cells, want = [], [], {}
    for name, _default, o in options():
        if not o.flag:
            continue
        column = o.flag.lstrip("-").removeprefix("no-")
        cell, value = _distinct(name, o.kind, o.choices)
        if name in ("library", "weights"):
            cell, value = f"{column}-folder", tmp_path / f"{column}-folder"
            value = value if o.kind is Path else str(value)
        elif cell is None:  # a setting of its own syntax (--section): its own test
            continue
        columns.append(column)
        cells.append(cell)
        want[name] = value
    listing = tmp_path / "all.csv"
    rows = [["song", *columns], ["x.wav", *([""] * len(columns))], ["y.wav", *cells]]
    listing.write_text("".join(",".join(row) + "\n" for row in rows))
    first, second = read_catalog([listing])
    assert first.settings == {} and first.path == tmp_path / "x.wav"
    assert second.settings == want


def test_lists_folders_and_names(songs: Path, tmp_path: Path) -> None:
    listing = tmp_path / "songs.txt"
    listing.write_text(f"# two songs\n{songs / 'song 00.wav'}\n\n{songs / 'song 00.wav'}\n")
    catalog = read_catalog([listing, songs])
    assert [s.folder for s in catalog[:2]] == ["song_00", "song_00"]
    assert len(catalog) == 2 + GOOD + 1
    out = tmp_path / "out"
    (out / "song_00").mkdir(parents=True)
    (out / "song_00" / "mine.blend").write_bytes(b"the user's")  # never written into
    task = GenerateTask({name: default for name, default, o in options() if o.flag})
    status = run_catalog(catalog[:2], out, task, where="inline")
    assert [r["folder"] for r in status.rows] == ["song_00_2", "song_00_3"]
    assert [p.name for p in (out / "song_00").iterdir()] == ["mine.blend"]
    again = run_catalog(catalog[:2], out, task, where="inline")
    assert [r["status"] for r in again.rows] == ["skipped", "skipped"]


def test_a_cluster_task_dances_from_the_bytes_it_is_sent(songs: Path, reference: dict) -> None:
    """What a Ray node runs, without Ray: the song's bytes in, its files out; the path it was read from on the
    driver is not there."""
    task = GenerateTask({name: default for name, default, o in options() if o.flag} | {"seed": 7})
    song = read_catalog([songs / "song 04.wav"])[0]
    rid = request_id(song, task)
    elsewhere = CatalogSong(song.label, Path("/nowhere/on/this/node") / song.path.name, song.folder)
    row, files = _ray_song(task, elsewhere, song.path.read_bytes(), rid)
    assert row["status"] == "done", row
    summary = json.loads(files["song_04.json"])
    assert summary["song"] == song.label  # the driver's name for it, not the node's copy
    assert files["song_04.bvh"] == reference["song_04"]["song_04.bvh"]
    assert files["song_04.npz"] == reference["song_04"]["song_04.npz"]


def test_without_ray_the_cluster_is_one_line(songs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                             capsys: pytest.CaptureFixture) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # what `import ray` meets where Ray is not installed
    assert main(["batch", str(songs), "-o", str(tmp_path / "out"), "--cluster", "ray"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'pip install "dancenet[cluster]"' in err[0], err
    assert not (tmp_path / "out").exists()


def test_a_cluster_that_does_not_answer_is_one_line_in_seconds(songs: Path, tmp_path: Path,
                                                                capsys: pytest.CaptureFixture) -> None:
    pytest.importorskip("ray")
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    t = time.monotonic()
    assert main(["batch", str(songs), "-o", str(tmp_path / "out"), "--cluster", "ray",
                 "--address", f"127.0.0.1:{port}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"no Ray cluster answers at 127.0.0.1:{port}" in err[0], err
    assert time.monotonic() - t < 30 and not (tmp_path / "out").exists()


def test_a_local_ray_cluster_writes_the_same_bytes(songs: Path, reference: dict, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture) -> None:
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, logging_level="ERROR")
    try:
        out = tmp_path / "out"
        assert _batch(str(songs), "-o", str(out), "--cluster", "ray") == 1
        assert f"{GOOD} danced, 0 already done, 1 failed" in capsys.readouterr().out
        _assert_same_as_generate(out, reference)
        assert "cannot decode" in _rows(out)[BAD]["error"]
        assert _batch(str(songs), "-o", str(out), "--cluster", "ray") == 1
        assert f"0 danced, {GOOD} already done, 1 failed" in capsys.readouterr().out
    finally:
        ray.shutdown()


@pytest.mark.skipif(importlib.util.find_spec("bpy") is None, reason="needs the bpy module (the blender extra)")
def test_fbx_for_every_take_beside_generate_s_files(songs: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture) -> None:
    """As a user runs it: the command in a process of its own (a process that has loaded bpy puts Blender's
    script folders on sys.path, which a worker it spawns inherits)."""
    out = tmp_path / "out"
    song = songs / "song 05.wav"
    run = subprocess.run([sys.executable, "-m", "dancenet_core.cli", "batch", str(song), "-o", str(out), "--fbx",
                          "--takes", "2", "--jobs", "1"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    alone = tmp_path / "alone"
    assert main(["generate", str(song), "-o", str(alone), "--takes", "2"]) == 0
    files = _files(out / "song_05")
    for take in (1, 2):
        assert files.pop(f"song_05_take{take}.fbx").startswith(b"Kaydara FBX Binary")
    assert files == _files(alone)


@pytest.mark.skipif(importlib.util.find_spec("bpy") is None, reason="needs the bpy module (the blender extra)")
def test_fbx_loads_neither_bpy_nor_the_add_on_in_the_core_s_process(songs: Path, tmp_path: Path) -> None:
    """A worker's own song (the task it runs) with --fbx, in a fresh interpreter: the FBX files are written, by
    the add-on's writer in a child process (after a song it failed, in one line), and the worker's process has
    loaded neither bpy nor any add-on code."""
    probe = (
        "import json, sys\nfrom pathlib import Path\nfrom dancenet_core.catalog import CatalogSong\n"
        "from dancenet_core.commands.batch import GenerateTask, write_fbx_takes\n"
        "from dancenet_core.errors import DanceNetError\nfrom dancenet_core.request import DanceRequest, options\n"
        f"song = Path({str(songs / 'song 03.wav')!r})\n"
        "try:\n    write_fbx_takes('not a result', DanceRequest(song), [])\n"
        "except DanceNetError as e:\n    said = str(e)\n"
        "defaults = {name: default for name, default, o in options() if o.flag} | {'takes': 2, 'seed': 7}\n"
        "row = GenerateTask(defaults, fbx=True)(CatalogSong(str(song), song, 'song_03'), "
        f"Path({str(tmp_path / 'song_03')!r}))\n"
        "print(json.dumps([said, row['files'], sorted(sys.modules)]))"
    )
    (tmp_path / "song_03").mkdir()  # as dance_song makes it
    run = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    said, files, modules = json.loads(run.stdout.splitlines()[-1])
    assert said == "--fbx: AttributeError: 'str' object has no attribute 'motions'"  # and the writer goes on
    assert {"song_03_take1.fbx", "song_03_take2.fbx"} <= set(files)
    assert (tmp_path / "song_03" / "song_03_take2.fbx").read_bytes().startswith(b"Kaydara FBX Binary")
    loaded = [m for m in modules if m.split(".")[0] in ("bpy", "blender_addon", "batch", "fbx_takes")]
    assert loaded == []
    assert not [m for m in modules if "addon" in m]


@pytest.mark.skipif(importlib.util.find_spec("bpy") is None, reason="needs the bpy module (the blender extra)")
def test_a_failing_fbx_writer_is_one_line_in_the_song_s_record_and_leaves_no_file(
        songs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The writer's traceback ends as one line of the song's row; none of the song's files is written, not even
    those written before the FBX (generate's own), and no temporary file is left."""
    from dancenet_core.commands import batch

    writer = tmp_path / "writer.py"
    writer.write_text("import sys\nprint('some chatter', file=sys.stderr)\nraise RuntimeError('no rig here')\n")
    monkeypatch.setattr(batch, "FBX_WRITER", writer)
    song = songs / "song 04.wav"
    out = tmp_path / "out"
    defaults = {name: default for name, default, o in options() if o.flag} | {"seed": 7}
    status = run_catalog(read_catalog([song]), out, GenerateTask(defaults, fbx=True), where="inline")
    assert status.counts()["failed"] == 1
    row = _rows(out)["song 04.wav"]
    assert row["error"] == "--fbx: RuntimeError: no rig here"
    assert not (out / "song_04").exists() or not any((out / "song_04").iterdir())

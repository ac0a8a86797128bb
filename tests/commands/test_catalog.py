"""The catalog runner's own guarantees, with a task that dances nothing (one small file a song): the song lists
as a spreadsheet saves them, what a song's request is made of and what a rerun reads, the folders' names, the
records, each song's memory, and the Ray driver's address and writes."""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import soundfile as sf
from made_up import music

from dancenet_core.catalog import RECORDS, CatalogSong, finished, read_catalog, request_id, run_catalog
from dancenet_core.catalog.cluster import check_reachable
from dancenet_core.errors import DanceNetError
from dancenet_core.music.audio import MADMOM_SAMPLE_RATE

ROOT = Path(__file__).resolve().parents[2]
HANG_S = 600


@dataclass(frozen=True)
class Writes:
    """A task that dances nothing: one small file a song, after holding `hold_mb` of memory for the songs named
    in `heavy`. At module level: a spawned worker unpickles it."""

    heavy: tuple[str, ...] = ()
    hold_mb: int = 0

    def settings(self, song: CatalogSong) -> dict[str, Any]:
        return {"engine": "dancenet", "library": None, **song.settings}

    def outputs_key(self) -> dict[str, Any]:
        return {}

    def __call__(self, song: CatalogSong, folder: Path) -> dict[str, Any]:
        if song.folder in self.heavy:
            held = bytearray(self.hold_mb << 20)
            held[:: 1 << 12] = b"\1" * len(held[:: 1 << 12])  # every page touched: resident
        (folder / "moves.txt").write_text(song.label)
        return {"style": "test", "tempo_bpm": 120.0, "frames": 1, "duration_s": 0.1, "takes": 1,
                "files": ["moves.txt"]}


def _wav(path: Path, seconds: float = 0.2) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    sf.write(path, music(seconds, seed=len(path.name)), MADMOM_SAMPLE_RATE)
    return path


def test_a_song_named_like_the_status_table_gets_a_folder_of_its_own(tmp_path: Path) -> None:
    songs = [_wav(tmp_path / "songs" / name) for name in ("batch.csv.wav", "batch.json.flac", "BATCH.CSV.ogg")]
    out = tmp_path / "out"
    status = run_catalog(read_catalog(songs), out, Writes(), where="inline")
    assert [r["status"] for r in status.rows] == ["done"] * 3, status.rows
    assert [r["folder"] for r in status.rows] == ["batch.csv_2", "batch.json_2", "BATCH.CSV_3"]
    assert (out / "batch.csv").is_file() and (out / "batch.json").is_file()


def test_a_library_column_does_not_enter_a_dancenet_song_s_request(tmp_path: Path) -> None:
    song = CatalogSong("a.wav", _wav(tmp_path / "a.wav"), "a")
    (tmp_path / "clips").mkdir()
    with_library = CatalogSong("a.wav", song.path, "a", {"library": tmp_path / "clips"})
    assert request_id(with_library, Writes()) == request_id(song, Writes())  # DanceNet does not read a library


def test_a_stray_file_in_the_library_leaves_the_request_alone(tmp_path: Path) -> None:
    library = tmp_path / "clips"
    library.mkdir()
    (library / "walk.bvh").write_text("HIERARCHY")
    song = CatalogSong("a.wav", _wav(tmp_path / "a.wav"), "a", {"library": library, "engine": "library"})
    rid = request_id(song, Writes())
    (library / ".DS_Store").write_bytes(b"Finder's")  # not a clip: the same library
    assert request_id(song, Writes()) == rid
    (library / "walk.bvh").write_text("HIERARCHY again")  # another clip: another library
    assert request_id(song, Writes()) != rid


# A later run of the batch, in a process of its own: the songs' statuses and the songs it opened.
RERUN = """
import builtins, json, sys
from pathlib import Path
sys.path[:0] = sys.argv[1:3]
from test_catalog import Writes
from dancenet_core.catalog import read_catalog, run_catalog
songs, opened, real_open = sys.argv[4:], [], builtins.open
def watched(file, *args, **kwargs):
    opened.extend(str(file) for song in songs if str(file) == song)
    return real_open(file, *args, **kwargs)
builtins.open = watched
status = run_catalog(read_catalog([Path(s) for s in songs]), Path(sys.argv[3]), Writes(), where="inline")
print(json.dumps([[r["status"] for r in status.rows], opened]))
"""


def test_a_rerun_reads_no_song_unchanged_since_the_last_run(tmp_path: Path) -> None:
    """The songs' digests are kept by size and time under .batch/: a catalog of tens of thousands of songs resumes
    without reading them again, and a song changed since is read and danced again."""
    songs = [str(_wav(tmp_path / "songs" / f"{k}.wav", 0.2 + 0.1 * k)) for k in range(3)]
    out = tmp_path / "out"

    def rerun() -> list:
        here = Path(__file__).parent
        run = subprocess.run([sys.executable, "-c", RERUN, str(here), str(here.parent), str(out), *songs], cwd=ROOT,
                             capture_output=True, text=True, timeout=HANG_S)
        assert run.returncode == 0, run.stderr
        return json.loads(run.stdout.splitlines()[-1])

    assert rerun() == [["done"] * 3, songs]
    assert rerun() == [["skipped"] * 3, []]
    sf.write(songs[1], music(0.3, seed=99), MADMOM_SAMPLE_RATE)  # the same size, other bytes, a later time
    os.utime(songs[1], ns=(time.time_ns(), time.time_ns() + 10**9))
    assert rerun() == [["skipped", "done", "skipped"], [songs[1]]]


def test_a_hand_edited_record_is_danced_again(tmp_path: Path) -> None:
    (song,) = read_catalog([_wav(tmp_path / "a.wav")])
    out = tmp_path / "out"
    run_catalog([song], out, Writes(), where="inline")
    record = out / RECORDS / "a.json"
    rid = json.loads(record.read_text())["request_id"]
    assert finished(out, song, rid) is not None
    record.write_text(json.dumps(json.loads(record.read_text()) | {"kept": "style=test"}))
    assert finished(out, song, rid) is None
    assert [r["status"] for r in run_catalog([song], out, Writes(), where="inline").rows] == ["done"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the song's own peak: Linux's clear_refs")
def test_each_song_s_peak_memory_is_its_own(tmp_path: Path) -> None:
    """A 300-MB song then a light one in the same process: the light one's row says its own peak."""
    songs = read_catalog([_wav(tmp_path / "heavy.wav"), _wav(tmp_path / "light.wav")])
    status = run_catalog(songs, tmp_path / "out", Writes(heavy=("heavy",), hold_mb=300), where="inline")
    heavy, light = (row["peak_memory_mb"] for row in status.rows)
    assert heavy > light + 200, status.rows


def test_a_ray_head_at_an_ipv6_address_is_reached(tmp_path: Path) -> None:
    if not socket.has_ipv6:
        pytest.skip("no IPv6 on this machine")
    with socket.socket(socket.AF_INET6) as head:
        try:
            head.bind(("::1", 0))
        except OSError:
            pytest.skip("no IPv6 loopback on this machine")
        head.listen()
        port = head.getsockname()[1]
        check_reachable(f"[::1]:{port}")  # answers: no error
        check_reachable(f"ray://[::1]:{port}")
    with pytest.raises(DanceNetError, match=r"no Ray cluster answers at \[::1\]"):
        check_reachable(f"[::1]:{port}")


def test_a_song_that_cannot_be_written_here_fails_alone_on_ray(tmp_path: Path) -> None:
    """The driver writes a cluster song's files: a write refused for one song (its folder turned into a file
    after its first run) fails that song, as a local worker does, and the others are done."""
    ray = pytest.importorskip("ray")
    songs = read_catalog([_wav(tmp_path / "songs" / f"{k}.wav", 0.2 + 0.1 * k) for k in range(2)])
    out = tmp_path / "out"
    run_catalog(songs[:1], out, Writes(), where="inline")
    shutil.rmtree(out / "0")
    (out / "0").write_bytes(b"in the way")
    ray.init(num_cpus=1, include_dashboard=False, logging_level="ERROR")
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])  # `Writes` sent whole: tests/ is not on the path
    try:
        status = run_catalog(songs, out, Writes(), where="ray", force=True)
    finally:
        ray.cloudpickle.unregister_pickle_by_value(sys.modules[__name__])
        ray.shutdown()
    first, second = status.rows
    assert first["status"] == "failed" and "cannot write" in first["error"], first
    assert second["status"] == "done" and (out / "1" / "moves.txt").read_text() == songs[1].label

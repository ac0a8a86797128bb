"""The commercial-use mode: a commercial `generate`, `batch` and `library build` open no file with a non-commercial or
unknown licence (every file opened is recorded by an audit hook, in a fresh interpreter so that nothing a test
loaded before is cached), every output's JSON names the parts used and their terms, the parts it leaves out are
one line that says why, and the style comes from the user or the song's tempo and meter."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from dancenet_core.bvh import write_bvh
from dancenet_core.cli import main
from dancenet_core.engines.styles import style_by_tempo
from dancenet_core.licence import NON_COMMERCIAL_FILES

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))
sys.path.insert(0, str(Path(__file__).resolve().parent / "library"))

from synth_songs import SongSpec, write_song  # noqa: E402
from test_library import dancer  # noqa: E402

# Run in a fresh interpreter: record every file opened under the package, madmom and the data folder while the CLI
# runs the given arguments, then write them to the JSON file named first.
RECORDER = """
import importlib.util, json, os, sys
roots = [os.path.dirname(importlib.util.find_spec(m).origin) for m in ("dancenet_core", "madmom")]
roots.append(os.environ["DANCENET_DATA"])
opened = []
def hook(event, args):
    if event == "open" and isinstance(args[0], (str, bytes)):
        path = os.path.abspath(os.fsdecode(args[0]))
        if any(path.startswith(os.path.abspath(r)) for r in roots):
            opened.append(path)
sys.addaudithook(hook)
from dancenet_core.cli import main
code = main(sys.argv[2:])
json.dump({"code": code, "opened": opened}, open(sys.argv[1], "w"))
"""


CACHE = Path()


@pytest.fixture(scope="module")
def own_clips(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A user's folder of clips in two styles (subfolders name them), and the module's cache (`recorded`)."""
    global CACHE
    CACHE = tmp_path_factory.mktemp("cache")
    folder = tmp_path_factory.mktemp("clips")
    for style, bpms in (("waltz", (84, 90)), ("tango", (120, 128))):
        (folder / style).mkdir()
        for k, bpm in enumerate(bpms):
            write_bvh(folder / style / f"{style}{k}.bvh", dancer(24, bpm, amplitude=0.3 + 0.1 * k, phase=k))
    return folder


@pytest.fixture(scope="module")
def waltz_song(tmp_path_factory: pytest.TempPathFactory) -> Path:
    song = tmp_path_factory.mktemp("song") / "waltz.ogg"
    write_song(SongSpec(87, 3, False, 16.0, seed=5), song)
    return song


def recorded(tmp_path: Path, *args: str) -> dict:
    """The CLI run on `args` in a fresh interpreter: its exit code, the files it opened (see RECORDER) and its
    stderr. The cache (built libraries, analyses) is the test module's."""
    out = tmp_path / f"opened_{len(list(tmp_path.glob('opened_*')))}.json"
    env = os.environ | {"DANCENET_CACHE": str(CACHE), "DANCENET_WORKERS": "1",
                        "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    env.setdefault("DANCENET_DATA", str(REPO.parent / "shared" / "data"))
    run = subprocess.run([sys.executable, "-c", RECORDER, str(out), *args], env=env, cwd=tmp_path,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    return json.loads(out.read_text()) | {"stderr": run.stderr}


def non_commercial(opened: list[str]) -> list[str]:
    return [p for p in opened if any(f in Path(p).as_posix() for f in NON_COMMERCIAL_FILES)]


def test_a_commercial_dance_opens_no_non_commercial_file(tmp_path: Path, own_clips: Path, waltz_song: Path) -> None:
    built = recorded(tmp_path, "library", "build", str(own_clips), "--commercial")
    assert built["code"] == 0 and not non_commercial(built["opened"])
    danced = recorded(tmp_path, "generate", str(waltz_song), "-o", str(tmp_path / "out"), "--commercial",
                      "--engine", "library", "--library", str(own_clips))
    assert danced["code"] == 0, danced["stderr"]
    assert danced["opened"], "the recorder saw no file of the package opened: it records nothing"
    assert not non_commercial(danced["opened"])
    summary = json.loads((tmp_path / "out" / "waltz.json").read_text())
    assert summary["licence"]["mode"] == "commercial" and summary["licence"]["commercial_use"] is True
    assert summary["style"] == "waltz"  # no classifier: the waltz's tempo and meter (87 BPM, 3/4)
    assert any("tempo" in p["part"] for p in summary["licence"]["parts"])


def test_the_default_mode_opens_them_and_says_so(tmp_path: Path, own_clips: Path, waltz_song: Path) -> None:
    """The same dance in the default mode: the recorder sees madmom's models and the trained weights opened, and the
    licence block says the dance is not for commercial use."""
    recorded(tmp_path, "library", "build", str(own_clips))
    danced = recorded(tmp_path, "generate", str(waltz_song), "-o", str(tmp_path / "out"), "--engine", "library",
                      "--library", str(own_clips))
    assert danced["code"] == 0, danced["stderr"]
    seen = [Path(p).as_posix() for p in non_commercial(danced["opened"])]
    assert any("madmom/models/" in p for p in seen)  # the default analysis' networks
    assert any(p.endswith("dancenet_core/weights/style_classifier.npz") for p in seen)  # waltz and tango: heard
    summary = json.loads((tmp_path / "out" / "waltz.json").read_text())
    assert summary["licence"]["mode"] == "non-commercial" and summary["licence"]["commercial_use"] is False


def test_a_commercial_batch_opens_no_non_commercial_file(tmp_path: Path, own_clips: Path, waltz_song: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """A batch in the commercial mode (its settings), and a list's `commercial` column that asks it of one song of
    a default batch."""
    recorded(tmp_path, "library", "build", str(own_clips))
    run = recorded(tmp_path, "batch", str(waltz_song), "-o", str(tmp_path / "out"), "--jobs", "1", "--commercial",
                   "--engine", "library", "--library", str(own_clips))
    assert run["code"] == 0, run["stderr"]
    assert not non_commercial(run["opened"])
    summary = json.loads((tmp_path / "out" / "waltz" / "waltz.json").read_text())
    assert summary["licence"]["commercial_use"] is True
    listing = tmp_path / "songs.csv"
    with listing.open("w", newline="") as f:
        csv.writer(f).writerows([["song", "commercial", "engine", "library"],
                                 [str(waltz_song), "yes", "library", str(own_clips)]])
    monkeypatch.setenv("DANCENET_CACHE", str(CACHE))  # the library built above
    assert main(["batch", str(listing), "-o", str(tmp_path / "listed"), "--jobs", "1"]) == 0
    summary = json.loads((tmp_path / "listed" / "waltz" / "waltz.json").read_text())
    assert summary["licence"]["mode"] == "commercial" and summary["licence"]["commercial_use"] is True


@pytest.mark.parametrize(("args", "says"), [
    (["--commercial"], "DanceNet was trained on Dance with Melody"),
    (["--commercial", "--engine", "library"], "give --library FOLDER"),
    (["--commercial", "--engine", "library", "--library", "x", "--weights", "w.npz"], "leave --weights out"),
])
def test_an_excluded_part_is_one_line_that_says_why(tmp_path: Path, waltz_song: Path, capsys: pytest.CaptureFixture,
                                                    args: list[str], says: str) -> None:
    assert main(["generate", str(waltz_song), "-o", str(tmp_path / "out"), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and "\n" not in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_analyze_commercial_reads_the_style_from_tempo_and_meter(tmp_path: Path, waltz_song: Path,
                                                                 capsys: pytest.CaptureFixture) -> None:
    assert main(["analyze", str(waltz_song), "--commercial", "--style-model", "x.npz"]) == 2
    assert "leave --style-model out" in capsys.readouterr().err
    assert main(["analyze", str(waltz_song), "--commercial", "--json", str(tmp_path / "a.json"),
                 "--cache-dir", str(tmp_path / "cache")]) == 0
    out = json.loads((tmp_path / "a.json").read_text())
    assert out["style"]["style"] == "waltz" and out["style"]["meter"] == 3
    assert out["licence"]["commercial_use"] is True and out["tempo_bpm"] == pytest.approx(87, rel=0.04)


def test_style_by_tempo_and_meter() -> None:
    styles = ["waltz", "Cha-Cha", "tango", "my_moves"]
    assert style_by_tempo(87, 3, styles) == "waltz"
    assert style_by_tempo(87, 4, styles) == ""  # a waltz's tempo in 4/4 is no waltz
    assert style_by_tempo(124, 4, styles) == "Cha-Cha"  # the cha-cha's and tango's ranges meet: the nearest centre
    assert style_by_tempo(129, 4, styles) == "tango"
    assert style_by_tempo(150, 4, styles) == ""  # nothing fits: every clip may dance

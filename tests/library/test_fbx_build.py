"""`dancenet library build` on FBX files written by Blender (tests/fbx_rigs.py: a Mixamo-like rig in centimetres
under a 0.01 scale with a skinned mesh, binary and ASCII, the same with the 0.01 on its own FBX node, a Z-up
generic rig in metres, an A-pose rig with Unreal's names, all danced by one made-up motion): read by worker
processes with Blender's module at their true size and as danced; cached by content; without the module one line
and the BVH clips built; a file that is no FBX or a broken one, one line each."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from fbx_rigs import FILES, SIZE, dance, sized, written

from dancenet_core.bvh import write_bvh
from dancenet_core.cli import main
from dancenet_core.library import fbx
from dancenet_core.library.store import MotionLibrary, library_path
from dancenet_core.skeleton import BODY_JOINTS, DEFAULT_SKELETON

pytestmark = pytest.mark.skipif(not fbx.bpy_installed(), reason="Blender's Python module (bpy) is not installed")
# How near a clip comes to the motion danced, joint by joint about the pelvis and along the pelvis' path over the
# floor (metres): the FBX file keeps float32 keys of centimetres, and both sides are resampled to 25 fps alike.
TOLERANCE_M = 2e-3


@pytest.fixture(scope="session")
def rigs(tmp_path_factory) -> Path:
    return written(tmp_path_factory)


@pytest.fixture
def cache(monkeypatch, tmp_path) -> Path:
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


@pytest.fixture
def sampled(monkeypatch) -> list[str]:
    """The files the worker processes sample (not those read from the cache)."""
    seen: list[str] = []
    sample = fbx.Worker.sample

    def counted(self, path: Path, out: Path) -> str | None:
        seen.append(path.name)
        return sample(self, path, out)

    monkeypatch.setattr(fbx.Worker, "sample", counted)
    return seen


def _folder(rigs: Path, where: Path, names: list[str]) -> Path:
    """A library folder of the named FBX files and a BVH clip of the same dancer."""
    where.mkdir()
    for name in names:
        shutil.copy(rigs / f"{name}.fbx", where / f"{name}.fbx")
    write_bvh(where / "bvh_clip.bvh", sized(dance()))
    return where


def _error(got: np.ndarray, want: np.ndarray) -> float:
    """Largest distance (m) between two position tracks [T, J, 3], about the pelvis and along its floor path."""
    about = np.linalg.norm((got - got[:, :1]) - (want - want[:, :1]), axis=-1).max()
    path = (got[:, 0, [0, 2]] - got[0, 0, [0, 2]]) - (want[:, 0, [0, 2]] - want[0, 0, [0, 2]])
    return float(max(about, np.linalg.norm(path, axis=-1).max()))


def test_the_command_line_reads_fbx_rigs_at_true_size_and_as_danced(rigs, cache, tmp_path, capsys, sampled):
    folder = _folder(rigs, tmp_path / "clips", list(FILES))
    assert main(["library", "build", str(folder), "--jobs", "2"]) == 0
    assert "; 0 left out;" in capsys.readouterr().out
    library = MotionLibrary.load(library_path(folder))
    assert sorted(library.names) == sorted([f"{n}.fbx" for n in FILES] + ["bvh_clip.bvh"]) and not library.notes
    assert sorted(sampled) == sorted(f"{n}.fbx" for n in FILES)
    # True size: every clip's skeleton is the rig's (SIZE times ours), the library's their mean; a rig read at a
    # hundredth of its size would have been refused (a dancer is 0.5-2.5 m), or shrunk the mean.
    tall = np.ptp(library.skeleton.rest_positions()[:, 1])
    assert 1.6 < tall < 1.9, tall
    np.testing.assert_allclose(library.offsets[:BODY_JOINTS], SIZE * DEFAULT_SKELETON.offsets[:BODY_JOINTS],
                               atol=1e-3)
    want = sized(dance()).resampled(25.0).positions()[:, :BODY_JOINTS]
    for c, name in enumerate(library.names):
        got = library.clip(c).positions()[:, :BODY_JOINTS]
        assert len(got) == len(want), name
        assert _error(got, want) < TOLERANCE_M, (name, _error(got, want))


def test_the_cache_samples_each_fbx_once(rigs, cache, tmp_path, sampled, capsys):
    folder = _folder(rigs, tmp_path / "clips", ["mixamo", "generic"])
    assert main(["library", "build", str(folder)]) == 0
    assert sorted(sampled) == ["generic.fbx", "mixamo.fbx"]
    sampled.clear()
    assert main(["library", "build", str(folder), "--force"]) == 0  # built again: every FBX read from the cache
    assert sampled == []
    shutil.copy(rigs / "apose.fbx", folder / "apose.fbx")
    assert main(["library", "build", str(folder)]) == 0  # one file more: only it is sampled
    assert sampled == ["apose.fbx"]
    assert len(MotionLibrary.load(library_path(folder)).names) == 4
    samples = list((cache / fbx.SAMPLE_VERSION).glob("*.npz"))
    assert len(samples) == 3
    capsys.readouterr()


def test_without_blenders_module_the_fbx_files_get_one_line_and_the_bvh_clips_build(rigs, cache, tmp_path,
                                                                                    monkeypatch, capsys, sampled):
    folder = _folder(rigs, tmp_path / "clips", ["mixamo", "apose"])
    monkeypatch.setattr(fbx, "bpy_installed", lambda: False)
    assert main(["library", "build", str(folder)]) == 0
    out = capsys.readouterr().out
    lines = [line for line in out.splitlines() if "FBX" in line]
    assert lines == ["left out the FBX files (2 FBX files: apose.fbx...): reading them needs Blender's Python module: "
                     "pip install 'dancenet[blender]' (Blender's Python module), or build the folder with Build "
                     "Library in Blender's DanceNet add-on"], out
    assert MotionLibrary.load(library_path(folder)).names == ["bvh_clip.bvh"] and sampled == []
    os.remove(folder / "bvh_clip.bvh")
    assert main(["library", "build", str(folder)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "holds only FBX files" in err and "pip install" in err, err
    # With the module back, the folder is read whole (the build that left the FBX files out is not kept).
    write_bvh(folder / "bvh_clip.bvh", sized(dance()))
    monkeypatch.undo()
    monkeypatch.setenv("DANCENET_CACHE", str(cache))
    assert main(["library", "build", str(folder)]) == 0
    assert len(MotionLibrary.load(library_path(folder)).names) == 3


def test_fbx_files_that_hold_no_dancer_are_one_line_each(rigs, cache, tmp_path, capsys):
    folder = _folder(rigs, tmp_path / "clips", ["generic"])
    (folder / "notes.fbx").write_text("these are my notes, not an FBX file\n")
    (folder / "ascii.fbx").write_text("; FBX 7.4.0 project file\nFBXHeaderExtension:  {\n}\n")
    assert main(["library", "build", str(folder)]) == 0
    notes = MotionLibrary.load(library_path(folder)).notes
    assert len(notes) == 2 and all("\n" not in n for n in notes), notes
    assert notes[0].startswith("left out ascii.fbx: Blender could not import it (") and "Location" not in notes[0]
    assert notes[1] == "left out notes.fbx: not an FBX file (it does not begin as one)", notes
    capsys.readouterr()


def test_a_worker_that_dies_costs_its_file_one_line_and_nothing_is_cached(rigs, cache, tmp_path, monkeypatch, capsys):
    folder = _folder(rigs, tmp_path / "clips", ["generic"])
    monkeypatch.setattr(fbx, "WORKER", "dancenet_core.no_such_worker")  # the worker process ends at once
    assert main(["library", "build", str(folder)]) == 0
    (note,) = MotionLibrary.load(library_path(folder)).notes
    assert note.startswith("left out generic.fbx: Blender's module stopped while reading it (") and "No module" in note
    assert not list(cache.glob(f"{fbx.SAMPLE_VERSION}/*.npz"))  # tried again next time
    capsys.readouterr()

"""Build Library in the add-on on a folder of FBX files written by Blender (tests/fbx_rigs.py): the Mixamo-like rig
(centimetres under a 0.01 scale, skinned mesh) as binary and ASCII FBX, the same with its 0.01 on its own FBX node
(which Blender imports at a hundredth of its size) and a Z-up generic rig read at their true size and as danced,
the file left as it was; the samples are cached by content, shared with the command line. With Blender's FBX
importer off, a file is not read and nothing is cached of it."""

from __future__ import annotations

from pathlib import Path

import addon_utils
import numpy as np
import pytest
from fbx_rigs import SIZE, dance, sized, written
from scene_helpers import bpy

from dancenet_core.library import fbx, fbx_worker
from dancenet_core.library.store import MotionLibrary, library_path
from dancenet_core.skeleton import BODY_JOINTS, DEFAULT_SKELETON

TOLERANCE_M = 2e-3  # as tests/library/test_fbx_build.py: the FBX file's float32 keys of centimetres


@pytest.fixture
def own_cache(monkeypatch, tmp_path) -> Path:
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def _counts() -> dict[str, int]:
    return {kind: len(getattr(bpy.data, kind)) for kind in dir(bpy.data)
            if isinstance(getattr(bpy.data, kind, None), bpy.types.bpy_prop_collection)}


def test_build_library_reads_mixamo_like_fbx_at_true_size(scene, addon, own_cache, tmp_path, tmp_path_factory):
    rigs = written(tmp_path_factory)
    folder = tmp_path / "downloads"
    folder.mkdir()
    for name in ("mixamo", "mixamo_node_scaled", "mixamo_ascii", "generic"):
        (folder / f"{name}.fbx").write_bytes((rigs / f"{name}.fbx").read_bytes())
    scene.dancenet.engine, scene.dancenet.library = "library", str(folder)
    counts = _counts()
    assert bpy.ops.dancenet.build_library() == {"FINISHED"}
    assert _counts() == counts  # the imports went, all of them
    library = MotionLibrary.load(library_path(folder))
    assert library.names == ["generic.fbx", "mixamo.fbx", "mixamo_ascii.fbx", "mixamo_node_scaled.fbx"]
    assert not library.notes
    assert 1.6 < np.ptp(library.skeleton.rest_positions()[:, 1]) < 1.9
    np.testing.assert_allclose(library.offsets[:BODY_JOINTS], SIZE * DEFAULT_SKELETON.offsets[:BODY_JOINTS],
                               atol=1e-3)
    want = sized(dance()).resampled(25.0).positions()[:, :BODY_JOINTS]
    for c, name in enumerate(library.names):
        got = library.clip(c).positions()[:, :BODY_JOINTS]
        about = np.linalg.norm((got - got[:, :1]) - (want - want[:, :1]), axis=-1).max()
        assert about < TOLERANCE_M, (name, about)
    # Each file's sample is cached by its content, as the command line's workers cache theirs.
    assert all(isinstance(fbx.load_sample(fbx.sample_path(f)), fbx.RigSample) for f in folder.iterdir())


def test_fbx_importer_off_is_said_and_not_cached(scene, addon, own_cache, tmp_path, tmp_path_factory):
    path = tmp_path / "mixamo.fbx"
    path.write_bytes((written(tmp_path_factory) / "mixamo.fbx").read_bytes())
    addon_utils.disable("io_scene_fbx")
    try:
        with pytest.raises(fbx_worker.ImporterOff, match="^Blender's FBX importer is off"):
            addon.rigclips.sample_fbx(path)
    finally:
        addon_utils.enable("io_scene_fbx")
    assert fbx.load_sample(fbx.sample_path(path)) is None
    assert isinstance(addon.rigclips.sample_fbx(path), fbx.RigSample)  # read once the importer is on again

"""Blender-side helpers of the add-on tests: Blender's user folders in a scratch directory (set before bpy
is first imported), pip bpy, and what several test files ask of a scene (bone positions, keyframes, rigs
built like other tools', the panel recorder)."""

from __future__ import annotations

import atexit
import importlib.util
import math
import os
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
_USER = Path(tempfile.mkdtemp(prefix="dancenet-addon-tests-"))
atexit.register(shutil.rmtree, _USER, ignore_errors=True)
BLENDER_ENV = {
    "BLENDER_USER_RESOURCES": str(_USER / "resources"),
    "BLENDER_USER_CONFIG": str(_USER / "config"),
    "BLENDER_USER_SCRIPTS": str(_USER / "scripts"),
    "BLENDER_USER_EXTENSIONS": str(_USER / "extensions"),
}
if "bpy" not in sys.modules:  # Blender reads these once, when bpy is first imported
    os.environ.update(BLENDER_ENV)
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

bpy = pytest.importorskip("bpy")

from dancenet_core.skeleton import DEFAULT_SKELETON, JOINT_NAMES  # noqa: E402

MM = 1e-3
IDENTITY_MAP = {n: n for n in JOINT_NAMES}


def world_heads(rig, bones) -> np.ndarray:
    return np.array([rig.matrix_world @ rig.pose.bones[b].head for b in bones])


def fk_world(motion) -> np.ndarray:
    """The core's FK joint positions [T, J, 3] in Blender's Z-up world."""
    from blender_addon.rigdef import Y_UP_TO_Z_UP

    return motion.positions() @ Y_UP_TO_Z_UP.T


def fcurves_of(action):
    slot = action.slots[0]
    return action.layers[0].strips[0].channelbag(slot).fcurves


def snapshot(scene) -> dict:
    """Everything a generation may touch, to show a cancelled or refused one touched nothing."""
    props = scene.dancenet
    editor = scene.sequence_editor
    return {
        "ids": {
            kind: sorted(i.name for i in getattr(bpy.data, kind))
            for kind in ("objects", "actions", "armatures", "meshes", "sounds", "texts", "materials")
        },
        "markers": [(m.name, m.frame) for m in scene.timeline_markers],
        "strips": None if editor is None else sorted(s.name for s in editor.strips_all),
        "frames": (scene.frame_start, scene.frame_end, scene.frame_current),
        "sync": scene.sync_mode,
        "props": {p.identifier: str(getattr(props, p.identifier)) for p in props.bl_rna.properties[1:]},
    }


def generate(scene, song: Path, **settings) -> set[str]:
    props = scene.dancenet
    props.music_source, props.music_file = "FILE", str(song)
    for key, value in settings.items():
        setattr(props, key, value)
    return bpy.ops.dancenet.generate()


def build_armature(name: str, bones, mixamo_import: bool = True, seed: int = 0):
    """An armature from (bone, parent, head, tail) rows, with random rolls (unlike ours).

    `mixamo_import`: stored like a Mixamo FBX import, Y-up centimetres turned and scaled 0.01 by the object.
    """
    from blender_addon.rig import armature_from_rows

    bones = list(bones)
    rng = np.random.default_rng(seed)
    obj = armature_from_rows(bpy.context, name, bones, {b[0]: rng.normal(size=3) for b in bones})
    if mixamo_import:
        obj.rotation_euler = (math.pi / 2, 0.0, 0.0)
        obj.scale = (0.01, 0.01, 0.01)
    bpy.context.view_layer.update()
    return obj


def assert_dances_like(rig, mapping: dict[str, str], motion, first_frame: int, scale: float) -> None:
    """Mapped bones point where our FK's joints point (< 0.5 degree) and the hips travel as our pelvis."""
    from blender_addon import rigdef
    from dancenet_core.jointmap import direction_child

    fk = fk_world(motion)
    pelvis = mapping["pelvis"]
    rest_hips = np.array(rig.matrix_world @ rig.data.bones[pelvis].head_local)
    ours_rest_pelvis = rigdef.rest_heads(DEFAULT_SKELETON)[0] @ rigdef.Y_UP_TO_Z_UP.T
    pairs = [
        (DEFAULT_SKELETON.index(j), c)
        for j in mapping
        if (c := direction_child(DEFAULT_SKELETON, DEFAULT_SKELETON.index(j))) is not None
        and JOINT_NAMES[c] in mapping
    ]
    assert len(pairs) >= 20
    for f in (0, motion.num_frames // 3, motion.num_frames - 1):
        bpy.context.scene.frame_set(first_frame + f)
        for j, c in pairs:
            head, child = world_heads(rig, [mapping[JOINT_NAMES[j]], mapping[JOINT_NAMES[c]]])
            theirs, ours = child - head, fk[f, c] - fk[f, j]
            cos = theirs @ ours / np.linalg.norm(theirs) / np.linalg.norm(ours)
            assert math.degrees(math.acos(min(1.0, cos))) < 0.5, (JOINT_NAMES[j], f)
        hips = world_heads(rig, [pelvis])[0]
        assert np.abs(hips - (rest_hips + scale * (fk[f, 0] - ours_rest_pelvis))).max() < MM


def panel_screenshot():
    """scripts/panel_screenshot.py: its UILayout recorder runs the real draw(), its painter makes docs/panel.png."""
    if "panel_screenshot" not in sys.modules:
        spec = importlib.util.spec_from_file_location("panel_screenshot", ROOT / "scripts" / "panel_screenshot.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module  # dataclasses look their module up while the class is built
        spec.loader.exec_module(module)
    return sys.modules["panel_screenshot"]


def modal_stand_in(operator: type):
    """A background operator's modal methods (Generate Dance's, Build Library's) on a plain object that keeps its
    reports: bpy as a module has no event loop to run the operator itself."""

    class StandIn:
        _begin, _start, _show, _end = operator._begin, operator._start, operator._show, operator._end
        modal, cancel, finish, doing = operator.modal, operator.cancel, operator.finish, operator.doing

        def __init__(self) -> None:
            self.reports: list[tuple[set[str], str]] = []

        def report(self, kind: set[str], message: str) -> None:
            self.reports.append((kind, message))

    return StandIn()

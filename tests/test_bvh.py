"""BVH reading and writing: FK checked by hand, every layout BVH allows, round trips, and error lines."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from made_up import data_root
from scipy.spatial.transform import Rotation

from dancenet_core.bvh import BvhData, BvhParseError, read_bvh, write_bvh, write_bvh_data
from dancenet_core.errors import DanceNetError
from dancenet_core.kinematics import fk_numpy
from dancenet_core.motion import Motion
from dancenet_core.skeleton import DEFAULT_SKELETON, EndSite, Skeleton

TOL = 1e-4  # 0.1 mm

CMU_DIR = data_root() / "cmu_dance"
CMU_FILES = sorted(CMU_DIR.glob("**/*.bvh")) if CMU_DIR.is_dir() else []

# A leg: hips -> knee -> ankle -> End Site, 1 m bones down -Y, a 0.5 m foot along +Z.
CHAIN = """HIERARCHY
ROOT hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT knee
  {
    OFFSET 0 -1 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT ankle
    {
      OFFSET 0 -1 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      End Site
      {
        OFFSET 0 0 0.5
      }
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.04
1 2 3 0 0 0 0 0 0 0 0 0
0 0 0 90 0 0 0 90 0 0 0 0
0 0 0 90 90 0 0 0 0 0 0 0
"""


def _write_text(tmp_path: Path, text: str, name: str = "walk.bvh") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _line_of(text: str, needle: str, occurrence: int = 1) -> int:
    """1-based number of the line holding the `occurrence`-th `needle`."""
    hits = [i + 1 for i, line in enumerate(text.splitlines()) if needle in line]
    return hits[occurrence - 1]


def test_chain_matches_hand_computed_fk(tmp_path: Path) -> None:
    data = read_bvh(_write_text(tmp_path, CHAIN))
    assert data.names == ("hips", "knee", "ankle")
    assert data.parents == (-1, 0, 1)
    assert data.fps == 25.0
    assert data.num_frames == 3
    assert data.values.shape == (3, 12)
    assert data.end_sites == (EndSite("ankle_end", 2, (0.0, 0.0, 0.5)),)
    expected = np.array(
        [
            [[1, 2, 3], [1, 1, 3], [1, 0, 3]],
            # hips turn 90 deg about Z: the leg points +X, then the knee bends 90 deg about X.
            [[0, 0, 0], [1, 0, 0], [1, 0, -1]],
            # Zrotation then Xrotation, intrinsic: R = Rz(90) Rx(90) swings the leg to -Z.
            [[0, 0, 0], [0, 0, -1], [0, 0, -2]],
        ],
        dtype=float,
    )
    ends = np.array([[[1, 0, 3.5]], [[1.5, 0, -1]], [[0.5, 0, -2]]])
    np.testing.assert_allclose(data.world_positions(), expected, atol=1e-12)
    np.testing.assert_allclose(data.end_site_positions(), ends, atol=1e-12)
    rot = Rotation.from_rotvec(data.local_rotations()[2, 0])
    np.testing.assert_allclose(
        rot.as_matrix(), Rotation.from_euler("ZX", [90, 90], degrees=True).as_matrix(), atol=1e-12
    )
    motion = data.to_motion()
    np.testing.assert_allclose(motion.positions(), expected, atol=1e-12)
    np.testing.assert_allclose(motion.end_effectors(), ends, atol=1e-12)


def _chain_file(root_channels: str, joint_channels: str, root_offset: str, values: np.ndarray) -> str:
    rows = "\n".join(" ".join(f"{v:.10f}" for v in row) for row in values)
    return (
        f"HIERARCHY\nROOT hips\n{{\n OFFSET {root_offset}\n"
        f" CHANNELS {len(root_channels.split())} {root_channels}\n"
        f" JOINT knee {{\n  OFFSET 0.1 -0.4 0.02\n  CHANNELS 3 {joint_channels}\n"
        f"  JOINT ankle {{ OFFSET 0 -0.4 -0.03\n   CHANNELS 3 {joint_channels}\n"
        f"   End Site {{ OFFSET 0 -0.05 0.12 }}\n  }}\n }}\n}}\n"
        f"MOTION\nFrames: {len(values)}\nFrame Time: 0.0333333\n{rows}\n"
    )


@pytest.mark.parametrize("order", ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"])
def test_every_rotation_order_agrees_with_fk_numpy(tmp_path: Path, order: str) -> None:
    rng = np.random.default_rng(len(order) + ord(order[0]) * 7 + ord(order[1]))
    t = 12
    rotvecs = Rotation.random(t * 3, random_state=rng).as_rotvec().reshape(t, 3, 3)
    root = rng.normal(size=(t, 3))
    euler = Rotation.from_rotvec(rotvecs.reshape(-1, 3)).as_euler(order, degrees=True).reshape(t, 3, 3)
    rot_names = " ".join(f"{a}rotation" for a in order)
    # Root: rotations first, positions last, names in odd case; the positions replace the OFFSET.
    values = np.concatenate([euler[:, 0], root, euler[:, 1], euler[:, 2]], axis=1)
    text = _chain_file(rot_names.upper() + " xposition Yposition ZPOSITION", rot_names, "0.5 1 0", values)
    data = read_bvh(_write_text(tmp_path, text))
    assert data.channels[0] == (*(f"{a}rotation" for a in order), "Xposition", "Yposition", "Zposition")
    assert data.fps == 30.0
    skeleton = Skeleton(data.offsets, data.names, data.parents, data.end_sites)
    pos, _, ends = fk_numpy(skeleton, rotvecs, root - data.offsets[0], with_end_sites=True)
    np.testing.assert_allclose(data.world_positions(), pos, atol=1e-9)
    np.testing.assert_allclose(data.end_site_positions(), ends, atol=1e-9)
    got = Rotation.from_rotvec(data.local_rotations().reshape(-1, 3)).as_matrix()
    np.testing.assert_allclose(got, Rotation.from_rotvec(rotvecs.reshape(-1, 3)).as_matrix(), atol=1e-9)
    np.testing.assert_allclose(data.to_motion().positions(), pos, atol=1e-9)


def test_root_with_rotation_channels_only_stays_at_its_offset(tmp_path: Path) -> None:
    values = np.array([[0, 0, 0, 0, 0, 0, 0, 0, 0], [0, 0, 90, 0, 0, 0, 0, 0, 0]], dtype=float)
    xyz = "Xrotation Yrotation Zrotation"
    data = read_bvh(_write_text(tmp_path, _chain_file(xyz, xyz, "0 1 0", values)))
    pos = data.world_positions()
    np.testing.assert_allclose(pos[:, 0], [[0, 1, 0], [0, 1, 0]])
    np.testing.assert_allclose(pos[1, 1], [0.4, 1.1, 0.02], atol=1e-12)  # (0.1, -0.4) turned 90 deg about Z
    np.testing.assert_allclose(data.to_motion().positions(), pos, atol=1e-12)


NESTED = """HIERARCHY
ROOT body
{
\tOFFSET 0 1 0
\tCHANNELS 3 Xposition Yposition Zposition
\tJOINT arm {
\t\tOFFSET 1 0 0
\t\tCHANNELS 6 Xposition Yposition Zposition Yrotation Xrotation Zrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 0 1
\t\t}
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 0 -1
\t\t}
\t\tJOINT hand
\t\t{
\t\t\tOFFSET 0.5 0 0
\t\t\tCHANNELS 0
\t\t}
\t}
}
ROOT prop
{
\tOFFSET 5 0 0
\tCHANNELS 1 Yrotation
\tJOINT tip
\t{
\t\tOFFSET 1 0 0
\t\tCHANNELS 0
\t}
}
MOTION
Frames: 2
Frame Time: 0.5
0 1 0 1 0 0 0 0 0 0
1 1 0 1.25 0 0 90 0 0 90
"""


def test_nested_layouts_end_sites_and_second_root(tmp_path: Path) -> None:
    data = read_bvh(_write_text(tmp_path, NESTED))
    assert data.names == ("body", "arm", "hand", "prop", "tip")
    assert data.parents == (-1, 0, 1, -1, 3)
    assert [len(c) for c in data.channels] == [3, 6, 0, 1, 0]
    assert [(s.name, s.parent) for s in data.end_sites] == [("arm_end", 1), ("arm_end2", 1)]
    pos = data.world_positions()
    # Position channels replace the OFFSET (position in the parent's frame), on any joint.
    np.testing.assert_allclose(pos[0], [[0, 1, 0], [1, 1, 0], [1.5, 1, 0], [5, 0, 0], [6, 0, 0]], atol=1e-12)
    # Frame 1: the arm turns 90 deg about Y, so its +X child ends up along -Z; the prop likewise.
    np.testing.assert_allclose(
        pos[1], [[1, 1, 0], [2.25, 1, 0], [2.25, 1, -0.5], [5, 0, 0], [5, 0, -1]], atol=1e-12
    )
    np.testing.assert_allclose(data.end_site_positions()[0], [[1, 1, 1], [1, 1, -1]], atol=1e-12)
    np.testing.assert_allclose(data.end_site_positions()[1], [[3.25, 1, 0], [1.25, 1, 0]], atol=1e-12)
    np.testing.assert_allclose(data.local_translations()[1, 1], [1.25, 0, 0])
    with pytest.raises(DanceNetError, match="2 root joints"):
        data.to_motion()
    single = BvhData(
        data.names[:3],
        data.parents[:3],
        data.offsets[:3],
        data.channels[:3],
        data.end_sites,
        data.frame_time,
        data.values[:, :9],
    )
    with pytest.raises(DanceNetError, match="'arm' changes its position over time"):
        single.to_motion()
    # Held still (as Blender writes unconnected bones), the arm's position channels become its offset.
    still = replace(single, values=np.tile(single.values[1], (2, 1)))
    motion = still.to_motion()
    assert motion.skeleton.offsets[1].tolist() == [1.25, 0, 0]
    np.testing.assert_allclose(motion.positions(), still.world_positions(), atol=1e-12)
    path = tmp_path / "again.bvh"
    write_bvh_data(path, data)
    again = read_bvh(path)
    assert again.names == data.names
    assert again.channels == data.channels
    assert again.end_sites == data.end_sites
    np.testing.assert_allclose(again.world_positions(), pos, atol=1e-9)


def _random_default_motion(rng: np.random.Generator, order: str, t: int = 24) -> Motion:
    nj = DEFAULT_SKELETON.num_joints
    rotvecs = rng.normal(scale=0.3, size=(t, nj, 3))
    rotvecs[::5] = Rotation.random(nj * len(rotvecs[::5]), random_state=rng).as_rotvec().reshape(-1, nj, 3)
    # Gimbal lock for this order: the middle angle at +-90 deg.
    locked = np.zeros((2 * nj, 3))
    locked[:, 1] = 90.0
    locked[nj:, 1] = -90.0
    locked[:, 0] = rng.uniform(-180, 180, 2 * nj)
    locked[:, 2] = rng.uniform(-180, 180, 2 * nj)
    rotvecs[1:3] = Rotation.from_euler(order, locked, degrees=True).as_rotvec().reshape(2, nj, 3)
    root = np.cumsum(rng.normal(scale=0.02, size=(t, 3)), axis=0) + [0.0, 0.95, 0.0]
    return Motion(rotvecs, root, 30.0)


@pytest.mark.parametrize("order", ["ZXY", "XYZ", "YXZ"])
def test_default_skeleton_round_trip(tmp_path: Path, order: str) -> None:
    motion = _random_default_motion(np.random.default_rng(sum(map(ord, order))), order)
    path = tmp_path / "dance.bvh"
    write_bvh(path, motion, rotation_order=order.lower())
    data = read_bvh(path)
    index = [data.names.index(n) for n in DEFAULT_SKELETON.names]
    np.testing.assert_allclose(data.world_positions()[:, index], motion.positions(), atol=TOL)
    assert data.channels[0] == ("Xposition", "Yposition", "Zposition", *(f"{a}rotation" for a in order))
    assert {len(c) for c in data.channels[1:]} == {3}
    back = data.to_motion()
    assert back.skeleton is DEFAULT_SKELETON
    assert back.fps == 30.0
    np.testing.assert_allclose(back.positions(), motion.positions(), atol=TOL)
    np.testing.assert_allclose(back.end_effectors(), motion.end_effectors(), atol=TOL)
    # The paper's end-effectors are End Sites; leaf joints without one get a short one.
    ends = {s.name: s for s in data.end_sites}
    assert "left_foot_end" in ends
    assert "head_end" in ends
    assert "left_wrist_end" in ends
    thumb_bone = DEFAULT_SKELETON.offsets[DEFAULT_SKELETON.index("left_thumb3")]
    np.testing.assert_allclose(ends["left_thumb3_end"].offset, thumb_bone / 2, atol=1e-6)


def test_write_scale_and_custom_skeleton(tmp_path: Path) -> None:
    skeleton = Skeleton(
        np.array([[0, 0.1, 0], [0, 0.5, 0], [0.3, 0, 0], [-0.3, 0, 0]]),
        ("a", "b", "c", "d"),
        (-1, 0, 1, 1),
        (),
    )
    rng = np.random.default_rng(3)
    motion = Motion(rng.normal(scale=0.5, size=(5, 4, 3)), rng.normal(size=(5, 3)), 24.0, skeleton)
    path = tmp_path / "cm.bvh"
    write_bvh(path, motion, scale=100.0)
    data = read_bvh(path)
    np.testing.assert_allclose(data.world_positions(), motion.positions() * 100.0, atol=TOL)
    assert [(s.name, s.parent) for s in data.end_sites] == [("c_end", 2), ("d_end", 3)]
    back = data.to_motion(scale=0.01)
    assert back.skeleton.names == skeleton.names
    assert back.fps == 24.0
    np.testing.assert_allclose(back.positions(), motion.positions(), atol=TOL)
    with pytest.raises(ValueError, match="permutation of XYZ"):
        write_bvh(path, motion, rotation_order="XXY")


# ------------------------------------------------------------------------------------ malformed files


def _replace(old: str, new: str, occurrence: int = 1) -> Callable[[str], str]:
    def edit(text: str) -> str:
        parts = text.split(old)
        assert len(parts) > occurrence
        return old.join(parts[:occurrence]) + new + old.join(parts[occurrence:])

    return edit


_LAST_BRACE = CHAIN.index("}\nMOTION")
_N_LINES = len(CHAIN.splitlines())

MALFORMED: dict[str, tuple[Callable[[str], str], int, str]] = {
    "offset not a number": (
        _replace("OFFSET 0 -1 0", "OFFSET 1.0 abc"),
        _line_of(CHAIN, "OFFSET 0 -1 0"),
        "expected 'OFFSET' followed by 3 numbers, got 'OFFSET 1.0 abc'",
    ),
    "offset missing": (
        _replace("OFFSET 0 -1 0\n", "", 2),
        _line_of(CHAIN, "OFFSET 0 -1 0", 2),
        "expected 'OFFSET' followed by 3 numbers, got 'CHANNELS 3",
    ),
    "unknown channel": (
        _replace("CHANNELS 3 Zrotation Xrotation", "CHANNELS 3 Zrotation Wrotation"),
        _line_of(CHAIN, "CHANNELS 3"),
        "got 'Wrotation'",
    ),
    "channel count": (
        _replace("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 3 Zrotation Xrotation"),
        _line_of(CHAIN, "CHANNELS 3"),
        "expected 'CHANNELS' followed by a count and that many channel names",
    ),
    "hierarchy ends early": (
        lambda text: "\n".join(text.splitlines()[:11]) + "\n",
        11,
        "expected 'OFFSET' followed by 3 numbers, got end of file",
    ),
    "missing closing brace": (
        lambda text: text[:_LAST_BRACE] + text[_LAST_BRACE + 2 :],
        _line_of(CHAIN, "MOTION") - 1,
        "expected '}' to close joint 'hips' (unbalanced braces), got 'MOTION'",
    ),
    "extra closing brace": (
        lambda text: text[:_LAST_BRACE] + "}\n" + text[_LAST_BRACE:],
        _line_of(CHAIN, "MOTION"),
        "expected 'ROOT' or 'MOTION', got '}'",
    ),
    "no hierarchy": (
        lambda text: "\n" + text[len("HIERARCHY\n") :],
        2,
        "expected 'HIERARCHY', got 'ROOT hips'",
    ),
    "bad frame count": (_replace("Frames: 3", "Frames: three"), _line_of(CHAIN, "Frames:"), "'Frames:'"),
    "bad frame time": (
        _replace("Frame Time: 0.04", "Frame Time: -1"),
        _line_of(CHAIN, "Frame Time"),
        "positive",
    ),
    "truncated frames": (
        lambda text: "\n".join(text.splitlines()[:-1]) + "\n",
        _N_LINES,
        "expected frame 3 of 3 (see 'Frames:'), got end of file",
    ),
    "truncated after header": (
        lambda text: text.split("Frame Time")[0],
        _line_of(CHAIN, "Frames:"),
        "expected 'Frame Time:' after 'MOTION', got end of file",
    ),
    "short motion line": (
        _replace("0 0 0 90 0 0 0 90 0 0 0 0", "0 0 0 90 0 0 0 90 0 0 0"),
        _N_LINES - 1,
        "expected 12 values (one per channel), found 11",
    ),
    "long motion line": (
        _replace("1 2 3 0 0 0 0 0 0 0 0 0", "1 2 3 0 0 0 0 0 0 0 0 0 7"),
        _N_LINES - 2,
        "expected 12 values (one per channel), found 13",
    ),
    "motion not a number": (
        _replace("0 0 0 90 90 0", "0 0 0 90 abc 0"),
        _N_LINES,
        "expected a number, got 'abc'",
    ),
    "extra frame": (
        lambda text: text + "0 0 0 0 0 0 0 0 0 0 0 0\n",
        _N_LINES + 1,
        "expected end of file after 3",
    ),
}


@pytest.mark.parametrize("case", list(MALFORMED))
def test_malformed_file_names_the_line(tmp_path: Path, case: str) -> None:
    edit, line, message = MALFORMED[case]
    path = _write_text(tmp_path, edit(CHAIN))
    with pytest.raises(BvhParseError) as info:
        read_bvh(path)
    assert isinstance(info.value, DanceNetError)
    text = str(info.value)
    assert text.startswith(f"{path}:{line}: "), text
    assert message in text
    assert "\n" not in text


def test_missing_and_empty_files(tmp_path: Path) -> None:
    with pytest.raises(DanceNetError, match="nope.bvh: BVH file not found"):
        read_bvh(tmp_path / "nope.bvh")
    with pytest.raises(BvhParseError, match=r"empty.bvh:1: expected 'HIERARCHY', got an empty file"):
        read_bvh(_write_text(tmp_path, "", "empty.bvh"))
    with pytest.raises(BvhParseError, match=r"blank.bvh:1: .*empty file"):
        read_bvh(_write_text(tmp_path, "\n  \n", "blank.bvh"))


# ------------------------------------------------------------------------------------ the CMU files


@pytest.mark.parametrize(
    "path",
    CMU_FILES
    or [pytest.param(None, marks=pytest.mark.skip(reason=f"no BVH files in {CMU_DIR} (DANCENET_DATA)"))],
    ids=lambda p: p.name if p else "absent",
)
def test_cmu_file_round_trips(tmp_path: Path, path: Path) -> None:
    data = read_bvh(path)
    pos = data.world_positions()
    ends = data.end_site_positions()

    copy = tmp_path / "copy.bvh"
    write_bvh_data(copy, data)
    again = read_bvh(copy)
    assert (again.names, again.parents, again.channels) == (data.names, data.parents, data.channels)
    assert again.end_sites == data.end_sites
    assert again.fps == data.fps
    np.testing.assert_allclose(again.world_positions(), pos, atol=TOL, rtol=0)
    np.testing.assert_allclose(again.end_site_positions(), ends, atol=TOL, rtol=0)

    # Through our Motion and back out in our own layout: new Euler angles, same poses.
    motion = data.to_motion()
    np.testing.assert_allclose(motion.positions(), pos, atol=1e-9, rtol=0)
    order = ("ZXY", "XYZ", "YXZ")[CMU_FILES.index(path) % 3]
    ours = tmp_path / "ours.bvh"
    write_bvh(ours, motion, rotation_order=order)
    mine = read_bvh(ours)
    assert mine.names == data.names
    assert mine.channels[1] == tuple(f"{a}rotation" for a in order)
    np.testing.assert_allclose(mine.world_positions(), pos, atol=TOL, rtol=0)


def test_blender_reads_what_we_write_and_we_read_what_it_writes(tmp_path: Path) -> None:
    bpy = pytest.importorskip("bpy")
    motion = _random_default_motion(np.random.default_rng(5), "ZXY", t=6)
    path = tmp_path / "ours.bvh"
    write_bvh(path, motion)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_anim.bvh(
        filepath=str(path), axis_forward="-Z", axis_up="Y", use_fps_scale=False, frame_start=1
    )
    armature = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
    heads = np.empty((motion.num_frames, DEFAULT_SKELETON.num_joints, 3))
    for f in range(motion.num_frames):
        bpy.context.scene.frame_set(f + 1)
        for j, name in enumerate(DEFAULT_SKELETON.names):
            heads[f, j] = armature.matrix_world @ armature.pose.bones[name].head
    z_up_to_y_up = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])
    np.testing.assert_allclose(heads @ z_up_to_y_up.T, motion.positions(), atol=TOL)  # Blender is float32

    exported = tmp_path / "blender.bvh"
    bpy.ops.export_anim.bvh(filepath=str(exported), frame_start=1, frame_end=motion.num_frames)
    data = read_bvh(exported)
    # Blender writes position channels on every bone not connected to its parent: here, all of them.
    assert {len(c) for c in data.channels} == {6}
    index = [data.names.index(n) for n in DEFAULT_SKELETON.names]
    np.testing.assert_allclose(
        data.world_positions()[:, index] @ z_up_to_y_up.T, motion.positions(), atol=TOL
    )
    back = data.to_motion()
    np.testing.assert_allclose(back.positions()[:, index] @ z_up_to_y_up.T, motion.positions(), atol=TOL)


# ------------------------------------------------------------------ what a file may ask for


def _dance(frames: int = 50) -> Motion:
    """Our dancer (the 55 joints at our rest offsets), moving a little."""
    from made_up import small_motion

    return small_motion(frames)


@pytest.mark.parametrize(("unit", "scale"), [("metres", 1.0), ("centimetres", 100.0), ("millimetres", 1000.0),
                                             ("inches", 1 / 0.0254)])
def test_a_dance_in_any_unit_reads_back_in_metres(tmp_path: Path, unit: str, scale: float) -> None:
    """The unit comes from the skeleton's size, so a dance saved in centimetres (offsets and root
    path x100) continues as the same dance, not one 100 times too large."""
    from dancenet_core.shaping.rootmotion import read_dance_bvh

    motion = _dance()
    write_bvh(tmp_path / "d.bvh", motion, scale=scale)
    back = read_dance_bvh(tmp_path / "d.bvh")
    np.testing.assert_allclose(back.skeleton.offsets, DEFAULT_SKELETON.offsets, atol=1e-5)
    np.testing.assert_allclose(back.positions(), motion.positions(), atol=1e-4)


def _asking_too_much(path: Path, case: str) -> None:
    """Our dance's BVH edited as a crafted file would be."""
    write_bvh(path, _dance(), scale={"giant": 1e6, "tiny": 1e-6}.get(case, 1.0))
    lines = path.read_text().splitlines()
    first = lines.index("MOTION") + 3
    if case in ("huge-path", "huge-height"):
        words = lines[first + 5].split()
        words[0 if case == "huge-path" else 1] = "1e30"
        lines[first + 5] = " ".join(words)
    elif case in ("slow", "fast"):
        lines[first - 1] = f"Frame Time: {1000 if case == 'slow' else 1e-5}"
    path.write_text("\n".join(lines) + "\n")


CRAFTED = {"huge-path": "more than 1000 m", "huge-height": "more than 1000 m", "slow": "1 to 1000 frames per second",
           "fast": "1 to 1000 frames per second", "giant": "no unit", "tiny": "no unit"}


@pytest.mark.parametrize("case", list(CRAFTED))
def test_continue_from_a_file_asking_too_much_is_one_line_before_any_work(
        tmp_path: Path, capsys: pytest.CaptureFixture, case: str) -> None:
    """Finite but absurd values (1e30 m, Frame Time 1000, a skeleton no unit makes a dancer's)
    are refused in one line before the music is analysed, not as a traceback after the dance is made."""
    from dancenet_core.cli import main as cli_main

    kept = tmp_path / "kept.bvh"
    _asking_too_much(kept, case)
    song = Path(__file__).resolve().parents[1] / "examples" / "example_song.ogg"
    code = cli_main(["generate", str(song), "-o", str(tmp_path / "out"), "--continue", str(kept), "--at", "1"])
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert len(err.splitlines()) == 1, err
    assert CRAFTED[case] in err, err
    assert not (tmp_path / "out").exists()


def test_reading_is_linear_in_the_joints_up_to_a_stated_limit(tmp_path: Path) -> None:
    """Names are looked up, not searched (a search took 3.8 s for 8,000 joints and never ended for 100,000); more
    than MAX_JOINTS is one line."""
    import time

    from dancenet_core.bvh import MAX_JOINTS

    def wide(joints: int) -> Path:
        body = "".join(f"JOINT j{j}\n{{\nOFFSET 0 1 0\nCHANNELS 0\nEnd Site\n{{\nOFFSET 0 1 0\n}}\n}}\n"
                       for j in range(joints - 1))
        path = tmp_path / f"wide{joints}.bvh"
        path.write_text("HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 3 Xposition Yposition Zposition\n" + body
                        + "}\nMOTION\nFrames: 1\nFrame Time: 0.04\n0 0 0\n")
        return path

    at_limit = wide(MAX_JOINTS)
    start = time.process_time()  # this process' CPU time: other processes on the machine do not count
    assert read_bvh(at_limit).num_joints == MAX_JOINTS
    assert time.process_time() - start < 2.0  # 0.2 s here; the quadratic reader took 6 s
    with pytest.raises(BvhParseError, match=f"more than {MAX_JOINTS} joints: not a skeleton"):
        read_bvh(wide(MAX_JOINTS + 1))

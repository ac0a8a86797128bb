"""A rig's animation as Blender samples it (world rest and pose matrices per bone) read onto our
skeleton (`jointmap.armature_pose`, `library.build.armature_motion`), made here without Blender: our skeleton
posed into an A-pose rest (arms 45 degrees down, the spine leaning), laid out Z-up facing -Y in centimetres under
an object scale of 0.01 with bones rolled every which way, then danced; and the command line's answer to FBX."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dancenet_core.bvh import write_bvh
from dancenet_core.cli import main
from dancenet_core.jointmap import armature_pose, min_rotation, tail_offsets
from dancenet_core.kinematics import fk_numpy
from dancenet_core.library.build import ArmatureClip, armature_motion, build_armature_library
from dancenet_core.motion import Motion
from dancenet_core.skeleton import BODY_JOINTS, DEFAULT_SKELETON, JOINT_INDEX

FPS = 30.0
Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # our Y-up frame -> Blender's world
A_POSE = {"left_shoulder": ("z", -45.0), "right_shoulder": ("z", 45.0), "spine1": ("x", 6.0)}
# A rest pose as an FBX file's first frame may be: the chest twisted (where the neck and collars branch off).
TWISTED = A_POSE | {"spine3": ("y", 30.0)}


def dance(seconds: float = 4.0, seed: int = 0) -> Motion:
    """Every body joint turning smoothly about all three axes, the pelvis travelling and bobbing."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(seconds * FPS))[:, None, None] / FPS
    amp, freq, phase = rng.uniform(0.1, 0.5, (3, 1, BODY_JOINTS, 3))
    rot = np.zeros((t.shape[0], DEFAULT_SKELETON.num_joints, 3))
    rot[:, :BODY_JOINTS] = amp * np.sin(2 * np.pi * (0.3 + freq) * t + 6 * phase)
    tt = t[:, 0, 0]
    root = np.stack([0.3 * np.sin(tt), 0.9 + 0.03 * np.cos(4 * tt), 0.2 * tt], axis=1)
    return Motion(rot, root, FPS)


def sampled(motion: Motion, a_pose: bool, rest_pose: dict[str, tuple[str, float]] = A_POSE) -> ArmatureClip:
    """`motion` danced by a rig of our bone lengths resting in `rest_pose` (or our T-pose), as Blender would sample it:
    bone matrices whose Y axis runs along the bone (rolled at random about it), in a Z-up world, in centimetres
    under the object's scale."""
    body = list(range(BODY_JOINTS))
    cm = 100.0
    rest_local = np.zeros((1, DEFAULT_SKELETON.num_joints, 3))
    if a_pose:
        for joint, (axis, degrees) in rest_pose.items():
            rest_local[0, JOINT_INDEX[joint]] = Rotation.from_euler(axis, degrees, degrees=True).as_rotvec()
    rest_pos, rest_rot = fk_numpy(DEFAULT_SKELETON, rest_local, np.zeros((1, 3)))
    pos, rot = fk_numpy(DEFAULT_SKELETON, motion.rotations, motion.root_positions)
    tails = tail_offsets(DEFAULT_SKELETON)
    rng = np.random.default_rng(7)
    rolls = [min_rotation(np.array([0.0, 1.0, 0.0]), tails[j]) @ Rotation.from_euler("y", rng.uniform(0, 360),
             degrees=True).as_matrix() for j in body]  # fmt: skip
    obj = np.eye(4)
    obj[:3, :3] = Z_UP / cm  # the object's turn and scale

    def world(p: np.ndarray, r: np.ndarray) -> np.ndarray:
        m = np.zeros((*p.shape[:-1], 4, 4))
        m[..., :3, :3], m[..., :3, 3], m[..., 3, 3] = r, p * cm, 1.0  # the armature's data, in cm
        return obj @ m

    rest_bone = np.stack([rest_rot[0, j] @ rolls[j] for j in body])
    rest = world(rest_pos[0, body], rest_bone)
    # Each bone turns in the world as our joint does from where the rest pose holds it.
    turn = rot[:, body] @ np.swapaxes(rest_rot[0, body], -1, -2)
    pose = world(pos[:, body], turn @ rest_bone)
    return ArmatureClip("dance", "", body, rest, pose, FPS)


@pytest.mark.parametrize(("a_pose", "rest_pose"), [(False, {}), (True, A_POSE), (True, TWISTED)])
def test_a_rigs_clip_comes_back_as_danced_whatever_its_rest(a_pose: bool, rest_pose: dict) -> None:
    motion = dance()
    clip = armature_motion(sampled(motion, a_pose, rest_pose))
    assert clip.fps == 25.0 and clip.num_frames == round(motion.duration * 25)
    want = motion.resampled(25.0).positions()
    got = clip.positions()
    # Where the joints are about the pelvis, and the pelvis' path over the floor: exact but for the resampling
    # (the same slerp on both sides) and float32-free arithmetic, so within 1e-6 m.
    rel = np.abs((got - got[:, :1]) - (want - want[:, :1]))[:, :BODY_JOINTS]
    assert rel.max() < 1e-6, rel.max()
    assert np.abs(got[:, 0, [0, 2]] - want[:, 0, [0, 2]]).max() < 1e-6
    assert np.allclose(clip.skeleton.offsets, DEFAULT_SKELETON.offsets, atol=1e-9)  # our bone lengths, read back


def test_without_the_rest_correction_an_a_pose_rig_would_not_read() -> None:
    """The A-pose's turns are the ones taken out: 45 degrees at the shoulders, 6 at the leaning spine; taken as
    a T-pose, the wrists would land far from where the rig puts them."""
    clip = sampled(dance(), a_pose=True)
    source = armature_pose(clip.joints, clip.rest, clip.pose, clip.fps, clip.name)
    angles = np.degrees(Rotation.from_matrix(source.rest_turns).magnitude())
    col = {j: k for k, j in enumerate(source.joints)}
    assert angles[col[JOINT_INDEX["left_shoulder"]]] == pytest.approx(45.0, abs=0.01)
    assert angles[col[JOINT_INDEX["spine1"]]] == pytest.approx(6.0, abs=0.01)
    assert angles[col[JOINT_INDEX["left_knee"]]] < 0.01
    naive = source.rotations @ np.swapaxes(source.rest_turns, -1, -2)  # the bones' turns from rest, as if T-pose
    w = col[JOINT_INDEX["left_wrist"]]
    e = col[JOINT_INDEX["left_elbow"]]
    arm = DEFAULT_SKELETON.offsets[JOINT_INDEX["left_wrist"]]
    off_naive = np.einsum("tij,j->ti", naive[:, e], arm)
    off_right = source.positions[:, w] - source.positions[:, e]
    assert np.linalg.norm(off_naive - off_right, axis=1).min() > 0.1


def test_a_rig_too_short_a_clip_or_not_a_humanoid_is_one_line(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    good = sampled(dance(), a_pose=True)
    blip = sampled(dance(0.5), a_pose=False)
    blip.name = "blip"
    tiny = sampled(dance(), a_pose=False)
    tiny.name = "tiny"
    tiny.rest[..., :3, 3] /= 100  # a centimetre rig's 0.01 scale applied twice: 1.5 cm from ankle to head
    tiny.pose[..., :3, 3] /= 100
    dust = sampled(dance(), a_pose=False)
    dust.name = "dust"
    dust.rest[..., :3, 3] /= 1e5  # no unit makes this a dancer
    dust.pose[..., :3, 3] /= 1e5
    headless = ArmatureClip("snake", "", [0, 1, 2], good.rest[:3], good.pose[:, :3], FPS)
    library, path = build_armature_library([good, blip, tiny, dust, headless], "test", notes=["Cube: no armature"],
                                           report=lambda _line: None)
    assert library.num_clips == 2 and path.is_file()
    tall = [np.ptp(library.clip(k).skeleton.rest_positions()[:, 1]) for k in range(2)]
    assert tall == pytest.approx([1.59, 1.59], abs=0.01)  # the tiny rig read at its true size
    notes = list(library.notes)
    assert notes[0] == "left out Cube: no armature"
    assert notes[1] == "left out blip: 0.48 s, too short to hold a bar"
    assert notes[2] == ("left out dust: the rig's rest pose is 1.53e-05 units tall, which no unit (metres, "
                        "centimetres, millimetres, inches) makes a dancer's 0.5-2.5 m")
    assert notes[3] == "left out snake: a rig's clip needs bones for the pelvis, hips and neck; missing: neck"
    again, same = build_armature_library([], "test")
    assert same == path and again.names == library.names  # cached: read, not built
    with pytest.raises(Exception, match="^none of the 1 actions could be read: blip: 0.48 s"):
        build_armature_library([blip], "blip")
    with pytest.raises(Exception, match="^no action animates a humanoid armature in this file: Cube: no armature$"):
        build_armature_library([], "none", notes=["Cube: no armature"])


def test_the_command_line_says_fbx_needs_blender(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture) -> None:
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "mixamo"
    folder.mkdir()
    write_bvh(folder / "a.bvh", dance(4.0))
    (folder / "Samba Dancing.fbx").write_bytes(b"Kaydara FBX Binary  \x00")
    assert main(["library", "build", str(folder)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert "holds 1 FBX file (Samba Dancing.fbx...), which only Blender reads: build this folder with Build " \
           "Library in the DanceNet add-on's panel" in err


def test_the_smallest_rotation_turns_any_direction_onto_any_other() -> None:
    """One function for one direction or many, keying and the library alike: a proper rotation taking a onto b
    and leaving their common perpendicular where it is; for opposite directions (no smallest one), half a turn,
    still a rotation."""
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    b[:5] = -a[:5] * rng.uniform(0.5, 2.0, (5, 1))  # opposite
    b[5:8] = a[5:8] * 3.0  # the same direction
    r = min_rotation(a, b)
    unit = (a / np.linalg.norm(a, axis=1, keepdims=True), b / np.linalg.norm(b, axis=1, keepdims=True))
    np.testing.assert_allclose(np.einsum("tij,tj->ti", r, unit[0]), unit[1], atol=1e-9)
    np.testing.assert_allclose(r @ np.swapaxes(r, 1, 2), np.broadcast_to(np.eye(3), r.shape), atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-9)
    normal = np.cross(a[8:], b[8:])
    np.testing.assert_allclose(np.einsum("tij,tj->ti", r[8:], normal), normal, atol=1e-9)
    np.testing.assert_allclose(r[5:8], np.broadcast_to(np.eye(3), (3, 3, 3)), atol=1e-12)
    for k in (0, 9):  # one direction at a time gives the same rotation
        np.testing.assert_allclose(min_rotation(a[k], b[k]), r[k], atol=1e-12)

"""Library clips of any humanoid skeleton: a made-up dance written as BVH in each convention the library reads
(`tests/conventions.py`: Mixamo with and without its prefix and with any fingers, VRM, Unreal, Character Creator,
Rokoko, Xsens, OptiTrack, DeepMotion, DAZ, MMD's Japanese names, Rigify and its metarig, MPFB, generic names, CMU, ours;
centimetres, millimetres, inches; Z up; A-poses; 24-120 fps; a prepended T-pose frame) is read back as the dance it
is; a skeleton that is no humanoid is one line that says what it lacks; a folder's manifest names a bone map for
bones Auto cannot find."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conventions import CONVENTIONS, Convention, as_convention, convention_bvh
from scipy.spatial.transform import Rotation

from dancenet_core.bvh import BvhData, write_bvh, write_bvh_data
from dancenet_core.errors import DanceNetError
from dancenet_core.library.build import build_library, read_clip
from dancenet_core.library.bvhclip import bvh_rig
from dancenet_core.motion import Motion
from dancenet_core.skeleton import BODY_JOINTS, DEFAULT_SKELETON, JOINT_INDEX, JOINT_NAMES, Skeleton

FPS = 30.0


def dance(seconds: float = 3.0, scale: float = 1.0, seed: int = 0) -> Motion:
    """Every joint, the fingers too, turning smoothly about all three axes; the pelvis travelling and bobbing; on a
    dancer `scale` times ours."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(seconds * FPS))[:, None, None] / FPS
    amp, freq, phase = rng.uniform(0.1, 0.5, (3, 1, DEFAULT_SKELETON.num_joints, 3))
    rot = amp * np.sin(2 * np.pi * (0.3 + freq) * t + 6 * phase)
    tt = t[:, 0, 0]
    root = np.stack([0.3 * np.sin(tt), 0.9 + 0.03 * np.cos(4 * tt), 0.2 * tt], axis=1) * scale
    return as_convention(Motion(rot, root, FPS, DEFAULT_SKELETON.scaled(scale)))


def body_error(got: Motion, want: Motion, joints: int = BODY_JOINTS) -> float:
    """The largest distance (m) between two clips' joints about their pelvis and between their pelvis paths."""
    a, b = got.positions()[:, :joints], want.positions()[:, :joints]
    assert a.shape == b.shape
    rel = np.linalg.norm((a - a[:, :1]) - (b - b[:, :1]), axis=-1).max()
    return float(max(rel, np.linalg.norm(a[:, 0] - b[:, 0], axis=-1).max()))


def reference(tmp_path: Path, motion: Motion) -> Motion:
    write_bvh(tmp_path / "ours.bvh", motion)
    return read_clip(tmp_path / "ours.bvh")


# A few dancers' sizes, so the reading is checked on proportions and not on ours alone.
SCALES = {"mixamo": 1.08, "vrm": 0.9, "daz": 1.1, "mmd": 0.95, "cmu": 1.05}
# The bone map Auto reads each convention by.
FOUND = {"mixamo": "Mixamo", "mixamo_bare": "Mixamo", "mixamo1_handless": "Mixamo", "vrm": "VRM", "vrm_humanoid": "VRM",
         "unreal": "Unreal Manny/Quinn", "character_creator": "Character Creator", "rokoko": "Rokoko",
         "daz": "DAZ Genesis", "mmd": "MMD", "rigify": "Rigify", "metarig": "Rigify metarig",
         "mpfb": "MakeHuman/MPFB", "generic": "Generic names", "generic_sided": "Generic names", "cmu": "CMU",
         "ours_z_up_mm": "SMPL-X", "xsens": "Xsens MVN", "motive": "OptiTrack Motive",
         "deepmotion": "Mixamo"}  # fmt: skip


@pytest.mark.parametrize("name", list(CONVENTIONS))
def test_a_clip_in_each_convention_reads_as_the_dance_it_is(tmp_path: Path, name: str) -> None:
    conv = CONVENTIONS[name]
    motion = dance(scale=SCALES.get(name, 1.0))
    write_bvh_data(tmp_path / f"{name}.bvh", convention_bvh(motion, conv))
    got = read_clip(tmp_path / f"{name}.bvh")
    assert bvh_rig(tmp_path / f"{name}.bvh").convention == FOUND[name]
    want = reference(tmp_path, motion)
    assert got.num_frames == want.num_frames  # a prepended T-pose frame is not danced
    assert body_error(got, want) < 0.01, name
    assert np.allclose(got.skeleton.offsets[:BODY_JOINTS], want.skeleton.offsets[:BODY_JOINTS], atol=1e-3)


def test_mmd_names_in_shift_jis_read(tmp_path: Path) -> None:
    """Japanese tools write MMD's bone names in Shift-JIS, not UTF-8."""
    motion = dance()
    write_bvh_data(tmp_path / "utf8.bvh", convention_bvh(motion, CONVENTIONS["mmd"]))
    text = (tmp_path / "utf8.bvh").read_text(encoding="utf-8")
    (tmp_path / "sjis.bvh").write_bytes(text.encode("cp932"))
    assert bvh_rig(tmp_path / "sjis.bvh").convention == "MMD"
    assert body_error(read_clip(tmp_path / "sjis.bvh"), reference(tmp_path, motion)) < 0.01


@pytest.mark.parametrize("variant", [{"unit": 0.001}, {"unit": 0.0254}, {"unit": 1.0, "z_up": True},
                                     {"fps": 120.0}, {"a_pose_deg": 45.0, "t_pose": True}])
def test_units_up_axes_rates_and_rests_read_alike(tmp_path: Path, variant: dict) -> None:
    conv = Convention(CONVENTIONS["mixamo"].bones, ends=CONVENTIONS["mixamo"].ends, **variant)
    motion = dance()
    write_bvh_data(tmp_path / "clip.bvh", convention_bvh(motion, conv))
    assert body_error(read_clip(tmp_path / "clip.bvh"), reference(tmp_path, motion)) < 0.01


def test_a_rest_frame_at_the_start_stays_when_the_dance_moves_off_it_smoothly(tmp_path: Path) -> None:
    motion = dance()
    rot = motion.rotations.copy()
    ease = np.clip(np.arange(motion.num_frames) / 20 - 0.5, 0, 1)[:, None, None]  # held, then eased into the dance
    still = Motion(rot * ease, motion.root_positions, FPS, motion.skeleton)
    write_bvh(tmp_path / "eased.bvh", still)
    assert read_clip(tmp_path / "eased.bvh").num_frames == round(motion.duration * 25)


def _rows(names: list[str], parents: list[int], heads: np.ndarray, frames: int = 40) -> BvhData:
    offsets = np.array([heads[j] - (heads[p] if p >= 0 else 0) for j, p in enumerate(parents)])
    rot = ("Zrotation", "Xrotation", "Yrotation")
    channels = (("Xposition", "Yposition", "Zposition", *rot), *([rot] * (len(names) - 1)))
    values = np.zeros((frames, 3 + 3 * len(names)))
    values[:, :3] = heads[0]
    values[:, 4] = np.linspace(0, 30, frames)
    return BvhData(tuple(names), tuple(parents), offsets, channels, (), 1 / FPS, values)


def _ours(prefix: str, keep: set[str] | None = None) -> tuple[list[str], list[int], np.ndarray]:
    """Our skeleton's body joints named `prefix` + Mixamo's names, only `keep` (and their chains) if given."""
    from conventions import shipped

    names = shipped("MIXAMO", body_only=True, strip="mixamorig:")
    joints = [j for j in range(BODY_JOINTS) if keep is None or JOINT_NAMES[j] in keep]
    heads = DEFAULT_SKELETON.rest_positions()[joints] + [0.0, DEFAULT_SKELETON.rest_pelvis_height(), 0.0]
    parents = [joints.index(DEFAULT_SKELETON.parents[j]) if DEFAULT_SKELETON.parents[j] in joints else -1
               for j in joints]  # fmt: skip
    return [prefix + names[JOINT_NAMES[j]] for j in joints], parents, heads


def test_a_skeleton_that_is_no_humanoid_is_one_line_naming_what_it_lacks(tmp_path: Path) -> None:
    upper = {"pelvis", "spine1", "spine2", "spine3", "neck", "head", "left_collar", "right_collar", "left_shoulder",
             "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist"}  # fmt: skip
    write_bvh_data(tmp_path / "bust.bvh", _rows(*_ours("", upper)))
    with pytest.raises(DanceNetError) as e:
        read_clip(tmp_path / "bust.bvh")
    assert str(e.value).startswith("bust.bvh: not a humanoid skeleton (14 bones: Hips, Spine, Spine1, Spine2, ...): "
                                   "no legs; name its bones in a bone map (docs/library.md)"), e.value
    a, b = _ours("A:"), _ours("B:")
    names = ["Stage", *a[0], *b[0]]
    parents = [-1, *(p + 1 if p >= 0 else 0 for p in a[1]), *(p + 23 if p >= 0 else 0 for p in b[1])]
    heads = np.concatenate([[[0.0, 0.0, 0.0]], a[2] + [-1.0, 0, 0], b[2] + [1.0, 0, 0]])
    write_bvh_data(tmp_path / "duet.bvh", _rows(names, parents, heads))
    with pytest.raises(DanceNetError, match=r"^duet\.bvh: not a humanoid skeleton \(45 bones: Stage, A:Hips, "
                       r"A:LeftUpLeg, A:LeftLeg, \.\.\.\): two hips \(A:Hips, B:Hips\); name its bones"):
        read_clip(tmp_path / "duet.bvh")


def test_a_manifest_names_a_bone_map_for_bones_auto_cannot_find(tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """Fingers named as no shipped map names them: Auto reads the body and leaves the fingers at rest; the
    folder's map (for one clip, or on a '*' row for all) reads them too. A map that cannot be read is one line."""
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    motion = dance()
    fingers = {j: f"Digit_{j}" for j in JOINT_NAMES if any(f in j for f in ("index", "middle", "thumb"))}
    conv = Convention(CONVENTIONS["mixamo"].bones | fingers, unit=0.01)
    folder = tmp_path / "clips"
    folder.mkdir()
    write_bvh_data(folder / "a.bvh", convention_bvh(motion, conv))
    write_bvh_data(folder / "b.bvh", convention_bvh(motion, conv))
    (folder / "digits.json").write_text(json.dumps({"name": "Digits", "bones": conv.bones}), encoding="utf-8")
    want = reference(tmp_path, motion)
    hands = [JOINT_INDEX[j] for j in fingers]

    def finger_error(clip: Motion) -> float:
        a, b = clip.positions()[:, hands], want.positions()[:, hands]
        return float(np.linalg.norm(a - b, axis=-1).max())

    assert finger_error(read_clip(folder / "a.bvh")) > 0.02  # Auto: the fingers stay at rest
    for manifest in ("file,bonemap\na.bvh,digits.json\nb.bvh,digits.json\n", "file,bonemap,style\n*,digits.json,\n"):
        (folder / "manifest.csv").write_text(manifest, encoding="utf-8")
        library, _ = build_library(folder, force=True, report=lambda _line: None)
        assert library.num_clips == 2
        for k in range(2):
            assert finger_error(library.clip(k)) < 0.01
    (folder / "manifest.csv").write_text("file,bonemap\na.bvh,missing.json\n", encoding="utf-8")
    with pytest.raises(DanceNetError, match=r"manifest\.csv, line 2: Cannot read bone map .*missing\.json"):
        build_library(folder, force=True)


def _collars_apart() -> Skeleton:
    """Our skeleton with the collars and shoulders set as the Dance with Melody dancers' are (5 mm further out and
    lower than ours, pointing 2 degrees apart): bones whose directions are not our T-pose's."""
    offsets = DEFAULT_SKELETON.offsets.copy()
    for side, sign in (("left", 1.0), ("right", -1.0)):
        offsets[JOINT_INDEX[f"{side}_collar"]] = (0.0551 * sign, 0.0828, -0.0069)
        offsets[JOINT_INDEX[f"{side}_shoulder"]] = (0.0866 * sign, 0.0207, -0.0069)
    return Skeleton(offsets, JOINT_NAMES, DEFAULT_SKELETON.parents, DEFAULT_SKELETON.end_sites)


@pytest.mark.parametrize("skeleton", [DEFAULT_SKELETON, _collars_apart()], ids=["ours", "collars_apart"])
def test_our_own_clips_read_exactly(tmp_path: Path, skeleton: Skeleton) -> None:
    """Our BVH (`dancenet generate`'s, the Dance with Melody dances) is read as written, on its own bones: every
    joint where it was written, turned as written, whatever its bones' directions (read as a rig's, onto our
    T-pose, the collars of the Dance with Melody dancers turned 2 degrees and moved 5 mm)."""
    motion = dance()
    motion = Motion(motion.rotations, motion.root_positions, motion.fps, skeleton)
    write_bvh(tmp_path / "ours.bvh", motion)
    got = read_clip(tmp_path / "ours.bvh")
    want = motion.resampled(25.0)
    np.testing.assert_allclose(got.skeleton.offsets[1:], skeleton.offsets[1:], atol=1e-6)
    pos, ref = got.positions(), want.positions()
    assert np.abs((pos - pos[:, :1]) - (ref - ref[:, :1])).max() < 1e-5
    turn = Rotation.from_rotvec(got.rotations[:, 1:].reshape(-1, 3)).inv() * Rotation.from_rotvec(
        want.rotations[:, 1:].reshape(-1, 3))
    assert np.degrees(turn.magnitude()).max() < 1e-3
    assert bvh_rig(tmp_path / "ours.bvh").convention == "SMPL-X"


def test_the_build_table_names_each_clips_convention_and_the_library_keeps_it(tmp_path: Path) -> None:
    from dancenet_core.commands.library import clip_table
    from dancenet_core.library.store import MotionLibrary

    folder = tmp_path / "clips"
    folder.mkdir()
    names = ("mixamo", "mmd", "unreal")
    for i, name in enumerate(names):
        write_bvh_data(folder / f"{i}_{name}.bvh", convention_bvh(dance(seconds=4.0, seed=i), CONVENTIONS[name]))
    library, path = build_library(folder, report=lambda _line: None)
    assert library.skeletons == [FOUND[n] for n in names]
    rows = clip_table(library).splitlines()[1:]
    assert [FOUND[n][:16] in row for row, n in zip(rows, names, strict=True)] == [True] * 3
    assert MotionLibrary.load(path).skeletons == library.skeletons

"""Retargeting BVH clips onto our skeleton by a joint-name map (the CMU dance clips)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dancenet_core.bvh import read_bvh, write_bvh
from dancenet_core.data.build import fitted_clip
from dancenet_core.data.cmu_dance import Clip, read_cmu_manifest
from dancenet_core.data.retarget import retarget
from dancenet_core.errors import DanceNetError
from dancenet_core.jointmap import CMU, RetargetError
from dancenet_core.kinematics import fk_numpy
from dancenet_core.motion import Motion
from dancenet_core.skeleton import DEFAULT_SKELETON, JOINT_INDEX, JOINT_NAMES, MIRROR_INDEX, PARENTS, Skeleton

BODY = 22
Z_UP = Rotation.from_euler("x", 90, degrees=True)  # our Y-up world -> a Z-up world, as AMASS writes CMU


def _cmu_like_clip(path: Path, frames: int = 90) -> Motion:
    """Write a 30-fps BVH with CMU's joint names, Z-up world and its own proportions; return the Y-up truth."""
    off = DEFAULT_SKELETON.offsets[:BODY].copy()
    for name in ("knee", "ankle"):  # longer legs, shorter arms, narrower hips than our rest skeleton
        off[[JOINT_INDEX[f"left_{name}"], JOINT_INDEX[f"right_{name}"]]] *= 1.1
    for name in ("elbow", "wrist"):
        off[[JOINT_INDEX[f"left_{name}"], JOINT_INDEX[f"right_{name}"]]] *= 0.9
    off[[JOINT_INDEX["left_hip"], JOINT_INDEX["right_hip"]], 0] *= 0.7
    rng = np.random.default_rng(0)
    t = np.arange(frames)[:, None, None] / 30.0
    rot = 0.4 * np.sin(2 * np.pi * rng.uniform(0.3, 1.2, (1, BODY, 3)) * t + rng.uniform(0, 6, (1, BODY, 3)))
    rot[:, 0] = (Rotation.from_euler("y", 1.5 * t[:, 0, 0]) * Rotation.from_rotvec(0.2 * rot[:, 0])).as_rotvec()
    root = np.stack([0.3 * np.sin(t[:, 0, 0]), 0.95 + 0.03 * np.sin(5 * t[:, 0, 0]), 0.2 * t[:, 0, 0]], -1)
    names = tuple(CMU.joints[n] for n in JOINT_NAMES[:BODY])
    truth = Motion(rot, root, 30.0, Skeleton(off, names, PARENTS[:BODY], ()))
    rot_z = rot.copy()
    rot_z[:, 0] = (Z_UP * Rotation.from_rotvec(rot[:, 0])).as_rotvec()
    write_bvh(path, Motion(rot_z, Z_UP.apply(root), 30.0, truth.skeleton), rotation_order="ZYX")
    return truth


def test_retarget_follows_a_known_clip(tmp_path: Path) -> None:
    truth = _cmu_like_clip(tmp_path / "clip.bvh")
    fit = retarget(read_bvh(tmp_path / "clip.bvh"), CMU, 25.0, steps=150)
    err = fit.errors()
    assert fit.motion.num_frames == 75
    assert fit.motion.fps == 25.0  # 3 s resampled to the model's rate
    assert err.mean() < 0.01, f"{err.mean() * 100:.2f} cm"
    assert np.percentile(err, 95) < 0.02, f"{err.mean() * 100:.2f} cm"
    # Up is +Y and the dancer faces where the source faces: the pelvis turns like the source's.
    src = truth.resampled(25.0)
    angle = (Rotation.from_rotvec(fit.motion.rotations[:, 0]) * Rotation.from_rotvec(src.rotations[:, 0]).inv())
    assert np.degrees(angle.magnitude()).max() < 10.0
    np.testing.assert_allclose(fit.motion.root_positions[:, 1], src.root_positions[:, 1], atol=0.03)
    # The performer's proportions, left/right symmetric (the mirror augmentation needs that).
    sk = fit.motion.skeleton
    shin = np.linalg.norm(truth.skeleton.offsets[JOINT_INDEX["left_ankle"]])
    assert np.linalg.norm(sk.offsets[JOINT_INDEX["left_ankle"]]) == pytest.approx(shin, rel=1e-6)
    np.testing.assert_allclose(sk.offsets[list(MIRROR_INDEX)] * [-1, 1, 1], sk.offsets, atol=1e-12)
    # End joints turn with the source's (the head is not left at an arbitrary twist).
    _, world = fk_numpy(sk, fit.motion.rotations, fit.motion.root_positions)
    _, world_src = fk_numpy(src.skeleton, src.rotations, src.root_positions)
    head = JOINT_INDEX["head"]
    diff = Rotation.from_matrix(world[:, head]) * Rotation.from_matrix(world_src[:, head]).inv()
    assert np.degrees(np.median(diff.magnitude())) < 10.0


def test_joint_names_off_the_map_are_named(tmp_path: Path) -> None:
    _cmu_like_clip(tmp_path / "clip.bvh", frames=5)
    text = (tmp_path / "clip.bvh").read_text().replace("JOINT lknee", "JOINT LeftLeg")
    (tmp_path / "renamed.bvh").write_text(text)
    with pytest.raises(RetargetError, match=r"missing: lknee \("):
        retarget(read_bvh(tmp_path / "renamed.bvh"), CMU, 25.0, steps=1, path="renamed.bvh")


def test_malformed_cmu_clip_is_one_clear_line(tmp_path: Path) -> None:
    _cmu_like_clip(tmp_path / "clip.bvh", frames=5)
    lines = (tmp_path / "clip.bvh").read_text().splitlines()
    (tmp_path / "bad.bvh").write_text("\n".join(lines[:-1]))  # a frame short
    with pytest.raises(DanceNetError, match=r"bad\.bvh:\d+: ") as e:
        fitted_clip(Clip("bad", "00", "test", tmp_path / "bad.bvh"), tmp_path)
    assert "\n" not in str(e.value)


@pytest.fixture(scope="module")
def cmu_clips(shared_data: Path) -> dict[str, Clip]:
    clips = {c.clip: c for c in read_cmu_manifest(shared_data)}
    if not clips:
        pytest.skip(f"no CMU clips under {shared_data}")
    return clips


@pytest.mark.parametrize("clip", ["05_03", "93_05"])
def test_fit_error_bounds_on_real_cmu_clips(cmu_clips: dict[str, Clip], clip: str) -> None:
    """Measured over all 61 clips: mean 0.81 cm, p95 1.77 cm (worst clip 94_07: p95 2.27 cm); with a margin."""
    fit = retarget(read_bvh(cmu_clips[clip].bvh), CMU, 25.0)
    err = fit.errors()
    assert err.mean() < 0.015, f"mean fit error {err.mean() * 100:.2f} cm"
    assert np.percentile(err, 95) < 0.03, f"p95 fit error {np.percentile(err, 95) * 100:.2f} cm"
    pos = fit.motion.positions()
    assert np.median(pos[:, JOINT_INDEX["head"], 1] - pos[:, 0, 1]) > 0.4  # upright in our Y-up world

"""Root motion the way game engines and animators want it: travelling (as danced), in place, or carried by a
separate root bone on the floor under the hips.

In place removes the hips' horizontal path and keeps everything else, the heading included, so a dance
that turns still turns. The root bone takes the horizontal path and the heading (a turn about the vertical
only): the hips then move only up and down above it and tilt relative to it, which is what Unreal's and
Unity's root-motion extraction reads.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..bvh import BvhData, _write, read_bvh
from ..constants import ROOT_MODES
from ..errors import DanceNetError
from ..motion import Motion
from ..representation import yaw_and_swing
from ..skeleton import DEFAULT_SKELETON, JOINT_NAMES, PARENTS, EndSite, Skeleton
from ..units import FILE_UNIT_NAMES, FILE_UNITS, dancer_unit

ROOT_BONE = "root"
SIZE_RANGE = (0.5, 2.0)  # a dancer from half to twice ours, in the unit found
MAX_TRAVEL_M = 1000.0  # no dance goes further from where it started: beyond this a file holds garbage, not a path


def in_place(motion: Motion) -> Motion:
    """The dance on the spot: the hips' horizontal path removed (height and every rotation kept)."""
    root = motion.root_positions.copy()
    root[:, [0, 2]] = 0.0
    return Motion(motion.rotations, root, motion.fps, motion.skeleton)


def split_root(motion: Motion) -> tuple[Motion, np.ndarray, np.ndarray]:
    """(the dance seen from the root bone, the root's floor point [T, 3] (y = 0), its heading [T] radians).

    Turning the first by the heading about +Y and moving it to the floor point gives the dance back.
    """
    yaw, swing = yaw_and_swing(motion.rotations[:, 0])
    floor = motion.root_positions * np.array([1.0, 0.0, 1.0])
    rotations = motion.rotations.copy()
    rotations[:, 0] = swing
    local_root = np.zeros_like(motion.root_positions)
    local_root[:, 1] = motion.root_positions[:, 1]
    return Motion(rotations, local_root, motion.fps, motion.skeleton), floor, yaw


def apply_mode(motion: Motion, mode: str) -> Motion:
    """The motion a mode keeps in a plain (one-root) Motion: in place for "in-place", as danced otherwise
    (a root bone is a layout of the same dance, written by `write_root_bone_bvh` or the add-on)."""
    if mode not in ROOT_MODES:
        raise DanceNetError(f"unknown root motion '{mode}'; choose one of: {', '.join(ROOT_MODES)}")
    return in_place(motion) if mode == "in-place" else motion


def write_root_bone_bvh(path: str | Path, motion: Motion, rotation_order: str = "ZXY") -> None:
    """BVH with a `root` joint on the floor (horizontal path and heading) above the 55 joints; the pelvis
    carries its height as position channels (the only child joint that moves, as engines expect)."""
    if motion.skeleton.names != JOINT_NAMES:
        raise DanceNetError("a root bone is added to the 55-joint DanceNet skeleton only")
    local, floor, yaw = split_root(motion)
    sk = motion.skeleton
    order = rotation_order.upper()
    t = motion.num_frames
    euler = Rotation.from_rotvec(local.rotations.reshape(-1, 3)).as_euler(order, degrees=True).reshape(t, -1, 3)
    # angles as (N, 1): newer scipy reads a 1-D array for one axis as a single rotation
    root_euler = Rotation.from_euler("y", yaw[:, None]).as_euler(order, degrees=True)
    rot = tuple(f"{a}rotation" for a in order)
    pos = ("Xposition", "Yposition", "Zposition")
    names = (ROOT_BONE, *sk.names)
    parents = (-1, *(p + 1 for p in sk.parents))
    # The hips' OFFSET puts them over the root in the rest pose (importers build the rest pose from OFFSETs).
    offsets = np.concatenate([np.zeros((1, 3)), sk.offsets])
    offsets[1, 1] += sk.rest_pelvis_height()
    channels = [pos + rot, pos + rot] + [rot] * (sk.num_joints - 1)
    columns = [np.concatenate([floor, root_euler], 1), np.concatenate([local.root_positions, euler[:, 0]], 1)]
    columns += [euler[:, j] for j in range(1, sk.num_joints)]
    ends = [EndSite(e.name, e.parent + 1, e.offset) for e in sk.end_sites]
    has_child = {p for p in parents if p >= 0} | {e.parent for e in ends}
    for j in range(len(names)):
        if j not in has_child:
            tip = offsets[j] * 0.5
            ends.append(EndSite(f"{names[j]}_end", j, (float(tip[0]), float(tip[1]), float(tip[2]))))
    _write(path, names, parents, offsets, channels, ends, columns, 1.0 / motion.fps)


def read_dance_bvh(path: str | Path) -> Motion:
    """A DanceNet dance from a BVH, travelling, in place or with a root bone (folded back into the hips),
    in our joint order; a one-line error for any other skeleton."""
    data = read_bvh(path)
    joints = dance_joints(data)
    if joints is None:
        raise DanceNetError(f"{Path(path).name} is not a DanceNet dance (its joints are not the 55 of "
                            "`dancenet generate`'s BVH)")
    motion = dance_motion(data, joints, Path(path).name)
    root = motion.root_positions
    if not np.abs(root - root[0]).max() <= MAX_TRAVEL_M:
        raise DanceNetError(f"{Path(path).name}: its hips go more than {MAX_TRAVEL_M:g} m from where they start; "
                            "that is not a dance (export it again)")
    return motion


def dance_joints(data: BvhData) -> list[int] | None:
    """The file's joint for each of our 55, in our order, when its skeleton is `dancenet generate`'s (our names and
    parents, with or without a root bone); None for any other skeleton."""
    body = data.names[1:] if data.names[:2] == (ROOT_BONE, "pelvis") else data.names
    index = {n: i for i, n in enumerate(data.names)}
    joints = [index.get(n, -1) for n in JOINT_NAMES]
    if sorted(body) != sorted(JOINT_NAMES) or any(data.parents[joints[j]] != joints[p] for j, p in
                                                  enumerate(PARENTS) if p >= 0):
        return None
    return joints


def dance_motion(data: BvhData, joints: list[int], name: str) -> Motion:
    """The motion of a BVH of our skeleton (`joints` from `dance_joints`) as written: its rotations, on its own
    bones, in the unit that makes it our dancer's size; a root bone folded back into the hips."""
    metres = _metres_per_unit(name, data.offsets[joints[1:]])
    world_p, world_r = data._fk()
    root = world_p[:, joints[0]] * metres
    rotations = data.local_rotations()[:, joints]
    rotations[:, 0] = Rotation.from_matrix(world_r[:, joints[0]]).as_rotvec()
    offsets = data.offsets[joints] * metres
    offsets[0] = 0.0
    skeleton = DEFAULT_SKELETON if np.allclose(offsets, DEFAULT_SKELETON.offsets, rtol=0.0, atol=1e-5) else \
        Skeleton(offsets, JOINT_NAMES, PARENTS, DEFAULT_SKELETON.end_sites)
    return Motion(rotations, root, data.fps, skeleton)


def _metres_per_unit(name: str, bones: np.ndarray) -> float:
    """The unit of a dance's BVH, from its bones [54, 3] against our dancer's: the file unit that makes it nearest
    our size, or a one-line error when no unit makes it a dancer's size."""
    size = float(np.linalg.norm(bones, axis=-1).sum() / np.linalg.norm(DEFAULT_SKELETON.offsets, axis=-1).sum())
    metres = dancer_unit(size, 1.0, FILE_UNITS.values())
    if not SIZE_RANGE[0] <= size * metres <= SIZE_RANGE[1]:
        raise DanceNetError(f"{name}: its skeleton is {size:.3g} times our dancer's size, which no unit "
                            f"({FILE_UNIT_NAMES}) makes a dancer's; export it again in one of them")
    return metres

"""A BVH clip of any humanoid skeleton as a rig's clip: the bones' world rest and pose matrices that
`jointmap.armature_pose` reads, as the add-on samples a rig in Blender, so a BVH and an FBX of one dance read
alike.

Which joint is which comes from the shared bone mapper (`rigmap.humanoid_joints`: the shipped maps by names, then
the skeleton's shape, or a map the folder's manifest names), run on the file's rest pose: each joint a bone from
its head on to its child or End Site (`rest_bones`). The rest pose may stand along any axis, in any unit, any pose;
the motion's world may stand along another (AMASS's CMU files rest Y-up and move Z-up): it is turned onto the
rest's. A first frame an exporter prepends in the rest pose (iClone's T-pose), followed by a jump into the dance, is
dropped.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from ..bvh import BvhData, read_bvh
from ..errors import DanceNetError
from ..jointmap import min_rotation, up_rotation
from ..rigmap import BoneMap, RestBone
from ..rigmap.humanoid import mapped_humanoid
from ..skeleton import JOINT_INDEX

REST_DEG = 0.5  # a frame whose mapped joints all turn less than this from the rest pose is the rest pose
JUMP = 0.1  # a frame whose joints move this share of the body's height from the one before is a jump
# Turns that make a file's rest frame Z up (the bone mapper's frame), the usual BVH Y up first.
_TO_Z_UP = [Rotation.from_euler("x", a, degrees=True) for a in (90, 0, -90, 180)] + [
    Rotation.from_euler("y", a, degrees=True) for a in (-90, 90)]  # fmt: skip


class BvhRig(NamedTuple):
    """A BVH as a rig's clip: our joints the file has (`joints`, ascending), each one's bone's world rest matrix
    [K, 4, 4] and world matrix per frame [T, K, 4, 4] (the head at the translation, the Y axis along the bone; the
    file's units), the frame rate, and the bone map that read the skeleton (the convention found)."""

    joints: list[int]
    rest: np.ndarray
    pose: np.ndarray
    fps: float
    convention: str


def bvh_rig(path: Path, bone_map: BoneMap | None = None, data: BvhData | None = None) -> BvhRig:
    """The clip in `path` (`data`: the file already read) as a rig's clip (`BvhRig`); a one-line DanceNetError for
    a skeleton that is no humanoid's or a file that is no BVH."""
    data = read_bvh(path) if data is None else data
    heads, tails = rest_bones(data)
    convention, mapped = _mapped(data, heads, tails, path.name, bone_map)
    joints = sorted(mapped)
    cols = [mapped[j] for j in joints]
    rest_rot = min_rotation(np.array([0.0, 1.0, 0.0]), tails[cols] - heads[cols])
    world_p, world_r = data._fk()
    first = _first_danced(data, world_p[:, cols], world_r, heads[cols], cols, joints)
    world_p, world_r = _upright(world_p[:, cols], world_r[:, cols], heads[cols], joints)
    rest = np.zeros((len(cols), 4, 4))
    rest[:, :3, :3], rest[:, :3, 3], rest[:, 3, 3] = rest_rot, heads[cols], 1.0
    pose = np.zeros((data.num_frames - first, len(cols), 4, 4))
    pose[..., :3, :3], pose[..., :3, 3], pose[..., 3, 3] = world_r[first:] @ rest_rot, world_p[first:], 1.0
    return BvhRig(joints, rest, pose, data.fps, convention)


def rest_bones(data: BvhData) -> tuple[np.ndarray, np.ndarray]:
    """Each joint's rest head and tail [J, 3] (the file's frame and units): the tail where the bone runs on
    straightest (of its children and End Sites, the one most along its parent's bone to it: a head runs to the
    head's top, not to the jaw or the eyes; a chest to the neck, not to a collar), the mean of its children for the
    root, on along its parent's bone for an end without a site."""
    heads = np.zeros((data.num_joints, 3))
    for j, p in enumerate(data.parents):
        heads[j] = data.offsets[j] + (heads[p] if p >= 0 else 0.0)
    ends: list[list[np.ndarray]] = [[] for _ in data.names]
    for j, p in enumerate(data.parents):
        if p >= 0:
            ends[p].append(heads[j])
    for site in data.end_sites:
        ends[site.parent].append(heads[site.parent] + np.asarray(site.offset, dtype=np.float64))
    size = max(float(np.ptp(heads, axis=0).max()), 1e-9)
    tails = heads.copy()
    for j, p in enumerate(data.parents):
        bones = [e - heads[j] for e in ends[j] if np.linalg.norm(e - heads[j]) > 1e-3 * size]
        along = heads[j] - heads[p] if p >= 0 else np.zeros(3)
        if np.linalg.norm(along) <= 1e-3 * size:
            along = np.array([0.0, 1.0, 0.0])
        if not bones:  # an end without a site: on along its parent's bone
            bone = along / np.linalg.norm(along) * 0.05 * size
        elif p < 0:
            bone = np.mean(bones, axis=0) if np.linalg.norm(np.mean(bones, axis=0)) > 1e-3 * size else bones[0]
        else:
            bone = max(bones, key=lambda v: float(v @ along) / float(np.linalg.norm(v)))
        tails[j] = heads[j] + bone
    return heads, tails


def _mapped(data: BvhData, heads: np.ndarray, tails: np.ndarray, name: str,
            bone_map: BoneMap | None) -> tuple[str, dict[int, int]]:
    """Our joint -> the file's joint index, by the bone mapper on the rest pose turned Z up: the first way up
    (the usual BVH Y up first) under which the head stands above the pelvis."""
    index = {n: i for i, n in enumerate(data.names)}
    parents = [data.names[p] if p >= 0 else None for p in data.parents]
    first_error: DanceNetError | None = None
    found: tuple[str, dict[int, str]] | None = None
    for turn in _TO_Z_UP:
        h, t = turn.apply(heads), turn.apply(tails)
        bones = [RestBone(n, parents[j], h[j], t[j]) for j, n in enumerate(data.names)]
        try:
            convention, joints = mapped_humanoid(bones, name, bone_map)
        except DanceNetError as e:
            first_error = first_error or e
            continue
        found = found or (convention, joints)
        up = h[index[joints[JOINT_INDEX["head"]]]] - h[index[joints[JOINT_INDEX["pelvis"]]]]
        if up[2] > 0.5 * np.linalg.norm(up):
            found = convention, joints
            break
    if found is None:
        raise DanceNetError(f"{first_error}; name its bones in a bone map (docs/library.md)")
    return found[0], {j: index[b] for j, b in found[1].items()}


def _upright(positions: np.ndarray, rotations: np.ndarray, rest: np.ndarray,
             joints: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """The motion's world turned so that it stands along the axis its rest pose stands along (a file whose root
    turns its rest into another world, as AMASS's CMU files do, Y up to Z up)."""
    pelvis, head = joints.index(JOINT_INDEX["pelvis"]), joints.index(JOINT_INDEX["head"])
    turn = up_rotation(rest[None], pelvis, head).inv() * up_rotation(positions, pelvis, head)
    if np.allclose(turn.as_matrix(), np.eye(3)):
        return positions, rotations
    m = turn.as_matrix()
    return positions @ m.T, m @ rotations


def _first_danced(data: BvhData, positions: np.ndarray, world: np.ndarray, rest: np.ndarray, cols: list[int],
                  joints: list[int]) -> int:
    """The first frame of the dance: past the rest-pose frames an exporter put first, when a jump into the dance
    follows them (a dance that starts from its rest pose and moves off smoothly keeps them). `world`: every joint's
    world rotation [T, J, 3, 3]; `positions`: the mapped joints' [T, K, 3]."""
    kids = [c for c in cols[1:] if data.parents[c] >= 0]
    local = np.swapaxes(world[:, [data.parents[c] for c in kids]], -1, -2) @ world[:, kids]
    cos = np.clip((np.trace(local, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    local = np.degrees(np.arccos(cos)).max(axis=1)
    at_rest = int(np.argmin(local < REST_DEG)) if not (local < REST_DEG).all() else data.num_frames
    if at_rest == 0 or at_rest == data.num_frames:
        return 0
    pelvis = joints.index(JOINT_INDEX["pelvis"])
    body = positions - positions[:, pelvis : pelvis + 1]
    height = float(np.ptp(rest, axis=0).max())
    jump = float(np.linalg.norm(body[at_rest] - body[at_rest - 1], axis=-1).max())
    return at_rest if jump > JUMP * height else 0

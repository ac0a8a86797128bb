"""Motion -> pose-bone values on any armature by rest-pose difference (`retarget`), written as an action in bulk
(`write_action`).

The retarget works in world space. For each mapped bone it asks for the world rotation
    Q · G_j · Qᵀ · D_j · R_rest
where G_j is joint j's world rotation from the core's FK (relative to our T-pose, turned to Blender's
Z-up), Q turns our character frame onto the rig's (so a Y-up Mixamo import or a rig facing elsewhere
dances facing its own front), and D_j is the smallest rotation taking the rig's rest bone direction onto
ours (an A-pose arm is first lifted into our T-pose). The pose-bone value is that rotation relative to
where the bone would be with an identity pose, which for our own rig reduces to
Rb⁻¹ · (C L_j Cᵀ) · Rb. Positions then follow our FK exactly on our rig and direction-wise elsewhere,
except that legs and arms bend (two-bone IK in the plane they already bend in) so feet and hands land
where the dance puts them, scaled like the hips, on a rig whose limbs are longer or shorter than ours.
"""


from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import bpy
import numpy as np
from scipy.spatial.transform import Rotation

from dancenet_core.jointmap import bone_directions, character_frame, min_rotation, rotation_part
from dancenet_core.kinematics import fk_numpy
from dancenet_core.rigmap import SPINE_JOINTS

from . import rigdef

if TYPE_CHECKING:
    from dancenet_core.motion import Motion
    from dancenet_core.skeleton import Skeleton


@dataclass
class PoseTracks:
    """Pose-bone values per frame: quaternions (w, x, y, z) per bone and the root bone's location."""

    rotations: dict[str, np.ndarray]  # bone -> [T, 4]
    root_bone: str
    root_locations: np.ndarray  # [T, 3]
    # A root bone above the hips: its name, quaternions [T, 4] and locations [T, 3] (root-bone motion).
    floor_bone: tuple[str, np.ndarray, np.ndarray] | None = None
    # Each mapped bone's world matrices [T, 4, 4]: where a control rig's deform bones must go.
    world: dict[str, np.ndarray] = field(default_factory=dict)
    # Bones keyed in the Euler order they already use (a control rig's): bone -> angles [T, 3] (X, Y, Z).
    eulers: dict[str, np.ndarray] = field(default_factory=dict)
    # Custom properties keyed once (a control rig's IK/FK switches): data path -> value.
    properties: dict[str, float] = field(default_factory=dict)

    @property
    def num_frames(self) -> int:
        return len(self.root_locations)


def continuous_quaternions(matrices: np.ndarray) -> np.ndarray:
    """Rotation matrices [T, 3, 3] -> quaternions [T, 4] (w, x, y, z) without sign flips between frames."""
    q = Rotation.from_matrix(matrices).as_quat()[:, [3, 0, 1, 2]]
    if len(q) > 1:
        flips = np.cumprod(np.where(np.einsum("ti,ti->t", q[1:], q[:-1]) < 0, -1.0, 1.0))
        q[1:] *= flips[:, None]
    return q


def _leg_length(heads: dict[int, np.ndarray], skeleton: Skeleton) -> float:
    """Mean hip-knee-ankle length of the two legs: how far a rig's hips travel for our metre."""
    total = 0.0
    for side in ("left", "right"):
        hip, knee, ankle = (skeleton.index(f"{side}_{n}") for n in ("hip", "knee", "ankle"))
        total += np.linalg.norm(heads[knee] - heads[hip]) + np.linalg.norm(heads[ankle] - heads[knee])
    return float(total / 2)


# Two-bone limbs (upper joint: middle joint, end joint) whose end is put where the dance puts it.
_LIMBS = {f"{side}_{upper}": (f"{side}_{mid}", f"{side}_{end}") for side in ("left", "right")
          for upper, mid, end in (("hip", "knee", "ankle"), ("shoulder", "elbow", "wrist"))}


def _reach(
    p_upper: np.ndarray, p_mid: np.ndarray, p_end: np.ndarray, want: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Two-bone IK: world turns (for the upper bone, for the lower one) that move the end from `p_end` to
    `want` (or as near as the bone lengths allow), the limb bending in the plane it already bends in."""
    a = np.linalg.norm(p_mid - p_upper, axis=-1, keepdims=True)
    b = np.linalg.norm(p_end - p_mid, axis=-1, keepdims=True)
    to = want - p_upper
    d = np.clip(np.linalg.norm(to, axis=-1, keepdims=True), np.abs(a - b) + 1e-6, a + b - 1e-6)
    u = to / np.maximum(np.linalg.norm(to, axis=-1, keepdims=True), 1e-12)
    bend = (p_mid - p_upper) - np.einsum("ti,ti->t", p_mid - p_upper, u)[:, None] * u
    straight = np.linalg.norm(bend, axis=-1, keepdims=True) < 1e-9  # no bend plane: leave the frame alone
    n = bend / np.maximum(np.linalg.norm(bend, axis=-1, keepdims=True), 1e-12)
    cos = np.clip((a**2 + d**2 - b**2) / (2 * a * d), -1.0, 1.0)
    mid = np.where(straight, p_mid, p_upper + a * (cos * u + np.sqrt(1 - cos**2) * n))
    end = np.where(straight, p_end, p_upper + d * u)
    turn_upper = min_rotation(p_mid - p_upper, mid - p_upper)
    turn_lower = min_rotation(np.einsum("tij,tj->ti", turn_upper, p_end - p_mid), end - mid) @ turn_upper
    return turn_upper, turn_lower


def _travel_bone(rig: bpy.types.Object, bone_map: dict[str, str]) -> str:
    """The bone keyed with the body's travel: the hips bone, or, where the spine does not hang below it (MMD's
    上半身 and 下半身 both hang from センター), the nearest bone above both, so the whole body moves."""
    bones = rig.data.bones
    spine = next(bone_map[j] for j in SPINE_JOINTS if j in bone_map)
    above_spine = {b.name for b in bones[spine].parent_recursive}
    if bone_map["pelvis"] in above_spine:
        return bone_map["pelvis"]
    return next((b.name for b in bones[bone_map["pelvis"]].parent_recursive if b.name in above_spine),
                bone_map["pelvis"])


def root_bone_of(rig: bpy.types.Object, hips: str) -> str | None:
    """The bone at the top of the hips bone's chain (a root bone for engines' root motion), if any."""
    parents = rig.data.bones[hips].parent_recursive
    return parents[-1].name if parents else None


def _floor_tracks(rest: np.ndarray, a: np.ndarray, o: np.ndarray, turn: np.ndarray, floor: np.ndarray,
                  yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quaternions and locations of a root bone (rest world matrix `rest`) that carry the dance's floor path
    and heading. The core maps a point p to the rig's world as a @ p + o, with `turn` its rotation part; the
    root must move the world as F(y) = T R T^-1 (y - o) + a X + o (R: the heading about the core's up, X: the
    floor point), so its pose is rest^-1 F rest."""
    t = len(yaw)
    f = np.broadcast_to(np.eye(4), (t, 4, 4)).copy()
    # yaw as (t, 1): newer scipy reads a 1-D array for one axis as a single rotation
    f[:, :3, :3] = turn @ Rotation.from_euler("y", yaw[:, None]).as_matrix() @ turn.T
    f[:, :3, 3] = floor @ a.T + o - f[:, :3, :3] @ o
    basis = np.linalg.inv(rest) @ f @ rest
    return continuous_quaternions(basis[:, :3, :3]), basis[:, :3, 3]


class _Fit:
    """The dance fitted onto a rig, what every bone's pose is computed from: the rig's world rest matrices, our
    rest joints and its mapped bones' heads in Blender's axes, the turn of our character frame onto the rig's
    (`frame_turn`), the size of its legs to ours (`scale`), each mapped joint's turn from our rest bone direction
    onto the rig's (`rest_turns`), where a bone stands for joints the rig lacks (`spans`), and the dance's FK."""

    def __init__(self, rig: bpy.types.Object, motion: Motion, bone_map: dict[str, str]) -> None:
        skeleton = self.skeleton = motion.skeleton
        self.mapped = {skeleton.index(joint): bone for joint, bone in bone_map.items()}
        self.joint_of = {bone: j for j, bone in self.mapped.items()}
        world = np.array(rig.matrix_world)
        self.rest = {b.name: world @ np.array(b.matrix_local) for b in rig.data.bones}
        up = rigdef.Y_UP_TO_Z_UP
        self.ours = rigdef.rest_heads(skeleton) @ up.T
        self.theirs = {j: self.rest[b][:3, 3] for j, b in self.mapped.items()}
        frame_keys = [skeleton.index(n) for n in ("left_hip", "right_hip", "pelvis", "neck")]
        self.frame_turn = (character_frame(*(self.theirs[k] for k in frame_keys))
                           @ character_frame(*(self.ours[k] for k in frame_keys)).T)
        self.scale = _leg_length(self.theirs, skeleton) / _leg_length(dict(enumerate(self.ours)), skeleton)
        self.rest_turns: dict[int, np.ndarray] = {}
        self.spans: dict[int, int] = {}  # joint -> the mapped joint its bone reaches past joints the rig lacks
        pairs = bone_directions(skeleton, self.theirs, {j: self.rest[b][:3, 1] for j, b in self.mapped.items()})
        for j, pair in pairs.items():
            self.rest_turns[j] = min_rotation(pair.theirs, self.frame_turn @ up @ pair.ours)
            if pair.reach is not None:
                self.spans[j] = pair.reach
        self.positions, turns = fk_numpy(skeleton, motion.rotations, motion.root_positions)
        self.to_rig = self.frame_turn @ up
        self.world_turns = self.to_rig @ turns @ self.to_rig.T  # in Blender axes, on the rig's own frame
        # The dance is scaled onto the rig about the hips, where the legs start, not about the pelvis bone's
        # head: rigs put that head anywhere from above the hips (ours) to below them (Rigify's), and scaling
        # about it would send the feet into the floor or leave them hanging above it.
        self.hips = [skeleton.index(f"{side}_hip") for side in ("left", "right")]
        self.hips_theirs = (self.theirs[self.hips[0]] + self.theirs[self.hips[1]]) / 2
        self.hips_ours = self.ours[self.hips].mean(axis=0)

    def placed(self, points: np.ndarray) -> np.ndarray:
        """Where points of the dance [..., 3] (our FK, Y up) go on the rig."""
        return self.hips_theirs + self.scale * (points @ rigdef.Y_UP_TO_Z_UP.T - self.hips_ours) @ self.frame_turn.T

    def aim(self, j: int, bone: str) -> np.ndarray:
        """Bone `bone`'s world rotation (unit scale) [T, 3, 3] for joint j: the dance's turn of its rest. A bone
        that stands for joints the rig lacks too (a spine of fewer bones) also takes their bend: it points where
        the dance puts the joint it reaches, so the missing bone's turn is spread over the ones present."""
        rest = self.rest[bone][:3, :3]
        turn = self.world_turns[:, j] @ (self.rest_turns[j] @ (rest / np.linalg.norm(rest, axis=0)))
        if j in self.spans:
            k = self.spans[j]
            reaching = self.frame_turn @ (self.ours[k] - self.ours[j])
            turn = min_rotation(np.einsum("tij,j->ti", self.world_turns[:, j], reaching),
                                (self.positions[:, k] - self.positions[:, j]) @ self.to_rig.T) @ turn
        return turn

    def head_offset(self, parent: str, child: str) -> np.ndarray:
        """Where `child`'s head sits in `parent`'s posed world frame (bones in between at rest)."""
        offset = (np.linalg.inv(self.rest[parent]) @ self.rest[child])[:3, 3]
        return offset * np.linalg.norm(self.rest[parent][:3, :3], axis=0)

    def root_target(self) -> np.ndarray:
        """Where the pelvis bone's head goes [T, 3]: where it must be for the hips, which it carries, to be
        where the dance puts them."""
        pelvis = self.mapped[0]
        pelvis_turn = self.aim(0, pelvis) @ rotation_part(self.rest[pelvis]).T
        hips = self.placed(self.positions[:, self.hips].mean(axis=1))
        return hips - pelvis_turn @ (self.hips_theirs - self.theirs[0])


def _top_down(rig: bpy.types.Object, bones: Iterable[str],
              parents: dict[str, str | None] | None) -> list[tuple[str, str | None]]:
    """`bones` and every bone above them, each with its parent, parents first. `parents` (bone -> bone)
    stands for the armature's parenting where constraints, not parents, chain the bones (a control rig)."""

    def parent_of(name: str) -> str | None:
        if parents is not None:
            return parents[name]
        return None if rig.data.bones[name].parent is None else rig.data.bones[name].parent.name

    depth: dict[str, int] = {}

    def depth_of(name: str) -> int:
        if name not in depth:
            up = parent_of(name)
            depth[name] = 0 if up is None else depth_of(up) + 1
        return depth[name]

    for bone in bones:
        depth_of(bone)
    return [(name, parent_of(name)) for name in sorted(depth, key=depth.__getitem__)]


def _limb_aim(fit: _Fit, name: str, j: int, at_rest: np.ndarray, target: np.ndarray,
              limb_turn: dict[str, np.ndarray]) -> np.ndarray:
    """An upper limb bone's world rotation turned so that the hand or foot goes where the dance puts it (scaled
    like the hips), whatever the rig's limb proportions: the angles alone would put it elsewhere on a rig
    built unlike our dancer. The lower bone's extra turn goes into `limb_turn`."""
    limb = _LIMBS.get(fit.skeleton.names[j])
    if limb is None or not all(fit.skeleton.index(x) in fit.mapped for x in limb):
        return target
    mid, end = (fit.skeleton.index(x) for x in limb)
    lower, end_bone = fit.mapped[mid], fit.mapped[end]
    p_upper = at_rest[:, :3, 3] * np.ones((len(fit.positions), 1))
    p_mid = p_upper + target @ fit.head_offset(name, lower)
    p_end = p_mid + fit.aim(mid, lower) @ fit.head_offset(lower, end_bone)
    turn_upper, limb_turn[lower] = _reach(p_upper, p_mid, p_end, fit.placed(fit.positions[:, end]))
    return turn_upper @ target


def _root_locations(at_rest: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """The travel bone's locations [T, 3] (in its rest frame) that move it by world `offset` [T, 3]."""
    return (np.linalg.inv(at_rest[:, :3, :3]) @ offset[:, :, None])[:, :, 0]


def retarget(rig: bpy.types.Object, motion: Motion, bone_map: dict[str, str],
             floor: tuple[str, np.ndarray, np.ndarray] | None = None,
             parents: dict[str, str | None] | None = None) -> PoseTracks:
    """Pose tracks that make `rig` perform `motion`; `bone_map` maps joint names to existing bone names.

    The map must contain the pelvis and the joints in `rigmap.REQUIRED_JOINTS` (see `rigmap.resolve`).
    Unmapped bones keep an identity pose and ride along with their parents. With `floor` = (root bone,
    floor points [T, 3], heading [T]) (see `rootmotion.split_root`), `motion` is the dance seen from the
    root bone, and the root bone is keyed to carry it along the floor. `parents` (mapped bone -> mapped bone)
    stands for the armature's parenting where constraints, not parents, chain the bones (a control rig).
    """
    fit = _Fit(rig, motion, bone_map)
    frames = motion.num_frames
    root_target = fit.root_target()
    travel = _travel_bone(rig, bone_map)
    posed: dict[str, np.ndarray] = {}  # bone -> world matrices [T or 1, 4, 4]
    rotations: dict[str, np.ndarray] = {}
    limb_turn: dict[str, np.ndarray] = {}  # lower limb bone -> its extra world turn from the limb's IK
    root_locations = np.zeros((frames, 3))
    for name, parent in _top_down(rig, fit.mapped.values(), parents):
        rest = fit.rest[name]
        at_rest = rest[None] if parent is None else posed[parent] @ (np.linalg.inv(fit.rest[parent]) @ rest)
        j = fit.joint_of.get(name)
        if name == travel != fit.mapped[0]:  # above the hips and the spine: it carries the body to where the hips go
            offset = root_target - fit.theirs[0]
            posed[name] = np.broadcast_to(at_rest, (frames, 4, 4)).copy()
            posed[name][:, :3, 3] += offset
            root_locations = _root_locations(at_rest, offset)
            continue
        if j is None:
            posed[name] = at_rest
            continue
        # The bone's world scale (the object's, e.g. 0.01 for a Mixamo import) is the same in every pose.
        scale_xyz = np.linalg.norm(rest[:3, :3], axis=0)
        target = fit.aim(j, name)
        if name in limb_turn:
            target = limb_turn[name] @ target
        target = _limb_aim(fit, name, j, at_rest, target, limb_turn)
        rotations[name] = continuous_quaternions(np.swapaxes(at_rest[:, :3, :3] / scale_xyz, -1, -2) @ target)
        posed[name] = np.broadcast_to(at_rest, (frames, 4, 4)).copy()
        posed[name][:, :3, :3] = target * scale_xyz
        if j == 0 and name == travel:
            root_locations = _root_locations(at_rest, root_target - at_rest[:, :3, 3])
            posed[name][:, :3, 3] = root_target
    tracks = PoseTracks(rotations, travel, root_locations, world={b: posed[b] for b in fit.mapped.values()})
    if floor is not None:
        root, points, yaw = floor
        origin = fit.hips_theirs - fit.scale * fit.frame_turn @ fit.hips_ours
        tracks.floor_bone = (root, *_floor_tracks(fit.rest[root], fit.scale * fit.to_rig, origin, fit.to_rig, points,
                                                  yaw))
    return tracks


_LINEAR = bpy.types.Keyframe.bl_rna.properties["interpolation"].enum_items["LINEAR"].value


def _fill(fcurve: bpy.types.FCurve, frames: np.ndarray, values: np.ndarray) -> None:
    """One key per frame in three bulk calls.

    Linear interpolation: with a key on every frame it only matters between frames (motion blur,
    retimed playback), and it needs no Bezier handles, which would cost a recalculation per curve
    (Blender recomputes them itself if the user switches a curve to Bezier).
    """
    n = len(frames)
    co = np.empty(2 * n, dtype=np.float32)
    co[0::2] = frames
    co[1::2] = values
    points = fcurve.keyframe_points
    points.add(n)
    points.foreach_set("co", co)
    points.foreach_set("interpolation", np.full(n, _LINEAR, dtype=np.int32))


def _fcurve_maker(
    action: bpy.types.Action, rig: bpy.types.Object
) -> tuple[bpy.types.ActionSlot | None, Callable[[str, int, str], bpy.types.FCurve]]:
    """(slot or None, new(data_path, index, group) -> FCurve) for layered (4.4+) or legacy actions."""
    if hasattr(action, "slots"):
        slot = action.slots.new(id_type="OBJECT", name=rig.name)
        bag = action.layers.new("Layer").strips.new(type="KEYFRAME").channelbag(slot, ensure=True)
        groups: dict[str, bpy.types.ActionGroup] = {}

        def new_layered(path: str, index: int, group: str) -> bpy.types.FCurve:
            fcurve = bag.fcurves.new(path, index=index)
            if group not in groups:
                groups[group] = bag.groups.new(group)
            fcurve.group = groups[group]
            return fcurve

        return slot, new_layered

    def new_legacy(path: str, index: int, group: str) -> bpy.types.FCurve:
        return action.fcurves.new(path, index=index, action_group=group)

    return None, new_legacy


def write_action(rig: bpy.types.Object, tracks: PoseTracks, name: str, frame_start: int) -> bpy.types.Action:
    """A new action (never reusing one) with one key per frame from `frame_start`, assigned to `rig`.

    The action keeps a fake user, so earlier takes survive saving even when no object uses them.
    """
    action = bpy.data.actions.new(name)
    action.use_fake_user = True
    slot, new_fcurve = _fcurve_maker(action, rig)
    frames = frame_start + np.arange(tracks.num_frames, dtype=np.float64)
    for bone, quats in tracks.rotations.items():
        rig.pose.bones[bone].rotation_mode = "QUATERNION"
        path = f'pose.bones["{bpy.utils.escape_identifier(bone)}"].rotation_quaternion'
        for i in range(4):
            _fill(new_fcurve(path, i, bone), frames, quats[:, i])
    path = f'pose.bones["{bpy.utils.escape_identifier(tracks.root_bone)}"].location'
    for i in range(3):
        _fill(new_fcurve(path, i, tracks.root_bone), frames, tracks.root_locations[:, i])
    for bone, angles in tracks.eulers.items():
        path = f'pose.bones["{bpy.utils.escape_identifier(bone)}"].rotation_euler'
        for i in range(3):
            _fill(new_fcurve(path, i, bone), frames, angles[:, i])
    for path, value in tracks.properties.items():
        _fill(new_fcurve(path, 0, "IK/FK"), frames[:1], np.array([value]))
    if tracks.floor_bone is not None:
        bone, quats, locations = tracks.floor_bone
        rig.pose.bones[bone].rotation_mode = "QUATERNION"
        path = f'pose.bones["{bpy.utils.escape_identifier(bone)}"]'
        for i in range(4):
            _fill(new_fcurve(f"{path}.rotation_quaternion", i, bone), frames, quats[:, i])
        for i in range(3):
            _fill(new_fcurve(f"{path}.location", i, bone), frames, locations[:, i])
    anim = rig.animation_data or rig.animation_data_create()
    anim.action = action
    if slot is not None:
        anim.action_slot = slot
    return action

"""Motion -> keyframes: retarget onto any armature by rest-pose difference, then write actions in bulk.

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

from dancenet_core.errors import DanceNetError
from dancenet_core.jointmap import bone_directions, character_frame, min_rotation, rotation_part
from dancenet_core.kinematics import fk_numpy
from dancenet_core.rigmap import SPINE_JOINTS

from . import rigcontrols, rigdef

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


def _continuous_quaternions(matrices: np.ndarray) -> np.ndarray:
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
    return _continuous_quaternions(basis[:, :3, :3]), basis[:, :3, 3]


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
        rotations[name] = _continuous_quaternions(np.swapaxes(at_rest[:, :3, :3] / scale_xyz, -1, -2) @ target)
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


def _joint_parents(skeleton: Skeleton, bone_map: dict[str, str]) -> dict[str, str | None]:
    """Mapped bone -> the bone of the nearest mapped joint above its joint (None for the pelvis')."""
    parents: dict[str, str | None] = {}
    for joint, bone in bone_map.items():
        p = skeleton.parents[skeleton.index(joint)]
        while p >= 0 and skeleton.names[p] not in bone_map:
            p = skeleton.parents[p]
        parents[bone] = bone_map[skeleton.names[p]] if p >= 0 else None
    return parents


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles [T] between rotations a and b [T, 3, 3]."""
    return np.arccos(np.clip((np.einsum("tij,tij->t", a, b) - 1.0) / 2.0, -1.0, 1.0))


def _miss(posed: np.ndarray, target: np.ndarray, aimed: bool) -> np.ndarray:
    """Angles [T] between bones' posed and target matrices [T, 4, 4]: between their Y axes if `aimed`."""
    if aimed:
        y, want = rotation_part(posed)[:, :, 1], rotation_part(target)[:, :, 1]
        return np.arccos(np.clip(np.einsum("ti,ti->t", y, want), -1.0, 1.0))
    return _angle(rotation_part(posed), rotation_part(target))


def _evaluate(rig: bpy.types.Object, scene: bpy.types.Scene, frames: np.ndarray, bones: list[str]) -> np.ndarray:
    """Armature-space matrices [T, B, 4, 4] of `bones` as Blender evaluates them at each frame: constraints,
    drivers and the IK/FK switches included, whatever the rig does between its controls and its bones."""
    pose = rig.pose.bones
    index = [pose.find(b) for b in bones]
    buf = np.empty(len(pose) * 16, dtype=np.float32)
    out = np.empty((len(frames), len(bones), 4, 4))
    for t, frame in enumerate(frames):
        scene.frame_set(int(frame))
        pose.foreach_get("matrix", buf)
        out[t] = np.swapaxes(buf.reshape(-1, 4, 4)[index], 1, 2)  # Blender lays matrices out by column
    return out


# Control-rig solve: passes (one evaluation of every frame each, the first one's of the rest pose only) until
# the deform bones turn within this of where the dance wants them; a rig whose controls drive its bones rigidly,
# whose carriers are found (`_carriers`), is done after one turn (Rigify's generated rig is).
_SOLVE_PASSES = 6
_SOLVE_TOLERANCE_DEG = 0.1
_SOLVE_GAP = 1e-3  # and the hips within this share of their bone's length of where the dance puts them


def _control_tracks(rig: bpy.types.Object, controls: rigcontrols.ControlRig, bases: dict[str, np.ndarray],
                    location: np.ndarray, floor: tuple[str, np.ndarray, np.ndarray] | None) -> PoseTracks:
    """The controls' pose-bone values: each in its own rotation mode (Euler orders kept, so the rig's other
    actions still read), the pelvis' control with its location, the IK/FK switches on FK."""
    tracks = PoseTracks({}, controls.controls["pelvis"][0], location, floor)
    for bone, basis in bases.items():
        mode = rig.pose.bones[bone].rotation_mode
        if mode in {"QUATERNION", "AXIS_ANGLE"}:
            tracks.rotations[bone] = _continuous_quaternions(basis)
        else:
            angles = Rotation.from_matrix(basis).as_euler(mode.lower())
            tracks.eulers[bone] = np.unwrap(angles[:, [mode.index(a) for a in "XYZ"]], axis=0)
    for pb in rig.pose.bones:
        for prop, value in controls.switches.items():
            if prop in pb:
                tracks.properties[f'pose.bones["{bpy.utils.escape_identifier(pb.name)}"]["{prop}"]'] = value
    return tracks


def _key_controls(rig: bpy.types.Object, motion: Motion, bone_map: dict[str, str], controls: rigcontrols.ControlRig,
                  name: str, frame_start: int, root_bone: bool) -> bpy.types.Action:
    """Key a control rig's controls so its deform bones (`bone_map`) perform `motion`, no constraint muted.

    The controls do not sit like the deform bones (other rest orientations, bones and constraints between),
    so the solve runs through Blender itself: key the controls, evaluate every frame, turn each control by
    what its deform bone still lacks (and move the pelvis' control by what the hips lack), parents first, a
    child counting on its parent's turn, and again until the bones are where the dance wants them.
    """
    from dancenet_core.rootmotion import split_root

    floor = None
    if root_bone:
        if controls.floor not in rig.data.bones:
            raise DanceNetError(f"Root Bone motion needs {controls.name}'s '{controls.floor}' control, which "
                                f"'{rig.name}' lacks: choose another Root Motion")
        motion, points, yaw = split_root(motion)
        floor = (controls.floor, points, yaw)
    dance = retarget(rig, motion, bone_map, floor, _joint_parents(motion.skeleton, bone_map))
    measured, targets = _control_targets(rig, dance, bone_map, controls)
    data = rig.data.bones
    # (joint, control) pairs, outer controls first; a control's turn carries the controls hanging below it.
    pairs = sorted(((j, c) for j, cs in controls.controls.items() for c in cs),
                   key=lambda pair: len(data[pair[1]].parent_recursive))
    above = _carriers(rig, controls, bone_map, measured)
    pairs.sort(key=lambda pair: _carrier_depth(pair[1], above))
    keyed = {c for _, c in pairs}

    n = dance.num_frames
    frames = frame_start + np.arange(n)
    bases = {c: np.broadcast_to(np.eye(3), (n, 3, 3)).copy() for c in keyed}
    location = np.zeros((n, 3))
    scene = bpy.context.scene
    frame_before = scene.frame_current
    action = None
    watched = sorted(keyed | set(measured.values()))
    carry = _floor_carry(rig, dance, controls)
    hips = measured["pelvis"]
    for solve_pass in range(_SOLVE_PASSES):
        if action is not None:
            bpy.data.actions.remove(action)
        action = write_action(rig, _control_tracks(rig, controls, bases, location, dance.floor_bone), name,
                              frame_start)
        if solve_pass == 0:  # the rest pose on every frame, carried by the floor control where it is keyed
            at_rest = _evaluate(rig, scene, frames[:1], watched)[0]
            moved = np.broadcast_to(np.eye(4), (n, 4, 4)) if carry is None else carry @ np.linalg.inv(carry[0])
            evaluated = moved[:, None] @ at_rest
        else:
            evaluated = _evaluate(rig, scene, frames, watched)
        at = dict(zip(watched, evaluated.swapaxes(0, 1), strict=True))
        error = max(_miss(at[measured[j]], targets[j], j in controls.aimed).max() for j in controls.controls)
        gap = np.linalg.norm(at[hips][:, :3, 3] - targets["pelvis"][:, :3, 3], axis=1).max()
        if error < np.radians(_SOLVE_TOLERANCE_DEG) and gap < _SOLVE_GAP * data[hips].length:
            break
        _turn_controls(controls, pairs, above, at, measured, targets, bases, location)
    else:
        bpy.data.actions.remove(action)
        action = write_action(rig, _control_tracks(rig, controls, bases, location, dance.floor_bone), name,
                              frame_start)
    scene.frame_set(frame_before)
    return action


def _control_targets(rig: bpy.types.Object, dance: PoseTracks, bone_map: dict[str, str],
                     controls: rigcontrols.ControlRig) -> tuple[dict[str, str], dict[str, np.ndarray]]:
    """Per joint of the controls: the bone measured (the deform bone, or its exact twin where the rig has one)
    and where the dance wants it, armature-space matrices [T, 4, 4] (its rest offset from the mapped bone kept;
    carried by the floor control when the dance was retargeted as seen from that control at rest)."""
    data = rig.data.bones
    measured = {j: bone_map[j] for j in controls.controls}
    if controls.exact is not None:
        deform, exact = controls.exact
        for j, bone in measured.items():
            twin = exact + bone.removeprefix(deform)
            if j not in controls.aimed and bone.startswith(deform) and twin in data:
                measured[j] = twin
    to_armature = np.linalg.inv(np.array(rig.matrix_world))
    targets = {j: to_armature @ dance.world[bone_map[j]] @ np.linalg.inv(np.array(data[bone_map[j]].matrix_local))
               @ np.array(data[measured[j]].matrix_local) for j in controls.controls}
    carry = _floor_carry(rig, dance, controls)
    if carry is not None:
        targets = {j: carry @ m for j, m in targets.items()}
    return measured, targets


def _floor_carry(rig: bpy.types.Object, dance: PoseTracks, controls: rigcontrols.ControlRig) -> np.ndarray | None:
    """How the floor control's keys move the rig, armature-space rigid motions [T, 4, 4]; None if not keyed."""
    if dance.floor_bone is None:
        return None
    _, quats, locations = dance.floor_bone
    rest = np.array(rig.data.bones[controls.floor].matrix_local)
    carry = np.broadcast_to(np.eye(4), (dance.num_frames, 4, 4)).copy()
    carry[:, :3, :3] = Rotation.from_quat(quats[:, [1, 2, 3, 0]]).as_matrix()
    carry[:, :3, 3] = locations
    return rest @ carry @ np.linalg.inv(rest)


# A control's carriers: the keyed controls whose turns turn it too, with the share of the turn each passes on
# (None: the part no keyed control turns).
Carriers = tuple[tuple[str | None, float], ...]


def _carriers(rig: bpy.types.Object, controls: rigcontrols.ControlRig, bone_map: dict[str, str],
              measured: dict[str, str]) -> dict[str, Carriers]:
    """Control -> its carriers, which a pass of the solve counts on. Found up the control's parents, through the
    bones whose rotation copies another bone's (Rigify's head copies the torso's, its neck half of it, a finger's
    base hangs from the hand's deform bone): the first keyed control, or the deform or measured bone of a joint
    (then that joint's innermost control). A wrong guess costs a pass, not the result: each pass measures
    where Blender put the bones."""
    keyed = {c for cs in controls.controls.values() for c in cs}
    turned_by = {b: controls.controls[j][-1] for j in measured for b in (bone_map[j], measured[j])}
    pose = rig.pose.bones

    def source(name: str | None, seen: frozenset[str]) -> dict[str | None, float]:
        if name is None or name in seen:
            return {None: 1.0}
        if name in keyed or name in turned_by:
            return {name if name in keyed else turned_by[name]: 1.0}
        # A part copied rotation blends by its influence; a copied transform is followed where it mostly wins.
        copies = [con for con in pose[name].constraints
                  if (con.type == "COPY_ROTATION" and con.influence > 0
                      or con.type == "COPY_TRANSFORMS" and con.influence > 0.5)
                  and not con.mute and con.target == rig and con.subtarget in pose]  # fmt: skip
        parent = pose[name].parent.name if pose[name].parent is not None else None
        if not copies:
            return source(parent, seen | {name})
        share = min(copies[-1].influence, 1.0) if copies[-1].type == "COPY_ROTATION" else 1.0
        mixed: dict[str | None, float] = {}
        for part, weight in ((copies[-1].subtarget, share), (parent, 1.0 - share)):
            for carrier, w in (source(part, seen | {name}).items() if weight > 0 else ()):
                mixed[carrier] = mixed.get(carrier, 0.0) + weight * w
        return mixed

    out = {}
    for c in sorted(keyed):
        parent = pose[c].parent
        found = source(parent.name if parent is not None else None, frozenset({c}))
        out[c] = tuple(sorted(found.items(), key=lambda item: -item[1]))

    def loops(c: str, path: frozenset[str]) -> bool:
        return any(up in path or loops(up, path | {up}) for up, _ in out[c] if up is not None)

    for c in sorted(keyed):  # a loop of carriers is cut where it is found
        if loops(c, frozenset({c})):
            out[c] = ((None, 1.0),)
    return out


def _carrier_depth(control: str | None, above: dict[str, Carriers]) -> int:
    """How many carriers deep a control hangs (a solve pass turns carriers first)."""
    if control is None:
        return -1
    return 1 + max(_carrier_depth(up, above) for up, _ in above[control])


def _carried(carriers: Carriers, turns: dict[str, np.ndarray], head: np.ndarray) -> np.ndarray:
    """What the turns of a control's carriers do to it, a rigid motion [T, 4, 4]: their rotations blended by
    their shares (slerp, as Blender blends a constraint by its influence), its head moved as the main carrier
    moves it."""
    moves = [turns[up] if up is not None else np.eye(4) for up, _ in carriers]
    if len(carriers) == 1:
        return moves[0]
    turn, total = np.broadcast_to(rotation_part(moves[0]), (len(head), 3, 3)), carriers[0][1]
    for move, (_, share) in zip(moves[1:], carriers[1:], strict=True):
        total += share
        step = Rotation.from_matrix(np.swapaxes(turn, 1, 2) @ rotation_part(move)).as_rotvec() * (share / total)
        turn = turn @ Rotation.from_rotvec(step).as_matrix()
    carried = np.broadcast_to(np.eye(4), (len(head), 4, 4)).copy()
    carried[:, :3, :3] = turn
    main = np.broadcast_to(moves[0], (len(head), 4, 4))
    moved = np.einsum("tij,tj->ti", main[:, :3, :3], head) + main[:, :3, 3]
    carried[:, :3, 3] = moved - np.einsum("tij,tj->ti", turn, head)
    return carried


def _turn_controls(controls: rigcontrols.ControlRig, pairs: list[tuple[str, str]], above: dict[str, Carriers],
                   at: dict[str, np.ndarray], measured: dict[str, str], targets: dict[str, np.ndarray],
                   bases: dict[str, np.ndarray], location: np.ndarray) -> None:
    """One pass of the solve: turn each control (its `bases`, and the pelvis' control's `location`, changed in
    place) by what its measured bone as Blender evaluated it (`at`) still lacks, outer controls first, a control
    counting on the turns of its carriers."""
    mover = controls.controls["pelvis"][0]
    n = len(location)
    turns: dict[str, np.ndarray] = {}  # control -> what this pass does to it, a rigid motion [T, 4, 4]
    for j, c in pairs:
        carried = _carried(above[c], turns, at[c][:, :3, 3])
        a_control, a_driven = carried @ at[c], carried @ at[measured[j]]  # after the controls above it turn
        if j in controls.aimed:
            turn = min_rotation(a_driven[:, :3, 1], targets[j][:, :3, 1])
        else:
            turn = rotation_part(targets[j]) @ np.swapaxes(rotation_part(a_driven), 1, 2)
        head = a_control[:, :3, 3]
        move = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
        move[:, :3, :3] = turn
        move[:, :3, 3] = head - np.einsum("tij,tj->ti", turn, head)
        if c == mover:
            # The location is in the frame the bone has with no pose: its current frame turned back by its
            # basis (the same before and after this turn).
            unposed = bases[c] @ np.linalg.inv(a_control[:, :3, :3])
        if j == "pelvis":  # the hips' place, after each of the pelvis' controls, made up by the mover's location
            shift = targets[j][:, :3, 3] - (move @ a_driven)[:, :3, 3]
            move[:, :3, 3] += shift
            location += np.einsum("tij,tj->ti", unposed, shift)
        u = rotation_part(a_control)
        bases[c] = bases[c] @ np.swapaxes(u, 1, 2) @ turn @ u
        turns[c] = move @ carried


def mute_overriding_constraints(rig: bpy.types.Object, bones: list[str]) -> list[str]:
    """Mute constraints on the driven bones (Rigify DEF bones copy ORG bones); returns the bones touched."""
    touched = []
    for name in bones:
        active = [con for con in rig.pose.bones[name].constraints if not con.mute and con.influence > 0]
        for con in active:
            con.mute = True
        if active:
            touched.append(name)
    return touched


def apply_motion(
    rig: bpy.types.Object,
    motion: Motion,
    bone_map: dict[str, str],
    action_name: str,
    frame_start: int,
    fps: float | None,
    root_motion: str = "travel",
) -> bpy.types.Action:
    """Retarget `motion` through `bone_map` and write it as a new action on `rig`. A Generate Dance passes its
    takes as `dancenet_core.generate.shape_takes` made them, with `fps` None; given a rate, a motion as danced is
    shaped here first by the same `shape_take` (resampled to `fps`, root motion applied).

    `root_motion` (see `dancenet_core.rootmotion`): "travel", "in-place", or "root-bone" (the bone at the
    top of the hips' chain carries the floor path and heading). A root bone of a rig made by DanceNet is
    keyed at rest in the other modes, so a take never inherits another take's root pose. A control rig
    (Rigify, Auto-Rig Pro: `rigcontrols`) is keyed on its controls instead of the mapped bones.
    """
    from dancenet_core.generate import shape_take  # the command line's shaping too: one output path
    from dancenet_core.rootmotion import split_root

    if fps is not None:
        motion = shape_take(motion, fps, root_motion)
    controls = rigcontrols.find(rig.data.bones.keys(), bone_map)
    if controls is not None:
        return _key_controls(rig, motion, bone_map, controls, action_name, frame_start, root_motion == "root-bone")
    root = root_bone_of(rig, bone_map["pelvis"])
    if root_motion == "root-bone":
        if root is None:
            raise DanceNetError(f"Root Bone motion needs a bone above the hips; '{bone_map['pelvis']}' of "
                                f"'{rig.name}' has none: choose New Rig (it gets a root bone) or another Root Motion")
        local, points, yaw = split_root(motion)
        tracks = retarget(rig, local, bone_map, (root, points, yaw))
    else:
        tracks = retarget(rig, motion, bone_map)
        if root is not None and rig.data.get(rigdef.RIG_PROP):
            n = tracks.num_frames
            tracks.floor_bone = (root, np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), np.zeros((n, 3)))
    return write_action(rig, tracks, action_name, frame_start)

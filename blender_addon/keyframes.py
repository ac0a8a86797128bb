"""Motion -> keyframes on a rig: the dance retargeted onto its mapped bones (`retarget.py`), or, on a control rig
(Rigify, Auto-Rig Pro: `rigcontrols`), onto its controls, solved against Blender's own evaluation of the rig
until the deform bones turn where the dance wants them; `apply_motion` is the one entry.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import bpy
import numpy as np
from scipy.spatial.transform import Rotation

from dancenet_core.errors import DanceNetError
from dancenet_core.jointmap import min_rotation, rotation_part

from . import rigcontrols, rigdef
from .retarget import PoseTracks, continuous_quaternions, retarget, root_bone_of, write_action

if TYPE_CHECKING:
    from dancenet_core.motion import Motion
    from dancenet_core.skeleton import Skeleton


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
            tracks.rotations[bone] = continuous_quaternions(basis)
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
    from dancenet_core.shaping.rootmotion import split_root

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
    takes as `dancenet_core.shaping.takes.shape_takes` made them, with `fps` None; given a rate, a motion as
    danced is shaped here first by the same `shape_take` (resampled to `fps`, root motion applied).

    `root_motion` (see `dancenet_core.shaping.rootmotion`): "travel", "in-place", or "root-bone" (the bone at the
    top of the hips' chain carries the floor path and heading). A root bone of a rig made by DanceNet is
    keyed at rest in the other modes, so a take never inherits another take's root pose. A control rig
    (Rigify, Auto-Rig Pro: `rigcontrols`) is keyed on its controls instead of the mapped bones.
    """
    from dancenet_core.shaping.rootmotion import split_root
    from dancenet_core.shaping.takes import shape_take  # the command line's shaping too: one output path

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

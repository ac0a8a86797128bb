"""A new armature built from the core's Skeleton, plus a simple mannequin mesh skinned to it."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import TypeVar

import bpy
import numpy as np

from dancenet_core.jointmap import tail_offsets
from dancenet_core.skeleton import DEFAULT_SKELETON, Skeleton

from . import rigdef

MANNEQUIN_MATERIAL = "DanceNet Mannequin"

# Body part shapes: joint -> (radius across the bone's X, radius across its Z), metres. A part spans the
# bone from head to tail unless _SPANS says otherwise. Left names stand for both sides.
_RADII: dict[str, tuple[float, float]] = {
    "pelvis": (0.15, 0.11), "spine1": (0.14, 0.10), "spine2": (0.15, 0.10), "spine3": (0.17, 0.11),
    "neck": (0.05, 0.05), "head": (0.085, 0.10), "jaw": (0.045, 0.03), "left_eye_smplhf": (0.014, 0.014),
    "left_collar": (0.045, 0.045), "left_shoulder": (0.05, 0.05), "left_elbow": (0.04, 0.04),
    "left_wrist": (0.045, 0.018), "left_hip": (0.075, 0.075), "left_knee": (0.055, 0.055),
    "left_ankle": (0.045, 0.04), "left_foot": (0.045, 0.03),
}  # fmt: skip
# Parts reach this much past their bone's length, so neighbours overlap at the joints.
_OVERLAP = 1.3
_FINGER_RADIUS = 0.009
_THUMB_RADIUS = 0.011
# Parts that reach past the bone: (start, end) as offsets from the joint in the core frame.
_SPANS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "pelvis": ((0.0, -0.10, 0.0), (0.0, 0.11, -0.02)),
    "head": ((0.0, -0.03, 0.01), (0.0, 0.19, 0.01)),
    "left_ankle": ((0.0, -0.05, -0.06), (0.0, -0.04, 0.12)),
    "left_eye_smplhf": ((0.0, 0.0, -0.012), (0.0, 0.0, 0.012)),
}  # fmt: skip


_T = TypeVar("_T")


def _lookup(table: dict[str, _T], name: str) -> _T | None:
    """A left-side table entry for either side."""
    return table.get(name.replace("right_", "left_"))


def _mirror(v: tuple[float, float, float], name: str) -> np.ndarray:
    return np.array([-v[0], v[1], v[2]]) if name.startswith("right_") else np.array(v)


def _unit_sphere(segments: int = 12, rings: int = 8) -> tuple[np.ndarray, list[tuple[int, ...]]]:
    """UV-sphere vertices (poles on +/-Y) and faces, to be stretched into ellipsoids."""
    verts = [(0.0, 1.0, 0.0)]
    for r in range(1, rings):
        phi = np.pi * r / rings
        for s in range(segments):
            th = 2 * np.pi * s / segments
            verts.append((np.sin(phi) * np.cos(th), np.cos(phi), np.sin(phi) * np.sin(th)))
    verts.append((0.0, -1.0, 0.0))
    bottom = len(verts) - 1
    faces: list[tuple[int, ...]] = []
    for s in range(segments):
        faces.append((0, 1 + (s + 1) % segments, 1 + s))
    for r in range(rings - 2):
        a, b = 1 + r * segments, 1 + (r + 1) * segments
        for s in range(segments):
            n = (s + 1) % segments
            faces.append((a + s, a + n, b + n, b + s))
    last = 1 + (rings - 2) * segments
    for s in range(segments):
        faces.append((last + s, last + (s + 1) % segments, bottom))
    return np.array(verts), faces


def mannequin_parts(skeleton: Skeleton) -> list[tuple[str, np.ndarray, np.ndarray, float, float, np.ndarray]]:
    """(bone, start, end, radius x, radius z, roll axis) per body part, in armature (core) space."""
    heads = rigdef.rest_heads(skeleton)
    tails = tail_offsets(skeleton)
    rolls = rigdef.roll_axes(tails)
    parts = []
    for j, name in enumerate(skeleton.names):
        radii = _lookup(_RADII, name)
        if radii is None:
            r = _THUMB_RADIUS if "thumb" in name else _FINGER_RADIUS
            radii = (r, r)
        span = _lookup(_SPANS, name)
        if span is None:
            start, end = heads[j], heads[j] + tails[j]
        else:
            start, end = heads[j] + _mirror(span[0], name), heads[j] + _mirror(span[1], name)
        parts.append((name, start, end, radii[0], radii[1], rolls[j]))
    return parts


def _mannequin_geometry(
    skeleton: Skeleton,
) -> tuple[np.ndarray, list[tuple[int, ...]], list[tuple[str, range]]]:
    sphere, sphere_faces = _unit_sphere()
    verts, faces, groups = [], [], []
    for name, start, end, rx, rz, roll in mannequin_parts(skeleton):
        axis = end - start
        length = float(np.linalg.norm(axis))
        y = axis / length
        z = roll - (roll @ y) * y
        if np.linalg.norm(z) < 1e-6:  # roll axis along the part: any perpendicular will do
            z = np.cross(y, [1.0, 0.0, 0.0])
        z /= np.linalg.norm(z)
        x = np.cross(y, z)
        local = sphere * np.array([rx, 0.5 * length * _OVERLAP, rz])
        base = sum(len(v) for v in verts)
        verts.append(0.5 * (start + end) + local @ np.stack([x, y, z]))
        faces.extend(tuple(base + i for i in f) for f in sphere_faces)
        groups.append((name, range(base, base + len(sphere))))
    return np.concatenate(verts), faces, groups


def _material() -> bpy.types.Material:
    mat = bpy.data.materials.get(MANNEQUIN_MATERIAL)
    if mat is None:
        mat = bpy.data.materials.new(MANNEQUIN_MATERIAL)
        mat.diffuse_color = (0.8, 0.62, 0.45, 1.0)  # light wood, like an artist's mannequin
        mat.roughness = 0.6
    return mat


def armature_from_rows(
    context: bpy.types.Context,
    name: str,
    rows: Iterable[tuple[str, str | None, Sequence[float], Sequence[float]]],
    roll_axes: Mapping[str, Sequence[float]] | None = None,
) -> bpy.types.Object:
    """A new armature object in the active collection from (bone, parent | None, head, tail) rows in armature
    space, parents named before or after their children; `roll_axes`: where a bone's Z axis points."""
    if context.mode != "OBJECT" and context.view_layer.objects.active is not None:
        bpy.ops.object.mode_set(mode="OBJECT")
    data = bpy.data.armatures.new(name)
    obj = bpy.data.objects.new(name, data)
    (context.collection or context.scene.collection).objects.link(obj)
    context.view_layer.objects.active = obj
    rows = list(rows)
    with context.temp_override(active_object=obj, object=obj):
        bpy.ops.object.mode_set(mode="EDIT")
        for bone, _parent, head, tail in rows:
            eb = data.edit_bones.new(bone)
            eb.head, eb.tail = head, tail
            if roll_axes is not None and bone in roll_axes:
                eb.align_roll(roll_axes[bone])
        for bone, parent, _head, _tail in rows:
            if parent is not None:
                data.edit_bones[bone].parent = data.edit_bones[parent]
        bpy.ops.object.mode_set(mode="OBJECT")
    return obj


def create_rig(
    context: bpy.types.Context,
    name: str = "DanceNet Rig",
    skeleton: Skeleton = DEFAULT_SKELETON,
    with_mesh: bool = True,
    root_bone: bool = False,
) -> bpy.types.Object:
    """A new armature object (and a mannequin mesh child) in the active collection; returns the armature.

    Bone heads sit on the joints, tails point at the main child (or an end site), every pose bone uses
    quaternions, and no bone is connected, so the root's location is the only translation keyed. With
    `root_bone`, a `root` bone on the floor under the hips is their parent (root motion for game engines).
    """
    heads = rigdef.rest_heads(skeleton)
    tails = tail_offsets(skeleton)
    floor = rigdef.ROOT_BONE if root_bone else None
    rows = [(rigdef.ROOT_BONE, None, (0.0, 0.0, 0.0), rigdef.ROOT_TAIL)] if root_bone else []
    rows += [(bone, skeleton.names[p] if p >= 0 else floor, heads[j], heads[j] + tails[j])
             for j, (bone, p) in enumerate(zip(skeleton.names, skeleton.parents, strict=True))]  # fmt: skip
    rig = armature_from_rows(context, name, rows, dict(zip(skeleton.names, rigdef.roll_axes(tails), strict=True)))
    rig.data[rigdef.RIG_PROP] = True
    rig.data.display_type = "OCTAHEDRAL"
    rig.rotation_euler = rigdef.OBJECT_ROTATION
    rig.show_in_front = True
    for pb in rig.pose.bones:
        pb.rotation_mode = "QUATERNION"

    if with_mesh:
        _add_mannequin(rig, skeleton, rig.users_collection[0])
    for obj in context.selected_objects:
        obj.select_set(False)
    rig.select_set(True)
    context.view_layer.update()
    return rig


def _add_mannequin(rig: bpy.types.Object, skeleton: Skeleton, collection: bpy.types.Collection) -> None:
    verts, faces, groups = _mannequin_geometry(skeleton)
    mesh = bpy.data.meshes.new(f"{rig.name} Mannequin")
    mesh.from_pydata(verts.tolist(), [], faces)
    mesh.polygons.foreach_set("use_smooth", np.ones(len(mesh.polygons), dtype=bool))
    mesh.materials.append(_material())
    mesh.update()
    body = bpy.data.objects.new(mesh.name, mesh)
    collection.objects.link(body)
    body.parent = rig  # the mesh is in armature space, so the parent's turn places it
    for bone_name, indices in groups:
        body.vertex_groups.new(name=bone_name).add(list(indices), 1.0, "REPLACE")
    modifier = body.modifiers.new("Armature", "ARMATURE")
    modifier.object = rig

"""FBX clips written by Blender, for the tests and the benchmark: rigs of several conventions danced by one
made-up motion, exported by Blender's FBX exporter. Run as a process of its own with Blender's module
(`python tests/fbx_rigs.py OUT [--seconds S] [--vertices N] [--copies K]`; `written` runs it once per test session);
the motion and the rigs' layout import without bpy, so a test compares what the library read with what was danced.

Rigs (all `SIZE` times our skeleton, so their rest pose is 1.75 m from feet to head):
- `mixamo`: `mixamorig:` names with every finger and the `_End` leaves (65 bones), stored as a Mixamo download
  imports: Y-up centimetres under an object turned 90 degrees and scaled 0.01, with a skinned mesh;
- `generic`: VRM-like `Hips/Spine/LeftUpperLeg` names, Z up in metres, no mesh, T-pose;
- `apose`: Unreal's names (`pelvis`, `thigh_l`), Z up in metres, resting in an A-pose (arms 45 degrees down);
- `mixamo_ascii`: the Mixamo-like rig's file rewritten as ASCII FBX 7.4 (`write_ascii`);
- `mixamo_node_scaled`: the Mixamo-like rig with a 0.01 scale on the armature's own FBX node over its centimetre
  bones in a centimetre file (exported with a global scale of 0.01), which Blender imports at a hundredth of its
  size (0.019 m tall): the Mixamo downloads Build Library refused.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from dancenet_core.kinematics import fk_numpy
from dancenet_core.motion import Motion
from dancenet_core.skeleton import BODY_JOINTS, DEFAULT_SKELETON, JOINT_INDEX

SIZE = 1.1
FPS = 30.0
RX90 = Rotation.from_euler("x", 90, degrees=True).as_matrix()  # our Y-up -> Blender's Z-up
FINGERS = ("thumb", "index", "middle", "ring", "pinky")
FILES = {"mixamo": ("mixamo", {}), "generic": ("generic", {}), "apose": ("apose", {}),
         "mixamo_node_scaled": ("mixamo", {"global_scale": 0.01}),
         "mixamo_ascii": ("mixamo", {})}  # file -> (rig, the exporter's options); *_ascii: rewritten as ASCII FBX
SECONDS = 4.0
_WRITTEN: dict[str, Path] = {}


def dance(seconds: float = SECONDS, seed: int = 0) -> Motion:
    """Every body joint turning smoothly about all three axes, fingers curling, the pelvis travelling and
    bobbing (our skeleton, Y up, metres)."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(seconds * FPS))[:, None, None] / FPS
    amp, freq, phase = rng.uniform(0.1, 0.5, (3, 1, DEFAULT_SKELETON.num_joints, 3))
    rot = amp * np.sin(2 * np.pi * (0.3 + freq) * t + 6 * phase)
    rot[:, BODY_JOINTS:BODY_JOINTS + 3] = 0.0  # jaw and eyes: no rig here has them
    tt = t[:, 0, 0]
    root = np.stack([0.3 * np.sin(tt), DEFAULT_SKELETON.rest_pelvis_height() + 0.03 * np.cos(4 * tt), 0.2 * tt], 1)
    return Motion(rot, root, FPS)


def sized(motion: Motion) -> Motion:
    """`motion` danced by a dancer `SIZE` times ours (what each rig's clip should read as)."""
    return Motion(motion.rotations, motion.root_positions * SIZE, motion.fps, DEFAULT_SKELETON.scaled(SIZE))


_LIMBS = ("hip", "knee", "ankle", "foot", "collar", "shoulder", "elbow", "wrist")
_CAPS = (("left", "Left"), ("right", "Right"))


def _limbs(bones: tuple[str, ...], sides: tuple[tuple[str, str], ...] = _CAPS) -> dict[str, str]:
    """Our limb joints of both sides -> the rig's names, from one name pattern per joint of `_LIMBS` ({s}: the
    side as the rig writes it)."""
    return {f"{side}_{joint}": bone.format(s=s) for side, s in sides for joint, bone in zip(_LIMBS, bones, strict=True)}


def names(kind: str) -> dict[str, str]:
    """Our joint -> the rig's bone name, for each joint the rig has."""
    if kind == "mixamo":
        out = {"pelvis": "Hips", "spine1": "Spine", "spine2": "Spine1", "spine3": "Spine2", "neck": "Neck",
               "head": "Head"}
        for side, cap in _CAPS:
            out |= _limbs(("{s}UpLeg", "{s}Leg", "{s}Foot", "{s}ToeBase", "{s}Shoulder", "{s}Arm", "{s}ForeArm",
                           "{s}Hand"), ((side, cap),))
            out |= {f"{side}_{f}{k}": f"{cap}Hand{f.capitalize()}{k}" for f in FINGERS for k in (1, 2, 3)}
        return {j: "mixamorig:" + b for j, b in out.items()}
    if kind == "generic":
        return {"pelvis": "Hips", "spine1": "Spine", "spine2": "Chest", "spine3": "UpperChest", "neck": "Neck",
                "head": "Head"} | _limbs(("{s}UpperLeg", "{s}LowerLeg", "{s}Foot", "{s}Toes", "{s}Shoulder",
                                          "{s}UpperArm", "{s}LowerArm", "{s}Hand"))
    return {"pelvis": "pelvis", "spine1": "spine_01", "spine2": "spine_02", "spine3": "spine_03", "neck": "neck_01",
            "head": "head"} | _limbs(("thigh_{s}", "calf_{s}", "foot_{s}", "ball_{s}", "clavicle_{s}", "upperarm_{s}",
                                      "lowerarm_{s}", "hand_{s}"), (("left", "l"), ("right", "r")))


def rest_rotations(kind: str) -> np.ndarray:
    """Our joints' local rotations that make the rig's rest pose from our T-pose."""
    rot = np.zeros((DEFAULT_SKELETON.num_joints, 3))
    if kind == "apose":
        rot[JOINT_INDEX["left_shoulder"]] = (0.0, 0.0, -np.pi / 4)
        rot[JOINT_INDEX["right_shoulder"]] = (0.0, 0.0, np.pi / 4)
    return rot


def rows(kind: str) -> list[tuple[str, str | None, np.ndarray, np.ndarray]]:
    """(bone, parent, head, tail) in the armature's space: Y-up cm for `mixamo`, else Z-up metres."""
    s = DEFAULT_SKELETON.scaled(SIZE)
    pos = fk_numpy(s, rest_rotations(kind)[None], np.array([[0.0, s.rest_pelvis_height(), 0.0]]))[0][0]
    pos = pos * 100.0 if kind == "mixamo" else pos @ RX90.T
    bone = names(kind)
    main = {"pelvis": "spine1", "spine3": "neck", "left_wrist": "left_middle1", "right_wrist": "right_middle1"}
    out = []
    for joint, name in bone.items():
        j = s.index(joint)
        kids = [c for c in s.children(j) if s.names[c] in bone]
        child = s.index(main[joint]) if joint in main and main[joint] in bone else (kids[0] if kids else None)
        p = s.parents[j]
        tail = pos[child] if child is not None else pos[j] + (pos[j] - pos[p]) * 0.8
        out.append((name, bone[s.names[p]] if p >= 0 else None, pos[j], tail))
    if kind == "mixamo":  # the leaves a Mixamo download has: fingertips, toe ends, the head's top
        heads = {r[0]: (r[2], r[3]) for r in out}
        for leaf, parent in [("HeadTop_End", "Head")] + [
                (f"{c}Hand{f.capitalize()}4", f"{c}Hand{f.capitalize()}3") for c in ("Left", "Right") for f in FINGERS
        ] + [(f"{c}Toe_End", f"{c}ToeBase") for c in ("Left", "Right")]:  # fmt: skip
            h, t = heads["mixamorig:" + parent]
            out.append(("mixamorig:" + leaf, "mixamorig:" + parent, t, t + (t - h) * 0.5))
    return out


def _keys(rig, motion: Motion, kind: str) -> None:
    """`motion` keyed on every bone of `rig`: each mapped bone turned in the world as our joint turns from the
    rig's rest pose, its head on our joint; the other bones follow their parents. Frame 0 holds the rest pose."""

    s = DEFAULT_SKELETON.scaled(SIZE)
    bone = names(kind)
    rest_pos, rest_rot = fk_numpy(s, rest_rotations(kind)[None], np.zeros((1, 3)))
    pos, rot = fk_numpy(s, motion.rotations, motion.root_positions * SIZE)
    turn = rot @ np.swapaxes(rest_rot[0], -1, -2)  # each joint's turn from the rig's rest, our Y-up frame
    obj = np.array(rig.matrix_world)
    unit = np.linalg.norm(obj[:3, 0])
    a = obj[:3, :3] / unit  # the object's turn
    data = rig.data.bones
    local = {b.name: np.array(b.matrix_local) for b in data}
    of = {b: j for j, b in bone.items()}
    poses: dict[str, np.ndarray] = {}
    basis: dict[str, np.ndarray] = {}
    n = motion.num_frames
    for b in data:  # parents come first
        p = b.parent.name if b.parent is not None else None
        if b.name in of:
            j = s.index(of[b.name])
            m = np.zeros((n, 4, 4))
            m[:, :3, :3] = a.T @ RX90 @ turn[:, j] @ RX90.T @ a @ local[b.name][:3, :3]
            m[:, :3, 3] = ((RX90 @ pos[:, j].T).T - obj[:3, 3]) @ a / unit
            m[:, 3, 3] = 1.0
        else:
            m = poses[p] @ np.linalg.inv(local[p]) @ local[b.name]
        poses[b.name] = m
        rel = local[b.name] if p is None else np.linalg.inv(local[p]) @ local[b.name]
        basis[b.name] = np.linalg.inv(rel) @ (m if p is None else np.linalg.inv(poses[p]) @ m)
    rig.animation_data_create()
    for pb in rig.pose.bones:
        pb.rotation_mode = "QUATERNION"
        pb.keyframe_insert("location", frame=0)
        pb.keyframe_insert("rotation_quaternion", frame=0)
    from dancenet_core.library.fbx_worker import _fcurves

    frames = np.arange(0, n + 1, dtype=np.float64)  # frame 0: the rest pose, where the rig is exported
    for fc in _fcurves(rig.animation_data.action):
        name = fc.data_path.split('"')[1]
        m = np.concatenate([np.eye(4)[None], basis[name]])
        if fc.data_path.endswith("location"):
            values = m[:, fc.array_index, 3]
        else:
            q = Rotation.from_matrix(m[:, :3, :3]).as_quat()  # x y z w
            q *= np.where(q[:, 3:] < 0, -1.0, 1.0)
            q = q[:, [3, 0, 1, 2]]
            for k in range(1, len(q)):  # no flips between frames: the keys interpolate the short way
                if q[k] @ q[k - 1] < 0:
                    q[k] = -q[k]
            values = q[:, fc.array_index]
        fc.keyframe_points.add(n)
        fc.keyframe_points.foreach_set("co", np.c_[frames, values].ravel())
        fc.keyframe_points.foreach_set("interpolation", np.full(n + 1, 1, dtype=np.int32))  # LINEAR
        fc.update()


def _skin(rig, per_bone: int) -> None:
    """A mesh of rings of vertices around every bone, each ring weighted to its bone, skinned by `rig`."""
    import bpy

    verts, faces, groups = [], [], []
    segs = 8 if per_bone >= 16 else 4
    rings = max(2, per_bone // segs)
    for k, b in enumerate(rig.data.bones):
        head, tail = np.array(b.head_local), np.array(b.tail_local)
        x, z = np.array(b.matrix_local)[:3, 0], np.array(b.matrix_local)[:3, 2]
        r = 0.15 * np.linalg.norm(tail - head) + 1e-3
        start = len(verts)
        for i in range(rings):
            c = head + (tail - head) * i / (rings - 1)
            for a in np.linspace(0, 2 * np.pi, segs, endpoint=False):
                verts.append(c + r * (np.cos(a) * x + np.sin(a) * z))
        for i in range(rings - 1):
            for a in range(segs):
                q = start + i * segs
                faces.append((q + a, q + (a + 1) % segs, q + segs + (a + 1) % segs, q + segs + a))
        groups.append((b.name, range(start, len(verts))))
        del k
    mesh = bpy.data.meshes.new("Body")
    mesh.from_pydata([tuple(v) for v in verts], [], faces)
    body = bpy.data.objects.new("Body", mesh)
    bpy.context.scene.collection.objects.link(body)
    body.parent = rig
    for name, idx in groups:
        body.vertex_groups.new(name=name).add(list(idx), 1.0, "REPLACE")
    body.modifiers.new("Armature", "ARMATURE").object = rig


def write_rig(kind: str, path: Path, motion: Motion, vertices: int = 0, **export: object) -> None:
    """The `kind` rig danced by `motion`, with a skinned mesh of about `vertices` vertices (0: none), exported
    to `path` by Blender's FBX exporter (with its options `export`)."""
    import bpy

    from blender_addon.rig import armature_from_rows

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = round(motion.fps)
    rng = np.random.default_rng(3)
    bones = rows(kind)
    rig = armature_from_rows(bpy.context, "Armature", bones, {b[0]: rng.normal(size=3) for b in bones})
    if kind == "mixamo":
        rig.rotation_euler = (np.pi / 2, 0.0, 0.0)
        rig.scale = (0.01, 0.01, 0.01)
    bpy.context.view_layer.update()
    _keys(rig, motion, kind)
    if vertices:
        _skin(rig, max(8, vertices // len(rig.data.bones)))
    scene.frame_start, scene.frame_end = 1, motion.num_frames
    scene.frame_set(0)  # the exporter writes the bones' nodes as posed now: their rest pose, as other tools do
    bpy.ops.export_scene.fbx(filepath=str(path), use_selection=False, object_types={"ARMATURE", "MESH"},
                             add_leaf_bones=False, bake_anim_use_all_actions=False, bake_anim_use_nla_strips=False,
                             bake_anim_simplify_factor=0.0, **export)


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser()
    p.add_argument("out", type=Path)
    p.add_argument("--seconds", type=float, default=SECONDS)
    p.add_argument("--vertices", type=int, default=600, help="the Mixamo-like rig's skinned mesh")
    p.add_argument("--copies", type=int, default=0, help="only the Mixamo-like rig, this many takes of it")
    args = p.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.copies:
        for k in range(args.copies):
            write_rig("mixamo", args.out / f"mixamo_{k:02d}.fbx", dance(args.seconds, seed=k), args.vertices)
        return 0
    for name, (kind, export) in FILES.items():
        path = args.out / f"{name}.fbx"
        write_rig(kind, path, dance(args.seconds), args.vertices if kind == "mixamo" else 0, **export)
        if name.endswith("_ascii"):
            write_ascii(path, path)
    return 0


def _ascii_values(elem) -> str:
    """An element's values as an ASCII FBX file writes them (binary "Name\\0\\1Class" is "Class::Name")."""
    out = []
    for value, kind in zip(elem.props, elem.props_type, strict=True):
        kind = chr(kind)
        if kind == "S":
            name, _, cls = value.partition(b"\x00\x01")
            text = (cls + b"::" + name if cls else name).decode("utf-8", "replace")
            out.append('"' + text.replace('"', "&quot;") + '"')
        elif kind in "BC":  # a flag
            out.append("N" if value in (False, 0, b"N", b"F", b"\x00") else "Y")
        elif kind in "il":
            out.append(f"*{len(value)} {{\n\ta: " + ",".join(str(int(v)) for v in value) + "\n}")
        elif kind in "fd":
            out.append(f"*{len(value)} {{\n\ta: " + ",".join(repr(float(v)) for v in value) + "\n}")
        elif kind in "DF":
            out.append(repr(float(value)))
        else:
            out.append(str(int(value)))
    return ",".join(out)


def write_ascii(binary: Path, out: Path) -> None:
    """A binary FBX file rewritten as ASCII FBX (as the FBX SDK writes it: `Name: values { children }`; raw
    bytes, which only the header's file id holds, left out), by Blender's own FBX parser."""
    from io_scene_fbx import parse_fbx

    root, version = parse_fbx.parse(str(binary))
    lines = [f"; FBX {version // 1000}.{version % 1000 // 100}.0 project file", ""]

    def emit(elem, depth: int) -> None:
        if b"R"[0] in elem.props_type:
            return
        pad = "\t" * depth
        head = f"{pad}{elem.id.decode()}: {_ascii_values(elem)}"
        if elem.elems or not elem.props:
            lines.append(head + " {")
            for child in elem.elems:
                emit(child, depth + 1)
            lines.append(pad + "}")
        else:
            lines.append(head)

    for elem in root.elems:
        emit(elem, 0)
    out.write_text("\n".join(lines) + "\n")


def written(tmp_path_factory) -> Path:
    """A folder of the `FILES`, written once per test session by Blender's module in a process of its own."""
    if "folder" not in _WRITTEN:
        folder = tmp_path_factory.mktemp("fbx_rigs")
        root = Path(__file__).resolve().parents[1]
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")]))
        subprocess.run([sys.executable, __file__, str(folder)], check=True, env=env, capture_output=True)
        _WRITTEN["folder"] = folder
    return _WRITTEN["folder"]


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

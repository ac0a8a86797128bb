"""An FBX file's armature animation sampled by Blender's Python module (`bpy`, the `blender` extra): the ONE
module of dancenet_core that imports bpy, so it runs only as a process of its own
(`python -m dancenet_core.library.fbx_worker PARENT_PID`, started by `library/fbx.py`; an import-linter contract
keeps every other core module from importing it). The add-on imports its sampling (`sample_armature`,
`import_fbx`) to read FBX files inside Blender the same way.

An ASCII FBX file is rewritten as binary first (`ascii_to_binary`, by Blender's own FBX encoder).

The worker reads jobs from stdin, one JSON object a line (`{"fbx": path, "out": path}`), imports each file into
an empty factory scene, samples its animated armature (`RigSample`: every bone's world rest and per-frame
matrices, in metres) and writes it to `out` (whole or not at all); it answers each job with one JSON line on its
own channel (`{"ok": true}` or `{"error": "one line"}`), and ends at the end of its input or with its parent.
Blender's own prints go to stderr, so they never mix with the answers.
"""

from __future__ import annotations

import json
import math
import os
import re
import sys
import tempfile
from pathlib import Path

import bpy
import numpy as np

from ..environment import end_with_parent
from ..errors import DanceNetError, first_line
from .fbx import RigSample, save_sample


def scene_fps(scene: bpy.types.Scene) -> float:
    return scene.render.fps / scene.render.fps_base


def _matrices(collection: bpy.types.bpy_prop_collection, attr: str) -> np.ndarray:
    """[N, 4, 4] of a matrix property of every item (Blender lays matrices out by column)."""
    buf = np.empty(len(collection) * 16, dtype=np.float32)
    collection.foreach_get(attr, buf)
    return np.swapaxes(buf.reshape(-1, 4, 4), 1, 2).astype(np.float64)


def sample_armature(rig: bpy.types.Object, scene: bpy.types.Scene, frames: range, fps: float) -> RigSample:
    """Every bone of `rig` as Blender evaluates it in `scene` (constraints and drivers included): its world rest
    matrix, head and tail where the object stands at the first frame, and its world matrix at each of `frames`.
    World coordinates are Blender's metres (the scene's own unit scale is taken out); a rig still far from a
    dancer's size after that is put in metres by `RigSample.in_metres`."""
    data = rig.data
    names = [b.name for b in data.bones]
    parents = np.array([names.index(b.parent.name) if b.parent is not None else -1 for b in data.bones])
    order = np.array([rig.pose.bones.find(n) for n in names])
    rest_local = _matrices(data.bones, "matrix_local")
    heads = np.array([tuple(b.head_local) for b in data.bones]).reshape(-1, 3)
    tails = np.array([tuple(b.tail_local) for b in data.bones]).reshape(-1, 3)
    unit = scene.unit_settings.scale_length if scene.unit_settings.system != "NONE" else 1.0
    pose = np.empty((len(frames), len(names), 4, 4))
    world0 = np.eye(4)
    depsgraph = scene.view_layers[0].depsgraph
    for t, frame in enumerate(frames):
        scene.frame_set(frame)
        evaluated = rig.evaluated_get(depsgraph)
        world = np.array(evaluated.matrix_world)
        if t == 0:  # the rest pose where the object stands as the clip starts
            world0 = world
        pose[t] = world @ _matrices(evaluated.pose.bones, "matrix")[order]
    rest = world0 @ rest_local
    heads, tails = heads @ world0[:3, :3].T + world0[:3, 3], tails @ world0[:3, :3].T + world0[:3, 3]
    pose[..., :3, 3] *= unit
    rest[..., :3, 3] *= unit
    return RigSample(names, parents, heads * unit, tails * unit, rest, pose, fps).in_metres()


class ImporterOff(DanceNetError):
    """Blender's FBX importer is not enabled: a fault of this Blender, not of the file, so no file's sample keeps it."""


def import_fbx(path: Path) -> None:
    """`path` imported into the context's scene by Blender's FBX importer (an ASCII file rewritten as binary
    first: the importer reads binary only); a one-line DanceNetError when it cannot be (`ImporterOff` when the
    importer is not enabled)."""
    if not hasattr(bpy.types, "IMPORT_SCENE_OT_fbx"):  # bpy.ops answers any name: its registered class is the test
        raise ImporterOff("Blender's FBX importer is off (Preferences > Add-ons > FBX format)")
    with open(path, "rb") as f:
        head = f.read(1024)
    with tempfile.TemporaryDirectory() as tmp:
        if not head.startswith(b"Kaydara FBX Binary"):
            if b"FBXHeaderExtension" not in head and not head.lstrip().startswith(b"; FBX"):
                raise DanceNetError("not an FBX file (it does not begin as one)")
            binary = Path(tmp) / "binary.fbx"
            try:
                ascii_to_binary(path.read_text(encoding="utf-8", errors="replace"), binary)
            except (ValueError, IndexError, KeyError) as e:
                raise DanceNetError(f"an ASCII FBX file that could not be read ({first_line(e)[:120]})") from e
            path = binary
        try:
            bpy.ops.import_scene.fbx(filepath=str(path))
        except RuntimeError as e:  # an error, or the importer's traceback: its last line says what
            lines = [line.strip() for line in str(e).splitlines() if line.strip()]
            said = [line for line in lines if not line.startswith("Location:")] or lines or ["no reason given"]
            raise DanceNetError(f"Blender could not import it ({said[-1].removeprefix('Error: ')[:160]})") from e


# An ASCII FBX file's values carry no binary type: each is typed as the binary format has it (what the importer
# checks), by its property's type, its element's name, or its own look.
_TOKEN = re.compile(r'\s*(?:;[^\n]*|(?P<key>[A-Za-z_][\w|]*)\s*:|"(?P<str>[^"]*)"|(?P<star>\*\d+)'
                    r"|(?P<num>[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)|(?P<word>[A-Za-z_]\w*)|(?P<punct>[{},]))")
_ARRAY_TYPES = {"KeyTime": "l", "KeyValueFloat": "f", "KeyAttrDataFloat": "f", **dict.fromkeys((
    "PolygonVertexIndex", "Edges", "Materials", "UVIndex", "NormalsIndex", "BinormalsIndex", "TangentsIndex",
    "ColorIndex", "Indexes", "KeyAttrFlags", "KeyAttrRefCount", "Smoothing", "VertexIndexArray"), "i")}
_P_TYPES = {**dict.fromkeys((b"int", b"Integer", b"enum", b"Enum", b"bool", b"Bool", b"Visibility Inheritance"),
                            "I"), **dict.fromkeys((b"KTime", b"ULongLong", b"LongLong"), "L"),
            **dict.fromkeys((b"float", b"Float"), "F")}
_INT64 = {"C", "Node", "LocalTime", "ReferenceTime"}
_DOUBLE = {"Default", "DeformPercent", "Weight"}


def _tokens(text: str) -> list[tuple[str, object]]:
    """(kind, value) of an ASCII FBX file, comments dropped; an array (`*N { a: ... }`) as one ("array", text)."""
    out: list[tuple[str, object]] = []
    pos, end = 0, len(text)
    while pos < end:
        m = _TOKEN.match(text, pos)
        if m is None:
            if text[pos:].strip():
                raise ValueError(f"unreadable text at character {pos}")
            break
        pos = m.end()
        kind = m.lastgroup
        if kind == "star":
            close = text.index("}", pos)
            body = text[text.index("{", pos) + 1:close].strip().removeprefix("a").lstrip().removeprefix(":")
            out.append(("array", body))
            pos = close + 1
        elif kind is not None:
            out.append((kind, m.group(kind)))
    return out


def _typed(elem: object, key: str, values: list[tuple[str, object]], under: str) -> None:
    """`values` added to the binary element `elem` (`encode_bin.FBXElem`) with the types the binary format uses."""
    ptype = values[1][1].encode() if key == "P" and len(values) > 1 else None
    for i, (kind, v) in enumerate(values):
        if kind == "str":
            text = str(v)
            if "::" in text and i < 2 and key != "P":  # an object's "Class::Name" is "Name\0\1Class" in binary
                cls, name = text.split("::", 1)
                elem.add_string(name.encode() + b"\x00\x01" + cls.encode())
            else:
                elem.add_string(text.encode())
        elif kind == "word" and key != "P":  # a flag: Y or T, N or F
            elem.add_char(b"Y" if v in ("Y", "T") else b"N")
        elif kind == "word":
            elem.add_string(str(v).encode())
        elif kind == "array":
            kind_of = _ARRAY_TYPES.get(key, "d")
            numbers = np.array([x for x in str(v).replace("\n", "").split(",") if x.strip()], dtype=np.float64)
            if kind_of == "d":
                elem.add_float64_array(numbers)
            elif kind_of == "f":
                elem.add_float32_array(numbers.astype(np.float32))
            elif kind_of == "l":
                elem.add_int64_array(numbers.astype(np.int64))
            else:
                elem.add_int32_array(numbers.astype(np.int32))
        else:
            text = str(v)
            whole = not any(c in text for c in ".eE")
            if key == "P" and i >= 4:
                kind_of = _P_TYPES.get(ptype, "D")
            elif whole and (key in _INT64 or (under == "Objects" and i == 0) or abs(int(text)) >= 2**31):
                kind_of = "L"
            else:
                kind_of = "I" if whole and key not in _DOUBLE else "D"
            add, number = {"I": (elem.add_int32, int), "L": (elem.add_int64, int), "F": (elem.add_float32, float),
                           "D": (elem.add_float64, float)}[kind_of]
            add(number(float(text)) if number is int and not whole else number(text))


def ascii_to_binary(text: str, out: Path) -> None:
    """An ASCII FBX file's text written to `out` as binary FBX by Blender's own encoder."""
    from io_scene_fbx import encode_bin

    tokens = _tokens(text)
    root = encode_bin.FBXElem(b"")
    stack, names = [root], [""]
    version, i = 7400, 0
    while i < len(tokens):
        kind, value = tokens[i]
        if kind == "punct" and value == "}":
            stack.pop()
            names.pop()
            i += 1
            continue
        if kind != "key":
            raise ValueError(f"a value where a name was expected: {value}")
        key, values, i = str(value), [], i + 1
        while i < len(tokens) and tokens[i][0] not in ("key",) and tokens[i][1] not in ("{", "}"):
            if tokens[i][1] != ",":
                values.append(tokens[i])
            i += 1
        elem = encode_bin.FBXElem(key.encode())
        _typed(elem, key, values, names[-1])
        stack[-1].elems.append(elem)
        if key == "FBXVersion" and values:
            version = int(str(values[0][1]))
        if i < len(tokens) and tokens[i][1] == "{":
            stack.append(elem)
            names.append(key)
            i += 1
    encode_bin.write(str(out), root, version)


def animated_armature(scene: bpy.types.Scene) -> tuple[bpy.types.Object, range]:
    """The armature an imported FBX file animates (the one with most keys, where several are) and the frames
    of its animation; a one-line DanceNetError when there is none."""
    rigs = [o for o in scene.objects if o.type == "ARMATURE"]
    if not rigs:
        raise DanceNetError("no armature in it")
    animated = [o for o in rigs if o.animation_data is not None and o.animation_data.action is not None]
    if not animated:
        raise DanceNetError(f"its armature '{rigs[0].name}' has no animation")
    rig = max(animated, key=lambda o: sum(len(fc.keyframe_points) for fc in _fcurves(o.animation_data.action)))
    first, last = rig.animation_data.action.frame_range
    return rig, range(math.floor(first), math.ceil(last) + 1)


def _fcurves(action: bpy.types.Action) -> list[bpy.types.FCurve]:
    """An action's F-curves, with slots (Blender 4.4 on) or without."""
    if not hasattr(action, "layers"):
        return list(action.fcurves)
    return [fc for layer in action.layers for strip in layer.strips for bag in strip.channelbags
            for fc in bag.fcurves]


def only(rig: bpy.types.Object, scene: bpy.types.Scene) -> None:
    """Everything but `rig` taken out of `scene`, so each frame evaluates the bones alone (a skinned mesh of a
    few thousand vertices would cost more than its armature)."""
    for coll in [scene.collection, *scene.collection.children_recursive]:
        for obj in list(coll.objects):
            if obj != rig:
                coll.objects.unlink(obj)


def sample_file(path: Path) -> RigSample:
    """An FBX file's armature animation, imported into an empty factory scene."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    import_fbx(path)
    rig, frames = animated_armature(scene)
    only(rig, scene)
    return sample_armature(rig, scene, frames, scene_fps(scene))


def main(argv: list[str]) -> int:
    """Jobs from stdin, answers on the process' own stdout; Blender's prints to stderr."""
    end_with_parent(int(argv[0]))
    answers = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    for line in sys.stdin:
        job = json.loads(line)
        try:
            save_sample(Path(job["out"]), sample_file(Path(job["fbx"])))
            answers.write(json.dumps({"ok": True}) + "\n")
        except DanceNetError as e:
            answers.write(json.dumps({"error": first_line(e)}) + "\n")
        except Exception as e:  # the importer's own failures: one line, and on to the next file
            answers.write(json.dumps({"error": f"Blender could not read it ({type(e).__name__}: "
                                               f"{first_line(e)[:160]})"}) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

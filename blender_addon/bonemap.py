"""Bone maps: which armature bone plays which of our 55 joints. Shipped as JSON, editable by users.

A map is {"name": ..., "description": ..., "bones": {"<SMPL-X joint>": "<bone>", ...}}. Joints left out
of a map, and optional joints whose bone the armature lacks, are simply not driven; the joints in
`rigdef.REQUIRED_JOINTS` must resolve or the dance could not read as a dance.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from dancenet_core.errors import DanceNetError
from dancenet_core.skeleton import JOINT_NAMES

from .rigdef import REQUIRED_JOINTS

MAP_DIR = Path(__file__).parent / "bonemaps"
SHIPPED: dict[str, str] = {"SMPLX": "smplx.json", "MIXAMO": "mixamo.json", "RIGIFY": "rigify.json"}


@dataclass
class BoneMap:
    name: str
    bones: dict[str, str]  # joint name -> bone name


def parse(text: str, source: str) -> BoneMap:
    """A BoneMap from JSON text; `source` names it in error messages."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise DanceNetError(f"Bone map {source} is not valid JSON (line {e.lineno}: {e.msg})") from e
    bones = data.get("bones") if isinstance(data, dict) else None
    if not isinstance(bones, dict) or not all(isinstance(v, str) for v in bones.values()):
        raise DanceNetError(f'Bone map {source} needs a "bones" object of joint name -> bone name')
    unknown = sorted(set(bones) - set(JOINT_NAMES))
    if unknown:
        raise DanceNetError(
            f"Bone map {source} has unknown joint names: {', '.join(unknown)} "
            "(use SMPL-X names like 'left_hip')"
        )
    return BoneMap(str(data.get("name", source)), dict(bones))


def load_shipped(key: str) -> BoneMap:
    return parse((MAP_DIR / SHIPPED[key]).read_text(encoding="utf-8"), SHIPPED[key])


def load_file(path: str | Path) -> BoneMap:
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise DanceNetError(f"Cannot read bone map {path}: {e.strerror or e}") from e
    except UnicodeDecodeError as e:
        raise DanceNetError(f"Bone map {path.name} is not UTF-8 text (byte {e.start}): save it as UTF-8 JSON") from e
    return parse(text, path.name)


def _find(wanted: str, bones: set[str], by_local: dict[str, list[str]]) -> str | None:
    """The bone named `wanted`, or the one bone with the same name after any 'namespace:' prefix."""
    if wanted in bones:
        return wanted
    matches = by_local.get(wanted.rsplit(":", 1)[-1], [])
    return matches[0] if len(matches) == 1 else None


def resolve(bone_map: BoneMap, bone_names: Iterable[str], armature: str) -> tuple[dict[str, str], list[str]]:
    """(joint -> existing bone, skipped optional joints) for an armature with `bone_names`.

    Raises DanceNetError naming every required joint the map leaves out or the armature lacks.
    """
    bones = set(bone_names)
    by_local: dict[str, list[str]] = {}
    for b in bones:
        by_local.setdefault(b.rsplit(":", 1)[-1], []).append(b)
    found: dict[str, str] = {}
    skipped: list[str] = []
    for joint, wanted in bone_map.bones.items():
        bone = _find(wanted, bones, by_local)
        if bone is not None:
            found[joint] = bone
        elif joint not in REQUIRED_JOINTS:
            skipped.append(f"{joint} ({wanted})")
    missing = [
        f"{j} ({bone_map.bones[j]!r} not in the armature)" if j in bone_map.bones else f"{j} (not in the map)"
        for j in REQUIRED_JOINTS
        if j not in found
    ]
    if missing:
        raise DanceNetError(
            f"Bone map '{bone_map.name}' does not fit armature '{armature}': missing {', '.join(missing)}. "
            "Pick another map or edit this one (Edit Bone Map)"
        )
    return found, skipped


def detect(bone_names: Iterable[str], armature: str) -> BoneMap:
    """The shipped map that resolves every required joint and the most bones in all, for Auto."""
    names = list(bone_names)
    best: tuple[int, BoneMap] | None = None
    for key in SHIPPED:
        candidate = load_shipped(key)
        try:
            found, _ = resolve(candidate, names, armature)
        except DanceNetError:
            continue
        if best is None or len(found) > best[0]:
            best = (len(found), candidate)
    if best is None:
        raise DanceNetError(
            f"No shipped bone map (SMPL-X, Mixamo, Rigify) fits armature '{armature}'. "
            "Choose one and edit it (Edit Bone Map), or load your own JSON map"
        )
    return best[1]

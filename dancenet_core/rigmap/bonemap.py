"""Bone maps: which armature bone plays which of our 55 joints. Shipped as JSON, editable by users.

A map is {"name": ..., "description": ..., "bones": {"<SMPL-X joint>": "<bone>", ...}}. Joints left out
of a map, and optional joints whose bone the armature lacks, are simply not driven; the joints in
`REQUIRED_JOINTS` and one of `SPINE_JOINTS` must resolve or the dance could not read as a dance
(a spine bone a rig lacks has its turn spread over those it has). Auto goes by names first and
by the skeleton's shape (`shapemap`) for the body joints the names leave out.
"""

from __future__ import annotations

import json
import re
import sys
import unicodedata
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from dancenet_core.errors import DanceNetError, first_line
from dancenet_core.skeleton import JOINT_NAMES

from .shapemap import BODY_JOINTS, RestBone, match_shape

MAP_DIR = Path(__file__).parent / "bonemaps"
SHIPPED: dict[str, str] = {
    "SMPLX": "smplx.json", "MIXAMO": "mixamo.json", "RIGIFY": "rigify.json", "UNREAL": "unreal.json",
    "VRM": "vrm.json", "CC": "cc.json", "DAZ": "daz.json", "MPFB": "mpfb.json", "MMD": "mmd.json",
    "METARIG": "metarig.json", "ROKOKO": "rokoko.json", "XSENS": "xsens.json", "MOTIVE": "motive.json",
    "CMU": "cmu.json", "GENERIC": "generic.json",
}  # fmt: skip

# Joints a bone map must name (and the rig must have) for a dance to read as that dance.
REQUIRED_JOINTS: tuple[str, ...] = (
    "pelvis", "neck", "head",
    "left_hip", "left_knee", "left_ankle", "right_hip", "right_knee", "right_ankle",
    "left_shoulder", "left_elbow", "left_wrist", "right_shoulder", "right_elbow", "right_wrist",
)  # fmt: skip

# The spine between them: a rig needs a bone for one of these at least. Rigs of one family differ in their
# count of spine bones; the dance's turn of those a rig lacks is spread over those it has (the add-on's
# keyframes.retarget; `jointmap.armature_pose` when a clip is read).
SPINE_JOINTS: tuple[str, ...] = ("spine1", "spine2", "spine3")


@dataclass
class BoneMap:
    name: str
    bones: dict[str, str | list[str]]  # joint name -> bone name, or names to try in turn
    by_shape: frozenset[str] = frozenset()  # joints Auto found by the skeleton's shape, not by a name


def name_key(name: str) -> tuple[str, str]:
    """(side "l"/"r"/"", body part) of a bone name, for names that differ only in how they write the side,
    case, width and separators: thigh.L, Thigh_L, LeftThigh, L_Thigh, lThigh (DAZ) all give ("l", "thigh"), and
    MMD's 左足ＩＫ, 足IK.L (MMD Tools' side suffixes) give ("l", "足ik")."""
    local = unicodedata.normalize("NFKC", name.rsplit(":", 1)[-1])
    side, rest = "", local
    if m := re.match(r"^([左右])(.+)$", local):
        side, rest = "l" if m[1] == "左" else "r", m[2]
    elif m := re.match(r"(?i)^(left|right)(.+)$", local):
        side, rest = m[1], m[2]
    elif m := re.match(r"(?i)^(.+?)(left|right)$", local):
        side, rest = m[2], m[1]
    elif m := re.search(r"(?i)(?:^|[._\- ])([lr])(?:[._\- ]|$)", local):
        side, rest = m[1], local[: m.start()] + " " + local[m.end() :]
    elif m := re.match(r"^([lr])([A-Z].*)$", local):
        side, rest = m[1], m[2]
    return side[:1].lower(), re.sub(r"[\W_]", "", rest.lower())


def parse(text: str, source: str) -> BoneMap:
    """A BoneMap from JSON text; `source` names it in error messages."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise DanceNetError(f"Bone map {source} is not valid JSON (line {e.lineno}: {e.msg})") from e
    except (ValueError, RecursionError) as e:  # a number of thousands of digits, lists nested thousands deep
        raise DanceNetError(f"Bone map {source} is JSON no bone map can be ({first_line(e, 80)})") from e
    bones = data.get("bones") if isinstance(data, dict) else None
    if not isinstance(bones, dict) or not all(
        isinstance(v, str) or (isinstance(v, list) and v and all(isinstance(x, str) for x in v)) for v in bones.values()
    ):
        raise DanceNetError(f'Bone map {source} needs a "bones" object of joint name -> bone name (or a list of '
                            "names to try in turn)")
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


def _find(wanted: str | list[str], bones: set[str], by_local: dict[str, list[str]],
          by_key: dict[tuple[str, str], list[str]]) -> str | None:
    """The first of the `wanted` names the armature has: as written, else the one bone with that name after
    any 'namespace:' prefix, else the one bone with the same `name_key` (side and part)."""
    for name in [wanted] if isinstance(wanted, str) else wanted:
        if name in bones:
            return name
        for found in (by_local.get(name.rsplit(":", 1)[-1], []), by_key.get(name_key(name), [])):
            if len(found) == 1:
                return found[0]
    return None


def _shown(wanted: str | list[str]) -> str:
    return repr(wanted) if isinstance(wanted, str) else " or ".join(repr(w) for w in wanted)


def match(bone_map: BoneMap, bone_names: Iterable[str]) -> tuple[dict[str, str], list[str]]:
    """(joint -> existing bone, joints the map names but the armature lacks); never raises (the panel
    draws it as the user edits)."""
    bones = set(bone_names)
    by_local: dict[str, list[str]] = {}
    by_key: dict[tuple[str, str], list[str]] = {}
    for b in bones:
        by_local.setdefault(b.rsplit(":", 1)[-1], []).append(b)
        by_key.setdefault(name_key(b), []).append(b)
    found: dict[str, str] = {}
    unmatched: list[str] = []
    for joint, wanted in bone_map.bones.items():
        bone = _find(wanted, bones, by_local, by_key)
        if bone is not None and bone not in found.values():  # one bone plays one joint
            found[joint] = bone
        else:
            unmatched.append(joint)
    return found, unmatched


def resolve(bone_map: BoneMap, bone_names: Iterable[str], armature: str) -> tuple[dict[str, str], list[str]]:
    """(joint -> existing bone, skipped optional joints) for an armature with `bone_names`.

    Raises DanceNetError naming every required joint the map leaves out or the armature lacks.
    """
    found, unmatched = match(bone_map, bone_names)
    skipped = [f"{j} ({_shown(bone_map.bones[j]).replace(chr(39), '')})" for j in unmatched if j not in REQUIRED_JOINTS]
    missing = [
        f"{j} ({_shown(bone_map.bones[j])} not in the armature)" if j in bone_map.bones else f"{j} (not in the map)"
        for j in REQUIRED_JOINTS
        if j not in found
    ]
    if not any(j in found for j in SPINE_JOINTS):
        missing.append("the spine (no bone for " + ", ".join(
            f"{j} ({_shown(bone_map.bones[j])})" if j in bone_map.bones else j for j in SPINE_JOINTS) + ")")
    if missing:
        raise DanceNetError(
            f"Bone map '{bone_map.name}' does not fit armature '{armature}': missing {', '.join(missing)}. "
            "Pick another map or edit this one (Edit Bone Map)"
        )
    return found, skipped


def user_maps(folder: Path | None) -> list[BoneMap]:
    """The maps a user saved (Save Bone Map) in `folder`, by name. A file that cannot be read as a map, whatever
    the reason, is left out with a one-line notice on the console: one bad file must not break Auto for every
    rig in every file."""
    if folder is None or not folder.is_dir():
        return []
    maps = []
    for path in sorted(folder.glob("*.json")):
        try:
            maps.append(load_file(path))
        except Exception as e:  # whatever a saved file holds, the other maps still work
            print(f"DanceNet: saved bone map {path.name} left out ({first_line(e, 160)})", file=sys.stderr)
    return maps


def closest(bone_names: Iterable[str], saved: Path | None = None) -> BoneMap:
    """The map that finds the most joints on an armature even if it misses required ones: the start for
    fixing a rig no map fits."""
    names = list(bone_names)
    candidates = [*user_maps(saved), *(load_shipped(key) for key in SHIPPED)]
    return max(candidates, key=lambda m: len(match(m, names)[0]))


def detect(bone_names: Iterable[str], armature: str, saved: Path | None = None) -> BoneMap:
    """By names: the map that resolves every required joint and the most bones in all, among the user's
    saved maps in `saved` (first, so they win a tie) and the shipped ones (Auto, `auto_map`, starts from it)."""
    names = list(bone_names)
    best: tuple[int, BoneMap] | None = None
    for candidate in [*user_maps(saved), *(load_shipped(key) for key in SHIPPED)]:
        try:
            found, _ = resolve(candidate, names, armature)
        except DanceNetError:
            continue
        if best is None or len(found) > best[0]:
            best = (len(found), candidate)
    if best is None:
        raise DanceNetError(
            f"No shipped bone map ({', '.join(load_shipped(k).name for k in SHIPPED)}) fits armature '{armature}'. "
            "Choose one and edit it (Edit Bone Map), or load your own JSON map"
        )
    return best[1]


def auto_map(bones: Sequence[RestBone], armature: str, saved: Path | None = None,
             own: BoneMap | None = None) -> BoneMap:
    """For Auto: the map the rig carries (`own`: the VRM add-on's assignments) if it fits, since the user (or the
    importer) said which bone is which; else the name map that fits best (`detect`, else `closest`), with the
    body joints its names leave out found by the skeleton's shape, so a rig whose bone names follow no rule
    still gets a full map."""
    names = [b.name for b in bones]
    if own is not None:
        try:
            resolve(own, names, armature)
            return own
        except DanceNetError:
            pass
    try:
        base = detect(names, armature, saved)
    except DanceNetError:
        base = closest(names, saved)
    found, _ = match(base, names)
    if set(BODY_JOINTS) <= found.keys():
        return base
    shaped = {j: b for j, b in match_shape(bones).items() if j not in found and b not in found.values()}
    if not shaped:
        return base
    if not found:  # no name matched: the base map's names would only be noise in the report
        return BoneMap("Skeleton shape", dict(shaped), frozenset(shaped))
    return BoneMap(f"{base.name} + shape", base.bones | shaped, frozenset(shaped))

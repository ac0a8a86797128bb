"""Takes: each generation's dances as actions on NLA tracks of the rig, with how each was made and its dance kept
on the action (so it can be chosen, listed and continued after the file is saved and opened again)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import bpy

from dancenet_core.errors import DanceNetError, first_line

# Set on the actions the add-on writes, to tell them from a user's own action on the same rig.
ACTION_PROP = "dancenet"
# On each take's action: how it was made (JSON) and its dance at the model's rate, so it can be continued.
TAKE_PROP = "dancenet_take"
MOTION_PROP = "dancenet_motion"


def action_name(song: Path, style: str, seed: int, take: int, takes: int) -> str:
    stem = song.stem if len(song.stem) <= 32 else song.stem[:31] + "…"
    name = f"{stem} · {style} · seed {seed}"
    return f"{name} · take {take}" if takes > 1 else name


# What a take's record holds (written by `pipeline.apply_result`), checked when a file is read back.
_TAKE_FIELDS: dict[str, type | tuple[type, ...]] = {
    "song": str, "style": str, "seed": int, "temperature": (int, float), "footfix": bool, "start_s": (int, float),
    "end_s": (int, float), "root_motion": str, "bone_map": dict, "continues": (str, type(None)),
}


def stored_json(text: Any, kind: type) -> Any:
    """JSON the add-on stored in a .blend, or None when it is unreadable or not a `kind`: a damaged or crafted
    file must not raise out of a panel, a poll or a Generate Dance (the rule for any saved file the add-on reads)."""
    try:
        value = json.loads(text)
    except (TypeError, ValueError, RecursionError):
        return None
    return value if isinstance(value, kind) else None


def take_info(action: bpy.types.Action | None) -> dict[str, Any] | None:
    """How a DanceNet take was made, or None for any other action (a user's, one without the record, or one
    whose record is not what the add-on writes)."""
    if action is None or TAKE_PROP not in action or MOTION_PROP not in action:
        return None
    info = stored_json(action[TAKE_PROP], dict)
    if info is None or not all(isinstance(info.get(k), t) for k, t in _TAKE_FIELDS.items()):
        return None
    names = info["bone_map"].items()
    if not all(isinstance(k, str) and (isinstance(v, str) or (isinstance(v, list) and all(isinstance(x, str)
                                                                                        for x in v)))
               for k, v in names):
        return None
    return info


def store_take(action: bpy.types.Action, motion: Any, info: dict[str, Any]) -> None:
    """Keep the take's dance (float32, ~0.7 MB a minute) and settings on its action, saved with the file."""
    import numpy as np

    action[TAKE_PROP] = json.dumps(info, default=str)  # a library folder (a Path) as its text
    action[MOTION_PROP] = {
        "rotations": motion.rotations.astype(np.float32).ravel(),
        "root": motion.root_positions.astype(np.float32).ravel(),
        "offsets": motion.skeleton.offsets.astype(np.float32).ravel(), "fps": float(motion.fps),
    }  # fmt: skip


def take_motion(action: bpy.types.Action) -> Any:
    """The dance stored on a take (dancenet_core.motion.Motion, at the model's frame rate)."""
    import numpy as np

    from dancenet_core.motion import Motion
    from dancenet_core.skeleton import Skeleton

    try:
        d = action[MOTION_PROP]
        skeleton = Skeleton(np.asarray(d["offsets"], np.float64).reshape(-1, 3))
        rotations = np.asarray(d["rotations"], np.float64).reshape(-1, skeleton.num_joints, 3)
        motion = Motion(rotations, np.asarray(d["root"], np.float64).reshape(-1, 3), float(d["fps"]), skeleton)
        if not (len(motion.root_positions) == motion.num_frames > 0 and np.isfinite(motion.rotations).all()
                and np.isfinite(motion.root_positions).all() and 0 < motion.fps <= 1000):
            raise ValueError("its frames do not fit together")
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise DanceNetError(f"The take {action.name} holds no readable dance ({first_line(e, 80)}): generate it "
                            "again") from e
    return motion


def takes_of(rig_obj: bpy.types.Object) -> list[tuple[bpy.types.NlaTrack, bpy.types.Action]]:
    """The rig's NLA tracks that hold a DanceNet take, bottom to top, with their action (a user's tracks
    are never among them)."""
    anim = rig_obj.animation_data
    if anim is None:
        return []
    found = []
    for track in anim.nla_tracks:
        actions = [strip.action for strip in track.strips]
        if len(actions) == 1 and actions[0] is not None and actions[0].get(ACTION_PROP):
            found.append((track, actions[0]))
    return found


def add_take_track(rig_obj: bpy.types.Object, action: bpy.types.Action) -> None:
    """A new NLA track (on top) holding the take, so every take stays a click away."""
    track = rig_obj.animation_data.nla_tracks.new()
    track.name = action.name[:63]
    strip = track.strips.new(action.name[:63], round(action.frame_range[0]), action)
    if hasattr(strip, "action_slot"):  # layered actions (Blender 4.4+): the slot made for this rig
        strip.action_slot = action.slots[0]


def choose_take(rig_obj: bpy.types.Object, action: bpy.types.Action) -> None:
    """Make `action` the rig's active take: its track plays and is the active action; the other takes'
    tracks are muted. A user's own tracks keep their state."""
    for track, take in takes_of(rig_obj):
        track.mute = take != action
    anim = rig_obj.animation_data
    anim.action = action
    if hasattr(action, "slots"):
        anim.action_slot = action.slots[0]

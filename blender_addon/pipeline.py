"""From the user's settings to a dancing rig: validate, generate (on a worker thread or inline), apply.

Nothing in the scene changes before a result is applied, and only `apply_result` (main thread) touches
bpy data, so a cancelled or failed generation leaves the file exactly as it was; a failure while applying
is undone (`rollback`).
"""

from __future__ import annotations

import json
import threading
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import bpy

from dancenet_core.constants import DEFAULT_TEMPERATURE
from dancenet_core.errors import DanceNetError, first_line

from . import bonemap, rig, rigcontrols, rollback, warming
from .shapemap import RestBone
from .vrmhumanoid import humanoid_map

Generator = Callable[..., Any]  # dancenet_core.generate.generate_dance or a stand-in with its signature

# Markers this add-on owns (replaced on each generation); anything else on the timeline is left alone.
BEAT_MARKER = "·"
# The (name, frame) pairs of the timeline markers the add-on made, as JSON on the scene: only those are
# replaced by the next Generate, never a user's marker that happens to be called "bar 2".
MARKERS_PROP = "dancenet_markers"
# Set on the actions the add-on writes, to tell them from a user's own action on the same rig.
ACTION_PROP = "dancenet"
# On each take's action: how it was made (JSON) and its dance at the model's rate, so it can be continued.
TAKE_PROP = "dancenet_take"
MOTION_PROP = "dancenet_motion"
RIG_NAME = "DanceNet Dancer"
_AUDIO_SUFFIXES = frozenset(".wav .mp3 .ogg .oga .flac .m4a .aac .aif .aiff .opus .wma .mp4 .webm".split())


def load_generator() -> Generator:
    """The core's generate_dance (imported late: it pulls in torch)."""
    from dancenet_core.generate import generate_dance

    return generate_dance


_styles_cache: list[str] = []


def available_styles() -> list[str]:
    """The shipped model's styles, or [] while the model is missing."""
    if not _styles_cache:
        try:
            from dancenet_core.generate import available_styles as core_styles

            _styles_cache.extend(core_styles())
        except (ImportError, DanceNetError, OSError):
            return []
    return list(_styles_cache)


@dataclass
class GenerationRequest:
    """The arguments to generate_dance (no bpy objects: it crosses to the worker thread)."""

    song: Path
    style: str = "auto"
    seed: int = 0
    temperature: float = DEFAULT_TEMPERATURE
    takes: int = 1
    footfix: bool = True
    start_s: float = 0.0  # the part of the song to dance, in the song's own seconds
    end_s: float | None = None
    continue_from: Any = None  # a take's Motion to keep up to `at_s` seconds (Continue From Here)
    at_s: float = 0.0

    def kwargs(self) -> dict[str, Any]:
        extra = {"continue_from": self.continue_from, "at_s": self.at_s} if self.continue_from is not None else {}
        return {
            "song": self.song, "style": self.style, "seed": self.seed, "temperature": self.temperature,
            "takes": self.takes, "footfix": self.footfix, "start_s": self.start_s, "end_s": self.end_s, **extra,
        }  # fmt: skip


@dataclass
class Placement:
    """Where the result goes. Names, not bpy references: those can die while the generator runs."""

    armature: str | None = None  # None: build a new rig
    bone_map: bonemap.BoneMap | None = None  # None with an armature: detect
    strip: str | None = None  # the sound strip playing the song; None: add the song as a new strip
    song_frame: float = 1.0  # where a new strip for the song starts (an existing strip's own place wins)
    add_markers: bool = True
    with_mesh: bool = True
    root_motion: str = "travel"  # dancenet_core.rootmotion.ROOT_MODES
    frame_start: int | None = None  # a continued take starts where the take it continues did
    continues: str | None = None  # the action a continued take grows from


@dataclass
class Plan:
    request: GenerationRequest
    placement: Placement = field(default_factory=Placement)


@dataclass
class Applied:
    """What apply_result made, for the report line and for callers (batch, tests)."""

    rig: str
    actions: list[str]
    frame_start: int
    frame_end: int
    style: str
    notes: list[str] = field(default_factory=list)

    def summary(self) -> str:
        takes = f"{len(self.actions)} takes" if len(self.actions) > 1 else f"action '{self.actions[0]}'"
        text = f"Dance on '{self.rig}' ({self.style}), frames {self.frame_start}-{self.frame_end}, {takes}"
        return "; ".join([text, *self.notes])


def strips_of(scene: bpy.types.Scene) -> bpy.types.bpy_prop_collection:
    """Top-level sequencer strips: `strips` since 4.4 (and only that in 5.0), `sequences` before.

    Tested with hasattr, not truthiness: an empty `strips` collection is falsy.
    """
    editor = scene.sequence_editor
    return editor.strips if hasattr(editor, "strips") else editor.sequences


def check_song(path: str | Path) -> Path:
    """An existing, readable audio file, or a DanceNetError saying what is wrong with it."""
    if not str(path).strip():
        raise DanceNetError("No audio file chosen: pick a song file in the DanceNet panel")
    p = Path(bpy.path.abspath(str(path))).expanduser()
    if p.is_dir():
        raise DanceNetError(f"{p} is a folder, not an audio file: give the path of a song file")
    if not p.is_file():
        raise DanceNetError(f"Audio file not found: {p}")
    if p.suffix.lower() not in _AUDIO_SUFFIXES:
        raise DanceNetError(
            f"{p.name} is not an audio file this add-on reads ({', '.join(sorted(_AUDIO_SUFFIXES))})"
        )
    try:
        with p.open("rb") as f:
            f.read(1)
    except OSError as e:
        raise DanceNetError(f"Cannot read {p}: {e.strerror or e}") from e
    return p


def song_of_strip(strip: bpy.types.Strip) -> Path:
    if strip.type != "SOUND" or strip.sound is None:
        raise DanceNetError(f"The active strip '{strip.name}' is not a sound strip: select the song's strip")
    sound = strip.sound
    if (
        sound.packed_file is not None
        and not Path(bpy.path.abspath(sound.filepath, library=sound.library)).is_file()
    ):
        raise DanceNetError(
            f"The sound of strip '{strip.name}' is packed in the .blend: unpack it (File > External Data) "
            "or choose the song as a file"
        )
    return check_song(bpy.path.abspath(sound.filepath, library=sound.library))


# Which part of the body an optional joint belongs to, for the one-line summary of those a rig lacks.
_JOINT_GROUPS = (("fingers", ("index", "middle", "ring", "pinky", "thumb")), ("face", ("jaw", "eye")),
                 ("spine", ("spine",)), ("collars", ("collar",)), ("toes", ("foot",)))


def missing_summary(skipped: list[str]) -> str:
    """One line for the optional joints a rig lacks (`bonemap.resolve`'s "joint (bones)" entries), so the report
    fits the status bar: "30 optional joints not on this rig (fingers: 30)"; the list is one click away."""
    counts: dict[str, int] = {}
    for entry in skipped:
        joint = entry.split(" ", 1)[0]
        group = next((g for g, marks in _JOINT_GROUPS if any(m in joint for m in marks)), "other")
        counts[group] = counts.get(group, 0) + 1
    groups = ", ".join(f"{g}: {n}" for g, n in sorted(counts.items(), key=lambda gn: -gn[1]))  # most first
    plural = "s" if len(skipped) != 1 else ""
    return f"{len(skipped)} optional joint{plural} not on this rig ({groups})"


def resolve_map(
    rig_obj: bpy.types.Object, bone_map: bonemap.BoneMap | None
) -> tuple[dict[str, str], list[str]]:
    """(joint -> bone, skipped optional joints) for an armature; DanceNetError if the map does not fit."""
    chosen = bone_map or bonemap.auto(rest_bones(rig_obj), rig_obj.name, saved_maps_dir(), humanoid_map(rig_obj.data))
    return bonemap.resolve(chosen, [b.name for b in rig_obj.data.bones], rig_obj.name)


def check_rig(rig_obj: bpy.types.Object) -> None:
    """DanceNetError for a rig that cannot be posed into a dance: its world matrix (its own scale, or a parent's)
    flattens it or is not finite, so no bone's rotation can be solved for."""
    import numpy as np

    turn = np.array(rig_obj.matrix_world)[:3, :3]
    if not np.isfinite(turn).all() or np.linalg.svd(turn, compute_uv=False).min() < 1e-6:
        raise DanceNetError(f"Armature '{rig_obj.name}' has a zero scale ({', '.join(f'{v:g}' for v in rig_obj.scale)}"
                            ", or a parent's flattens it): give it a scale other than 0 (Object Properties > "
                            "Transform), then generate again")


def rest_bones(rig_obj: bpy.types.Object) -> list[RestBone]:
    """The armature's bones at rest in world space (Z up), for mapping by the skeleton's shape."""
    world = rig_obj.matrix_world
    return [RestBone(b.name, b.parent.name if b.parent else None, tuple(world @ b.head_local),
                     tuple(world @ b.tail_local)) for b in rig_obj.data.bones]


def saved_maps_dir() -> Path:
    """Where Save Bone Map puts a user's maps: Blender's user presets, shared by every file."""
    return Path(bpy.utils.user_resource("SCRIPTS", path="presets/dancenet/bonemaps"))


def current_map(props: Any) -> bonemap.BoneMap:
    """The bone map the panel's settings choose for the target armature (Auto: by names and shape, even when
    it does not fit, to start fixing from)."""
    chosen = _chosen_map(props)
    if chosen is not None:
        return chosen
    rig_obj = props.armature
    if rig_obj is None or rig_obj.type != "ARMATURE":
        return bonemap.load_shipped("SMPLX")
    return bonemap.auto(rest_bones(rig_obj), rig_obj.name, saved_maps_dir(), humanoid_map(rig_obj.data))


def prepare(scene: bpy.types.Scene) -> Plan:
    """Validate the scene's DanceNet settings into a Plan; raises DanceNetError for the user to read."""
    props = scene.dancenet
    if props.music_source == "STRIP":
        strip = scene.sequence_editor.active_strip if scene.sequence_editor else None
        if strip is None:
            raise DanceNetError(
                "No active sound strip: select the song's strip in the Sequencer, or choose a file"
            )
        song, strip_name = song_of_strip(strip), strip.name
    else:
        song, strip_name = check_song(props.music_file), None
        strip = strip_playing(scene, song)
    fps = scene.render.fps / scene.render.fps_base
    song_frame = song_zero_frame(strip, fps) if strip is not None else float(scene.frame_start)
    start_s, end_s = part_of_song(scene, strip, song_frame)
    placement = Placement(strip=strip_name, song_frame=song_frame, add_markers=props.add_markers,
                          with_mesh=props.with_mesh, root_motion=props.root_motion)
    if props.target == "EXISTING":
        target = props.armature
        if target is None or target.type != "ARMATURE":
            raise DanceNetError("No target armature: pick one in the DanceNet panel, or choose New Rig")
        placement.armature = target.name
        check_rig(target)
        from . import keyframes  # needs scipy (and the core's FK): loaded on first use

        placement.bone_map = _chosen_map(props)
        hips = resolve_map(target, placement.bone_map)[0]["pelvis"]  # fail now, not after minutes of generation
        if props.root_motion == "root-bone" and keyframes.root_bone_of(target, hips) is None:
            raise DanceNetError(f"Root Bone motion needs a bone above the hips; '{hips}' of '{target.name}' has "
                                "none: choose New Rig (it gets a root bone) or another Root Motion")
    # A style the installed model no longer has reads back as "": fall back to Auto.
    style = props.style or "auto"
    request = GenerationRequest(song, style, props.seed, props.temperature, props.takes, props.footfix,
                                start_s, end_s)
    return Plan(request, placement)


def _chosen_map(props: Any) -> bonemap.BoneMap | None:
    if props.bone_map == "AUTO":
        return None
    if props.bone_map == "FILE":
        return bonemap.load_file(bpy.path.abspath(props.bone_map_file))
    if props.bone_map == "TEXT":
        if props.bone_map_text is None:
            raise DanceNetError("Bone map 'Text' chosen but no text block picked")
        return bonemap.parse(props.bone_map_text.as_string(), f"text '{props.bone_map_text.name}'")
    return bonemap.load_shipped(props.bone_map)


def error_message(error: BaseException) -> str:
    """One line for the user; unexpected errors also go to the console with their traceback."""
    if isinstance(error, DanceNetError):
        return str(error)
    traceback.print_exception(error)
    return f"Generation failed: {type(error).__name__}: {error} (details in the system console)"


class GenerationJob:
    """The generator on a worker thread. The thread never touches bpy; the main thread polls it."""

    def __init__(self, generator: Callable[[], Generator], request: GenerationRequest) -> None:
        self._generator = generator
        self._request = request
        self._lock = threading.Lock()
        self._cancel = threading.Event()
        self._stage, self._fraction = "Starting", 0.0
        self.result: Any = None
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="dancenet-generate", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def _progress(self, stage: str, fraction: float) -> None:
        with self._lock:
            self._stage, self._fraction = stage, min(max(float(fraction), 0.0), 1.0)

    def _run(self) -> None:
        try:
            with warming.LOCK:  # never beside a warm-up step (warming.py)
                self.result = self._generator()(
                    **self._request.kwargs(), progress=self._progress, should_cancel=self._cancel.is_set
                )
        except Exception as e:  # reported on the main thread; a cancelled job's error is dropped
            self.error = e

    def progress(self) -> tuple[str, float]:
        with self._lock:
            return self._stage, self._fraction

    def cancel(self) -> None:
        self._cancel.set()

    @property
    def done(self) -> bool:
        return not self._thread.is_alive()

    def join(self, timeout: float | None = None) -> None:
        self._thread.join(timeout)


def generate_now(context: bpy.types.Context, plan: Plan, generator: Generator) -> Applied:
    """Generate and apply on the calling thread: scripts, background mode, tests."""
    try:
        result = generator(**plan.request.kwargs())
    except DanceNetError:
        raise
    except Exception as e:
        raise DanceNetError(error_message(e)) from e
    return apply_result(context, plan, result)


def _action_name(song: Path, style: str, seed: int, take: int, takes: int) -> str:
    stem = song.stem if len(song.stem) <= 32 else song.stem[:31] + "…"
    name = f"{stem} · {style} · seed {seed}"
    return f"{name} · take {take}" if takes > 1 else name


# What a take's record holds (written by `_apply`), checked when a file is read back.
_TAKE_FIELDS: dict[str, type | tuple[type, ...]] = {
    "song": str, "style": str, "seed": int, "temperature": (int, float), "footfix": bool, "start_s": (int, float),
    "end_s": (int, float), "root_motion": str, "bone_map": dict, "continues": (str, type(None)),
}


def stored_json(text: Any, kind: type) -> Any:
    """JSON the add-on stored in a .blend, or None when it is unreadable or not a `kind`: a damaged or crafted
    file must not raise out of a panel, a poll or a Generate Dance (issue 26: any saved file the add-on reads)."""
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


def _store_take(action: bpy.types.Action, motion: Any, info: dict[str, Any]) -> None:
    """Keep the take's dance (float32, ~0.7 MB a minute) and settings on its action, saved with the file."""
    import numpy as np

    action[TAKE_PROP] = json.dumps(info)
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


def _add_take_track(rig_obj: bpy.types.Object, action: bpy.types.Action) -> None:
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


def prepare_continue(scene: bpy.types.Scene, rig_obj: bpy.types.Object | None) -> Plan:
    """A Plan that keeps the rig's active take up to the current frame and dances the rest with a new seed."""
    action = rig_obj.animation_data.action if rig_obj is not None and rig_obj.animation_data else None
    info = take_info(action)
    if info is None:
        raise DanceNetError("Continue From Here needs a rig whose active action is a DanceNet take: "
                            "generate a dance first")
    song = check_song(info["song"])
    fps = scene.render.fps / scene.render.fps_base
    first, last = (round(f) for f in action.frame_range)
    frame = scene.frame_current
    if not first + 2 <= frame <= last + 1 - fps:  # two kept frames give a velocity; a second left to dance
        raise DanceNetError(f"Put the current frame inside the take, from frame {first + 2} to {last + 1 - round(fps)} "
                            "(the dance is kept before it and danced anew from it)")
    continued = [a for a in bpy.data.actions if (take_info(a) or {}).get("continues") == action.name]
    request = GenerationRequest(song, info["style"], info["seed"] + 1 + len(continued), info["temperature"], 1,
                                info["footfix"], info["start_s"], info["end_s"], take_motion(action),
                                (frame - first) / fps)
    placement = Placement(armature=rig_obj.name, bone_map=bonemap.BoneMap(action.name, info["bone_map"]),
                          add_markers=False, root_motion=info["root_motion"], frame_start=first,
                          continues=action.name)
    return Plan(request, placement)


def strip_playing(scene: bpy.types.Scene, song: Path) -> bpy.types.Strip | None:
    """The sound strip already playing `song` (a second take must not add a second copy), if any."""
    if scene.sequence_editor is None:
        return None
    for s in strips_of(scene):
        if s.type == "SOUND" and s.sound is not None:
            path = Path(bpy.path.abspath(s.sound.filepath, library=s.sound.library))
            if path.is_file() and path.resolve() == song.resolve():
                return s
    return None


def song_zero_frame(strip: bpy.types.Strip, fps: float) -> float:
    """The timeline frame where the song's second 0 would play: Blender plays the sound from
    (frame - frame_start + animation_offset_start) / fps + sound_offset seconds."""
    return strip.frame_start - strip.animation_offset_start - strip.sound_offset * fps


def part_of_song(scene: bpy.types.Scene, strip: bpy.types.Strip | None, song_frame: float,
                 ) -> tuple[float, float | None]:
    """(start, end) seconds of the song to dance: what the strip lets be heard (its trim and place on the
    timeline), within the panel's frames when "Part of the Song" is on. The end is None for a song with
    no strip yet and no chosen end (the whole song)."""
    from dancenet_core.constants import MIN_PART_S

    props = scene.dancenet
    fps = scene.render.fps / scene.render.fps_base
    lo, hi = (strip.frame_final_start, strip.frame_final_end) if strip is not None else (song_frame, None)
    if props.use_part:
        lo, hi = max(lo, props.part_start), min(hi, props.part_end + 1) if hi is not None else props.part_end + 1
    if hi is not None and hi - lo < fps * MIN_PART_S:
        where = f"frames {props.part_start}-{props.part_end}" if props.use_part else f"strip '{strip.name}'"
        raise DanceNetError(f"Less than {MIN_PART_S:g} s of the song is heard in {where}: choose frames "
                            f"where the song plays (it is heard from frame {lo:g})")
    if lo < song_frame:
        raise DanceNetError(f"Frame {lo:g} is before the song starts (frame {song_frame:g}): "
                            "move the part's first frame")
    return (lo - song_frame) / fps, (None if hi is None else (hi - song_frame) / fps)


def _song_strip(scene: bpy.types.Scene, song: Path, frame: int) -> bpy.types.Strip:
    """The sound strip already playing `song`, else a new one starting at `frame`."""
    found = strip_playing(scene, song)
    if found is not None:
        return found
    scene.sequence_editor_create()
    strips = strips_of(scene)
    channel = min(1 + max((s.channel for s in strips), default=0), 128)
    try:
        return strips.new_sound(song.stem, str(song), channel, frame)
    except RuntimeError as e:
        raise DanceNetError(f"Blender cannot play {song.name}: {e}") from e


def _set_markers(scene: bpy.types.Scene, result: Any, frame_start: int, fps: float) -> None:
    stored = stored_json(scene.get(MARKERS_PROP, "[]"), list) or []
    ours = {(m[0], m[1]) for m in stored if isinstance(m, list) and len(m) == 2 and isinstance(m[0], str)
            and isinstance(m[1], int)}
    for marker in [m for m in scene.timeline_markers if (m.name, m.frame) in ours]:
        scene.timeline_markers.remove(marker)
    downbeats = {round(float(t) * fps) for t in result.downbeat_times}
    made = [(f"bar {i}", frame_start + t) for i, t in enumerate(sorted(downbeats), start=1)]
    beats = {round(float(t) * fps) for t in result.beat_times} - downbeats
    made += [(BEAT_MARKER, frame_start + t) for t in sorted(beats)]
    for name, frame in made:
        scene.timeline_markers.new(name, frame=frame)
    scene[MARKERS_PROP] = json.dumps(made)


def _keep_users_action(target: bpy.types.Object) -> str | None:
    """Give the rig's current action a fake user if it is the user's own (not one of ours), so replacing it
    on the rig never loses it on save; returns a note for the report saying where it went."""
    anim = target.animation_data
    action = anim.action if anim is not None else None
    if action is None or action.get(ACTION_PROP):
        return None
    action.use_fake_user = True
    return f"your action '{action.name}' was kept with a fake user (pick it again in the Action Editor)"


def apply_result(context: bpy.types.Context, plan: Plan, result: Any) -> Applied:
    """Put a generation result into the scene: song strip, frame range, markers, rig, one action per take.

    Any failure on the way (one line, DanceNetError) leaves the file as it was: what was added is removed and
    what was changed is set back (`rollback`), whichever step failed.
    """
    target = bpy.data.objects.get(plan.placement.armature) if plan.placement.armature is not None else None
    with rollback.undone_on_failure(context, target):
        try:
            return _apply_result(context, plan, result)
        except DanceNetError as e:
            raise DanceNetError(f"{e}; nothing was changed" if "nothing was changed" not in str(e) else str(e)) from e
        except Exception as e:
            raise DanceNetError(f"{error_message(e)}; nothing was changed") from e


def _apply_result(context: bpy.types.Context, plan: Plan, result: Any) -> Applied:
    """apply_result's steps, unguarded."""
    from . import keyframes  # needs scipy (the core's FK): loaded on first use

    scene = context.scene
    place, req = plan.placement, plan.request
    target = None
    if place.armature is not None:
        target = bpy.data.objects.get(place.armature)
        if target is None or target.type != "ARMATURE":
            raise DanceNetError(f"The armature '{place.armature}' is gone; nothing was changed")
        check_rig(target)  # checked before the dance was made too, but the rig may have changed since
        bone_map, skipped = resolve_map(target, place.bone_map)
    strip = None
    if place.strip is not None:
        strip = strips_of(scene).get(place.strip) if scene.sequence_editor else None
        if strip is None:
            raise DanceNetError(f"The sound strip '{place.strip}' is gone; nothing was changed")

    fps = scene.render.fps / scene.render.fps_base
    if place.frame_start is not None:
        frame_start = place.frame_start
    else:
        if strip is None:
            strip = _song_strip(scene, req.song, round(place.song_frame))
        # The dance starts where the part it was made for is heard (the strip's first audible frame by default).
        frame_start = round(song_zero_frame(strip, fps) + result.start_s * fps)
    notes: list[str] = []
    if target is None:
        target = rig.create_rig(context, RIG_NAME, result.motions[0].skeleton, place.with_mesh,
                                root_bone=place.root_motion == "root-bone")
        bone_map, skipped = {n: n for n in result.motions[0].skeleton.names}, []
        props = getattr(scene, "dancenet", None)
        if props is not None:  # the next Generate adds takes to this rig instead of building another
            props.target, props.armature, props.bone_map = "EXISTING", target, "AUTO"
            notes.append("the next Generate adds a take to this rig")
    elif (controls := rigcontrols.find(target.data.bones.keys(), bone_map)) is not None:
        notes.append(f"keyed {controls.name}'s FK controls (IK/FK switches on FK)")
    else:
        muted = keyframes.mute_overriding_constraints(target, list(bone_map.values()))
        if muted:
            notes.append(f"muted constraints on {len(muted)} bones so the keys show")
    if skipped:
        notes.append(missing_summary(skipped))

    kept = _keep_users_action(target)
    if kept:
        notes.append(kept)
    actions = []
    frames = 0
    for k, motion in enumerate(result.motions, start=1):
        name = _action_name(req.song, result.style, req.seed, k, len(result.motions))
        if place.continues is not None:
            name = f"{name} · from frame {frame_start + round(req.at_s * fps)}"
        action = keyframes.apply_motion(target, motion, bone_map, name, frame_start, fps, place.root_motion)
        action[ACTION_PROP] = True
        _store_take(action, motion, {
            "song": str(req.song), "style": result.style, "seed": req.seed, "temperature": req.temperature,
            "footfix": req.footfix, "start_s": result.start_s, "end_s": result.start_s + result.duration_s,
            "root_motion": place.root_motion, "bone_map": bone_map, "continues": place.continues,
        })  # fmt: skip
        actions.append(action)
        frames = max(frames, round(motion.duration * fps))
    for action in actions:
        _add_take_track(target, action)
    choose_take(target, actions[0])

    scene.frame_start, scene.frame_end = frame_start, frame_start + frames - 1
    scene.frame_set(frame_start)
    scene.sync_mode = "AUDIO_SYNC"  # playback keeps pace with the music
    if place.add_markers:
        _set_markers(scene, result, frame_start, fps)
    props = getattr(scene, "dancenet", None)
    if props is not None:
        props.remember_analysis(req.song, result)
    return Applied(
        target.name, [a.name for a in actions], scene.frame_start, scene.frame_end, result.style, notes
    )

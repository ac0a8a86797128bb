"""The song: the audio file chosen or the sound strip playing it, where on the timeline its second 0 is, and the
part of it that the user lets be heard (a strip's trim, the panel's frames)."""

from __future__ import annotations

from pathlib import Path

import bpy

from dancenet_core.constants import MIN_PART_S
from dancenet_core.errors import DanceNetError

_AUDIO_SUFFIXES = frozenset(".wav .mp3 .ogg .oga .flac .m4a .aac .aif .aiff .opus .wma .mp4 .webm".split())


def scene_fps(scene: bpy.types.Scene) -> float:
    """The scene's true frame rate: `fps` frames per `fps_base` seconds (30000 / 1001 = 29.97)."""
    return scene.render.fps / scene.render.fps_base


def strips_of(scene: bpy.types.Scene) -> bpy.types.bpy_prop_collection:
    """Top-level sequencer strips: `strips` since 4.4 (and only that in 5.0), `sequences` before.

    Tested with hasattr, not truthiness: an empty `strips` collection is falsy.
    """
    editor = scene.sequence_editor
    return editor.strips if hasattr(editor, "strips") else editor.sequences


def readable(text: str) -> str:
    """`text` (a file's name or a line naming one) with each byte that is not UTF-8, kept by Python as a lone
    surrogate, as U+FFFD: Blender's strings, names and reports take UTF-8 only."""
    return text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")


def check_song(path: str | Path) -> Path:
    """An existing, readable audio file, or a DanceNetError saying what is wrong with it."""
    if not str(path).strip():
        raise DanceNetError("No audio file chosen: pick a song file in the DanceNet panel")
    p = Path(bpy.path.abspath(str(path))).expanduser()
    if readable(str(p)) != str(p):
        raise DanceNetError(f"Blender takes only UTF-8 file names: rename '{readable(p.name)}' (or its folder) "
                            "and pick it again")
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
    props = scene.dancenet
    fps = scene_fps(scene)
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


def song_strip(scene: bpy.types.Scene, song: Path, frame: int) -> bpy.types.Strip:
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

"""A Workbench preview video of a dancing rig: a fixed camera framing the whole dance, the song as audio.

Workbench (not EEVEE) because it renders headless on a CPU-only machine at ~0.2 s a frame (640x360,
FXAA), and a preview needs shapes and timing, not lighting. Blender's own FFmpeg output muxes the
Sequencer's sound strip into the MP4.
"""

from __future__ import annotations

import math
from pathlib import Path

import bpy
import numpy as np

from dancenet_core.atomic import atomic_path

CAMERA_NAME = "DanceNet Camera"
FLOOR_NAME = "DanceNet Floor"
_LENS_MM = 35.0


def _pelvis_track(scene: bpy.types.Scene, rig: bpy.types.Object, bone: str, samples: int = 200) -> np.ndarray:
    """World positions of `bone`'s head at up to `samples` frames across the scene range."""
    frames = np.unique(np.linspace(scene.frame_start, scene.frame_end, samples).round().astype(int))
    track = []
    for f in frames:
        scene.frame_set(int(f))
        track.append(np.array(rig.matrix_world @ rig.pose.bones[bone].head))
    scene.frame_set(scene.frame_start)
    return np.array(track)


def _add_floor(scene: bpy.types.Scene, centre: np.ndarray, size: float) -> None:
    mesh = bpy.data.meshes.new(FLOOR_NAME)
    h = size / 2
    mesh.from_pydata([(-h, -h, 0.0), (h, -h, 0.0), (h, h, 0.0), (-h, h, 0.0)], [], [(0, 1, 2, 3)])
    floor = bpy.data.objects.new(FLOOR_NAME, mesh)
    floor.location = (float(centre[0]), float(centre[1]), 0.0)
    scene.collection.objects.link(floor)


def setup_preview(
    scene: bpy.types.Scene,
    rig: bpy.types.Object,
    filepath: str | Path,
    resolution: tuple[int, int] = (640, 360),
    antialias: bool = True,
    root_bone: str = "pelvis",
) -> None:
    """Add a camera and a floor, and set Workbench and MP4 (H.264 + AAC) output to `filepath`."""
    track = _pelvis_track(scene, rig, root_bone)
    lo, hi = track.min(axis=0), track.max(axis=0)
    centre = (lo + hi) / 2
    # Level camera at chest height, in front (-Y): wide enough for the sideways travel plus arm span,
    # tall enough for 2.2 m (raised arms), from in front of the nearest point the dancer reaches.
    width = max(float(hi[0] - lo[0]) + 1.4, 2.2 * resolution[0] / resolution[1])
    distance = width / 2 / math.tan(math.atan(18.0 / _LENS_MM))  # 36 mm sensor width
    camera = bpy.data.objects.new(CAMERA_NAME, bpy.data.cameras.new(CAMERA_NAME))
    camera.data.lens = _LENS_MM
    camera.location = (float(centre[0]), float(lo[1]) - distance, 1.0)
    camera.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    _add_floor(scene, centre, 4.0 * distance)

    if scene.world is None:
        scene.world = bpy.data.worlds.new(CAMERA_NAME)
    scene.world.color = (0.32, 0.36, 0.42)  # Workbench's background: a studio grey-blue, not black
    scene.render.engine = "BLENDER_WORKBENCH"
    shading = scene.display.shading
    shading.light, shading.color_type, shading.show_shadows = "STUDIO", "MATERIAL", True
    scene.display.render_aa = "FXAA" if antialias else "OFF"
    render = scene.render
    render.resolution_x, render.resolution_y = resolution
    render.resolution_percentage = 100
    if hasattr(render.image_settings, "media_type"):  # Blender 5.0 splits video off image formats
        render.image_settings.media_type = "VIDEO"
    render.image_settings.file_format = "FFMPEG"
    render.ffmpeg.format, render.ffmpeg.codec, render.ffmpeg.audio_codec = "MPEG4", "H264", "AAC"
    render.ffmpeg.constant_rate_factor = "MEDIUM"
    render.filepath = str(filepath)


def render_preview(scene: bpy.types.Scene) -> Path:
    """Render the scene's frame range to the output set by `setup_preview`; returns the video's path.
    The video is rendered under a temporary name and renamed into place, so an interrupted render never
    leaves half a video where a good one was."""
    render = scene.render
    chosen = render.filepath
    final = Path(bpy.path.abspath(render.frame_path(frame=scene.frame_start)))
    try:
        with atomic_path(final) as tmp:
            render.filepath = str(tmp)
            with bpy.context.temp_override(scene=scene):
                bpy.ops.render.render(animation=True, scene=scene.name)
            produced = Path(bpy.path.abspath(render.frame_path(frame=scene.frame_start)))
            if produced != tmp:  # Blender added a frame range to the name
                produced.replace(tmp)
    finally:
        render.filepath = chosen
    return final

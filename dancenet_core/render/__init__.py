"""Preview renderer: the dancer as capsules and spheres on a grid floor, drawn off-screen with OpenGL.

pyrender gives the headless OpenGL context, so the command line and CI make previews without Blender; the
drawing itself is a few OpenGL calls of our own with pyrender's shading. By what each module holds:
`gl` chooses the off-screen platform (EGL or OSMesa) and checks the render extra; `camera` the follow camera,
the figure's scale and the floor's height; `geometry` the figure's mesh, the floor and the shadows' texture;
`shaders` the GLSL; `stage` draws one frame; `frames` draws a dance's frames in order (a process pool for long
ones); `stills` writes PNG frames and contact sheets; `video` pipes the frames to ffmpeg with the music.
What callers use is imported here.
"""

from .camera import YFOV, Camera, camera_path, figure_scale, floor_height
from .frames import iter_frames, render_frames
from .geometry import floor_quad
from .gl import gl_platform, pyopengl_compat
from .stage import BACKGROUND_RGB
from .stills import contact_sheet, write_frames
from .video import render_motion

__all__ = [
    "BACKGROUND_RGB", "YFOV", "Camera", "camera_path", "contact_sheet", "figure_scale", "floor_height", "floor_quad",
    "gl_platform", "iter_frames", "pyopengl_compat", "render_frames", "render_motion", "write_frames",
]

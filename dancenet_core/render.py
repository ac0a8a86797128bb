"""Preview renderer: the dancer as capsules and spheres on a grid floor, drawn off-screen with OpenGL.

pyrender gives the headless OpenGL context (EGL, on a GPU or Mesa's llvmpipe; OSMesa where EGL is missing),
so the command line and CI make previews without Blender; the drawing itself is a few OpenGL calls of our
own with pyrender's shading (`_Stage` says why). Frames go raw (rgb24) down a pipe
to ffmpeg, which encodes H.264 and muxes the music from time zero, trimmed or padded to the dance, so
sound and picture start and end together. The camera looks from the front (+Z, where the rest pose
faces) and follows the dancer's low-pass-filtered root, so steps do not shake it.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import importlib.util
import math
import multiprocessing as mp
import os
import shutil
import subprocess
import sys
import tempfile
from collections import deque
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import IO, cast

import numpy as np
from scipy.ndimage import gaussian_filter1d

from .atomic import atomic_path
from .environment import default_workers, end_with_parent
from .errors import DanceNetError, first_line
from .kinematics import fk_numpy
from .motion import Motion
from .progress import Progress
from .skeleton import Skeleton

BACKGROUND_RGB: tuple[int, int, int] = (206, 219, 236)  # the sky above the floor's far edge
YFOV = float(np.radians(40.0))
# Sizes below are in metres for a figure _FIGURE_HEIGHT tall; other skeletons (a BVH in centimetres,
# a child) scale them by their own height.
_FIGURE_HEIGHT = 1.70
_CAMERA_OFFSET = np.array([0.0, 0.6, 4.1])  # eye minus look-at point
_FOLLOW_SIGMA_S = 0.6  # Gaussian low-pass of the root path the camera follows, seconds
_FLOOR_MARGIN = 40.0  # floor beyond the dance's footprint, so its edge sits near the horizon
_FLOOR_TILE = 1.0  # grid spacing
_CHUNK = 256  # frames of forward kinematics at a time, so long dances stay small in memory
_LOD_TOLERANCE_PX = 0.5  # the most a part's facets may stray from its true outline, in pixels
_WORKER_CHUNK = 16  # frames a rendering worker draws per task
_PARALLEL_MIN_FRAMES = 100  # below this, starting worker processes costs more than they save

_FINGER_WORDS = ("thumb", "index", "middle", "ring", "pinky", "finger")
_TORSO_WORDS = ("pelvis", "hip", "spine", "chest", "neck", "collar", "clavicle", "head")
_FOOT_WORDS = ("foot", "toe")
_COLOURS: dict[str, tuple[float, float, float]] = {
    "left": (0.15, 0.40, 0.85),
    "right": (0.92, 0.45, 0.12),
    "centre": (0.30, 0.32, 0.40),
    "head": (0.95, 0.78, 0.62),
    "eye": (0.06, 0.06, 0.08),
}

_PLATFORMS = ("egl", "osmesa")
# Exactly what rendering needs, run in a child process: PyOpenGL picks its platform once, at import,
# and a failed EGL start cannot be undone in the process that tried it.
_PROBE = (
    "from dancenet_core.render import pyopengl_compat\n"
    "pyopengl_compat()\n"
    "import pyrender\n"
    "scene = pyrender.Scene()\n"
    "scene.add(pyrender.PerspectiveCamera(yfov=1.0))\n"
    "renderer = pyrender.OffscreenRenderer(8, 8)\n"
    "renderer.render(scene)\n"
    "renderer.delete()\n"
)


@functools.cache
def gl_platform() -> str:
    """The off-screen OpenGL platform that works here, 'egl' or 'osmesa', set in PYOPENGL_PLATFORM.

    A platform already named in PYOPENGL_PLATFORM is tried first. Each is tried in a child process
    before OpenGL is imported here, because PyOpenGL cannot switch platforms after its first import.
    """
    _check_render_extra()
    wanted = os.environ.get("PYOPENGL_PLATFORM", "")
    if "OpenGL" in sys.modules:
        if wanted in _PLATFORMS:
            return wanted
        raise DanceNetError(
            "OpenGL was loaded before the renderer could choose an off-screen platform; "
            "start again with PYOPENGL_PLATFORM=egl (or osmesa) set"
        )
    order = [wanted] if wanted in _PLATFORMS else []
    order += [p for p in _PLATFORMS if p not in order]
    failures = []
    for platform in order:
        error = _probe(platform)
        if error is None:
            os.environ["PYOPENGL_PLATFORM"] = platform
            return platform
        failures.append(f"{platform}: {error}")
    raise DanceNetError(
        f"no off-screen OpenGL works here ({'; '.join(failures)}); install one (Debian/Ubuntu: apt-get install "
        "libegl1 libgl1-mesa-dri libopengl0 libgl1 libglu1-mesa, or libosmesa6; a checkout lists them in "
        "scripts/apt-packages.txt)"
    )


def pyopengl_compat() -> None:
    """Let PyOpenGL 3.1.0, which pyrender pins and `pip install ".[render]"` therefore installs, take ctypes
    `byref` arguments on Python 3.12+: it looks their type up as builtins.CArgObject, which Python 3.12 renamed
    _ctypes.CArgObject, so pyrender's off-screen contexts failed ("No array-type handler for type _ctypes.type").
    Registers the type under the name it has here, as PyOpenGL 3.1.10 does itself; a no-op where it is known."""
    from OpenGL.plugins import FormatHandler  # imports no platform: safe before the window system is chosen

    byref = type(ctypes.byref(ctypes.c_int()))
    if FormatHandler.match(byref) is None:
        FormatHandler("ctypesparameter", "OpenGL.arrays.ctypesparameters.CtypesParameterHandler",
                      [f"{byref.__module__}.{byref.__name__}"], isOutput=True)


def _check_render_extra() -> None:
    """One line saying what to install when the render extra is missing (a pip install has no
    scripts/apt-packages.txt to point at)."""
    missing = [m for m in ("pyrender", "trimesh", "PIL", "OpenGL") if importlib.util.find_spec(m) is None]
    if missing:
        raise DanceNetError(f"the preview needs the render extra ({', '.join(missing)} missing): "
                            'pip install "dancenet[render]" (from a checkout: ".[render]")')


def _probe(platform: str) -> str | None:
    """None if pyrender renders with `platform` in a child process, else the last line of its error."""
    env = {**os.environ, "PYOPENGL_PLATFORM": platform}
    try:
        proc = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True,
                              timeout=180)
    except subprocess.TimeoutExpired:
        return "timed out"
    if proc.returncode == 0:
        return None
    lines = [line.strip() for line in proc.stderr.splitlines() if line.strip()]
    return lines[-1][:160] if lines else f"exit status {proc.returncode}"


# ------------------------------------------------------------------------------------------- camera


def _look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Camera-to-world pose (OpenGL: the camera looks down its -Z, +Y up) from `eye` towards `target`."""
    z = eye - target
    z = z / np.linalg.norm(z)
    x = np.cross([0.0, 1.0, 0.0], z)
    x = x / np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, np.cross(z, x), z, eye
    return pose


@dataclass(frozen=True, eq=False)
class Camera:
    """A pinhole camera at `eye` looking at `target` (+Y up), exactly as the renderer draws with it."""

    eye: np.ndarray
    target: np.ndarray
    width: int
    height: int
    yfov: float = YFOV

    @property
    def pose(self) -> np.ndarray:
        """Camera-to-world 4x4 (OpenGL convention, as pyrender takes it)."""
        return _look_at(np.asarray(self.eye, float), np.asarray(self.target, float))

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel coordinates [..., 2] (x right, y down; pixel (i, j) covers [i, i+1) x [j, j+1)).

        Points behind the camera come out as NaN.
        """
        pts = np.asarray(points, dtype=np.float64)
        world_to_cam = np.linalg.inv(self.pose)
        cam = pts @ world_to_cam[:3, :3].T + world_to_cam[:3, 3]
        depth = np.where(cam[..., 2] < 0, -cam[..., 2], np.nan)
        f = 1.0 / np.tan(self.yfov / 2)
        ndc_x = f * (self.height / self.width) * cam[..., 0] / depth
        ndc_y = f * cam[..., 1] / depth
        return np.stack([(ndc_x + 1) / 2 * self.width, (1 - ndc_y) / 2 * self.height], axis=-1)


def figure_scale(skeleton: Skeleton) -> float:
    """The skeleton's rest height over a 1.70 m dancer's: sizes figure parts, floor grid and camera."""
    rest = skeleton.rest_positions()
    points = rest
    if skeleton.end_sites:
        points = np.concatenate([rest, rest[skeleton.end_site_parents()] + skeleton.end_site_offsets()])
    return max(float(np.ptp(points[:, 1])), 1e-6) / _FIGURE_HEIGHT


def _fk_chunks(motion: Motion, frames: np.ndarray) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(frame numbers, world positions [n, J, 3], world rotations [n, J, 3, 3]), a chunk at a time."""
    for start in range(0, len(frames), _CHUNK):
        chunk = frames[start:start + _CHUNK]
        pos, rot = fk_numpy(motion.skeleton, motion.rotations[chunk], motion.root_positions[chunk])
        yield chunk, pos, rot


def floor_height(motion: Motion) -> float:
    """Height of the floor: where the lowest point of the body (joints, end sites) mostly is.

    The 5th percentile over frames ignores brief dips below it (a badly fitted frame) and leaps.
    """
    skel = motion.skeleton
    lowest = []
    for _, pos, rot in _fk_chunks(motion, np.arange(motion.num_frames)):
        low = pos[..., 1].min(axis=-1)
        if skel.end_sites:
            parents = skel.end_site_parents()
            ends = pos[:, parents] + np.einsum("teij,ej->tei", rot[:, parents], skel.end_site_offsets())
            low = np.minimum(low, ends[..., 1].min(axis=-1))
        lowest.append(low)
    return float(np.percentile(np.concatenate(lowest), 5))


def camera_path(motion: Motion, width: int, height: int) -> list[Camera]:
    """One camera per frame, looking at the root's path low-pass filtered (zero-phase: no lag, no jitter).

    The camera keeps its direction and distance, so only the dancer's travel (and a slow rise or fall,
    as in a crouching dance) moves the picture; steps and bounces do not.
    """
    unit = figure_scale(motion.skeleton)
    root = motion.root_positions + motion.skeleton.offsets[0]
    targets = gaussian_filter1d(root, sigma=_FOLLOW_SIGMA_S * motion.fps, axis=0, mode="nearest")
    return [Camera(t + _CAMERA_OFFSET * unit, t, width, height) for t in targets]


# ------------------------------------------------------------------------------------------- figure


def _side(name: str) -> str:
    n = name.lower()
    return "left" if n.startswith(("left", "l_")) else "right" if n.startswith(("right", "r_")) else "centre"


def _bone_radius(name: str) -> float:
    """Radius of the bone ending at joint `name`, in metres on a 1.70 m figure."""
    n = name.lower()
    if any(w in n for w in _FINGER_WORDS):
        return 0.009
    if any(w in n for w in _TORSO_WORDS):
        return 0.058
    if "knee" in n or "upleg" in n or "thigh" in n:
        return 0.06
    if any(w in n for w in _FOOT_WORDS):
        return 0.032
    if "wrist" in n or "hand" in n:
        return 0.036
    return 0.046


@dataclass(frozen=True)
class _Figure:
    """The whole figure as one triangle mesh, each vertex fixed in the frame of the joint it moves with.

    One mesh, re-posed with a single gather and matrix product a frame, because pyrender's per-object
    cost (uniforms, lights, a draw call each) is what limits its speed on ~110 capsules and spheres.
    """

    joint: np.ndarray  # [V] the joint each vertex rides on
    vertices: np.ndarray  # [V, 3] in that joint's frame
    normals: np.ndarray  # [V, 3]
    colours: np.ndarray  # [V, 4] linear RGB (the shader multiplies after lighting), alpha 1
    faces: np.ndarray  # [F, 3]

    def posed(self, pos: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World vertices and normals [V, 3] for joint positions [J, 3] and rotations [J, 3, 3]."""
        r = rot[self.joint]
        vertices = np.einsum("vij,vj->vi", r, self.vertices) + pos[self.joint]
        return vertices.astype(np.float32), np.einsum("vij,vj->vi", r, self.normals).astype(np.float32)


def _segments(radius_px: float) -> int:
    """Segments around a circle this many pixels in radius whose chords stay within _LOD_TOLERANCE_PX
    of it (even, 4 to 24)."""
    if radius_px <= _LOD_TOLERANCE_PX:
        return 4
    n = math.ceil(math.pi / math.acos(1.0 - _LOD_TOLERANCE_PX / radius_px))
    return min(max(n + n % 2, 4), 24)


def _build_figure(skeleton: Skeleton, unit: float, px_per_m: float) -> _Figure:
    """Capsules from each joint to its children (and to toe and palm end sites), spheres on the joints,
    a bigger sphere for the head; left side blue, right side orange. Each part is tessellated only as
    finely as its size on screen needs (`px_per_m`, pixels per metre of a 1.70 m figure): llvmpipe's cost
    goes by triangles, and a finger a pixel across needs no 320-face sphere."""
    import trimesh  # the render extra, and 1.4 s to load: only drawing needs it

    @functools.cache
    def sphere(subdivisions: int) -> trimesh.Trimesh:
        return trimesh.creation.icosphere(subdivisions=subdivisions)

    parts: list[tuple[int, np.ndarray, np.ndarray, np.ndarray, str]] = []

    def capsule(parent: int, offset: np.ndarray, radius: float, colour: str) -> None:
        length = float(np.linalg.norm(offset))
        if length > 1e-6 * unit:
            n = _segments(radius * px_per_m)
            mesh = trimesh.creation.capsule(height=length, radius=radius * unit, count=[max(4, n // 2), n])
            align = _align_z(offset)
            parts.append((parent, mesh.vertices @ align.T + offset / 2, mesh.vertex_normals @ align.T,
                          mesh.faces, colour))

    def ball(joint: int, centre: np.ndarray, radius: float, colour: str) -> None:
        # an icosphere's edges span 63.4 degrees, halved by each subdivision: ~5.7 * 2^s segments around
        s = next((s for s in range(3) if 5.7 * 2**s >= _segments(radius * px_per_m)), 3)
        mesh = sphere(s)
        parts.append((joint, centre + mesh.vertices * radius * unit, mesh.vertex_normals, mesh.faces, colour))

    for j, name in enumerate(skeleton.names):
        n = name.lower()
        side = _side(name)
        if "eye" in n:  # eyes and chin poke out of the head sphere and show where the face is
            ball(j, np.zeros(3), 0.018, "eye")
        elif "jaw" in n:
            ball(j, np.zeros(3), 0.03, "head")
        elif skeleton.parents[j] < 0:
            ball(j, np.zeros(3), 0.066, side)
        else:
            radius = _bone_radius(name)
            ball(j, np.zeros(3), 1.12 * radius, side)
            capsule(skeleton.parents[j], skeleton.offsets[j], radius, side)
        if n == "head":
            tops = [np.asarray(s.offset, float) for s in skeleton.end_sites if s.parent == j]
            ball(j, tops[0] / 2 if tops else np.array([0.0, 0.09 * unit, 0.0]), 0.095, "head")
    for site in skeleton.end_sites:  # toes, palms, finger tips; the head's is inside the head sphere
        if "head" not in site.name.lower():
            capsule(site.parent, np.asarray(site.offset, float), min(_bone_radius(site.name), 0.03),
                    _side(skeleton.names[site.parent]))

    starts = np.cumsum([0] + [len(v) for _, v, _, _, _ in parts])
    linear = {k: (*(np.asarray(c) ** 2.2), 1.0) for k, c in _COLOURS.items()}
    colours = np.concatenate([np.tile(linear[c], (len(v), 1)) for _, v, _, _, c in parts])
    return _Figure(
        joint=np.concatenate([np.full(len(v), j) for j, v, _, _, _ in parts]),
        vertices=np.concatenate([v for _, v, _, _, _ in parts]),
        normals=np.concatenate([nrm for _, _, nrm, _, _ in parts]),
        colours=colours.astype(np.float32),
        faces=np.concatenate([f + s0 for (_, _, _, f, _), s0 in zip(parts, starts[:-1], strict=True)]),
    )


def _align_z(v: np.ndarray) -> np.ndarray:
    """A rotation taking +Z to the direction of `v` (capsules are built along Z)."""
    z = v / np.linalg.norm(v)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def _grid_texture(px: int = 256, line: int = 3) -> np.ndarray:
    """One floor tile, grey (sRGB): light with darker lines on its edges."""
    tile = np.full((px, px), 198, np.uint8)
    tile[:line] = tile[-line:] = tile[:, :line] = tile[:, -line:] = 140
    return tile


def _blob_texture(px: int = 64) -> np.ndarray:
    """A soft round shadow's opacity: a Gaussian falling to ~0 at the quad's edge."""
    r2 = np.sum(np.square(np.mgrid[-1:1:px * 1j, -1:1:px * 1j]), axis=0)
    return np.round(255 * np.exp(-r2 / (2 * 0.35**2)) * (r2 < 1)).astype(np.uint8)


def floor_quad(motion: Motion, floor: float) -> tuple[np.ndarray, np.ndarray]:
    """Corners [4, 3] and texture coordinates [4, 2] of a grid floor under the whole dance at height `floor`,
    its texture anchored to the world so the grid stays put."""
    unit = figure_scale(motion.skeleton)
    root = motion.root_positions[:, [0, 2]] + motion.skeleton.offsets[0, [0, 2]]
    lo = root.min(axis=0) - _FLOOR_MARGIN * unit
    hi = root.max(axis=0) + _FLOOR_MARGIN * unit
    xz = np.array([[lo[0], lo[1]], [lo[0], hi[1]], [hi[0], hi[1]], [hi[0], lo[1]]])
    return np.column_stack([xz[:, 0], np.full(4, floor), xz[:, 1]]), xz / (_FLOOR_TILE * unit)


def _perspective(yfov: float, aspect: float, znear: float, zfar: float) -> np.ndarray:
    """OpenGL projection matrix, as pyrender's PerspectiveCamera makes it."""
    t = np.tan(yfov / 2)
    return np.array([[1 / (aspect * t), 0, 0, 0], [0, 1 / t, 0, 0],
                     [0, 0, (zfar + znear) / (znear - zfar), 2 * zfar * znear / (znear - zfar)], [0, 0, -1, 0]])


def _rigid_inverse(pose: np.ndarray) -> np.ndarray:
    """Inverse of a rotation-plus-translation 4x4, without a general (LAPACK) inverse in every frame."""
    inverse = np.eye(4)
    inverse[:3, :3] = pose[:3, :3].T
    inverse[:3, 3] = -pose[:3, :3].T @ pose[:3, 3]
    return inverse


# pyrender's metallic-roughness shading (its shaders/mesh.frag), written out for what the preview draws: dielectrics
# (metallic 0, f0 0.04) under white directional lights plus ambient light. Hand-written for speed: pyrender's
# general shader loops over absent kinds of light and texture in every pixel. Its terms that do not depend on the
# colour are scalars here (colour = base * diffuse + specular); gamma 2.2 out, as pyrender's.
_VERTEX_SHADER = """
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
layout(location = 2) in vec4 colour;
layout(location = 3) in vec2 uv;
uniform mat4 view_projection;
out vec3 frag_position;
out vec3 frag_normal;
out vec4 frag_colour;
out vec2 frag_uv;
void main() {
    gl_Position = view_projection * vec4(position, 1.0);
    frag_position = position;
    frag_normal = normalize(normal);
    frag_colour = colour;
    frag_uv = uv;
}
"""

_FRAGMENT_SHADER = """
in vec3 frag_position;
in vec3 frag_normal;
in vec4 frag_colour;
in vec2 frag_uv;
uniform vec3 cam_pos;
uniform vec3 to_light[N_LIGHTS];
uniform float intensity[N_LIGHTS];
uniform vec3 ambient;
uniform float roughness;
uniform sampler2D tex;
out vec4 out_colour;
const float PI = 3.141592653589793;

vec2 diffuse_specular(vec3 n) {
    vec3 v = normalize(cam_pos - frag_position);
    float nv = clamp(abs(dot(n, v)), 0.001, 1.0);
    float r = roughness + 1.0;
    float k = r * r / 8.0;
    float g1 = nv / (nv * (1.0 - k) + k);
    float a = roughness * roughness;
    float a2 = a * a;
    vec2 sum = vec2(0.0);
    for (int i = 0; i < N_LIGHTS; i++) {
        vec3 l = to_light[i];
        vec3 h = normalize(l + v);
        float nl = clamp(dot(n, l), 0.001, 1.0);
        float nh = clamp(dot(n, h), 0.0, 1.0);
        float vh = clamp(dot(v, h), 0.0, 1.0);
        float c = clamp(1.0 - vh, 0.0, 1.0);
        float f = 0.04 + 0.96 * (c * c) * (c * c) * c;
        float g = g1 * nl / (nl * (1.0 - k) + k);
        float d = nh * nh * (a2 - 1.0) + 1.0;
        d = a2 / (PI * d * d);
        sum += nl * intensity[i] * vec2((1.0 - f) * 0.96 / PI, f * g * d / (4.0 * nl * nv + 0.001));
    }
    return sum;
}

void main() {
#if defined(SHADOW)
    out_colour = vec4(0.0, 0.0, 0.0, frag_colour.a * texture(tex, frag_uv).r);
#else
#if defined(FLOOR)  // the grid's sRGB grey, made linear, on a floor facing up
    float s = texture(tex, frag_uv).r;
    vec3 base = vec3(s < 0.04045 ? s / 12.92 : pow((s + 0.055) / 1.055, 2.4));
    vec4 multiplier = vec4(1.0);
    vec2 ds = diffuse_specular(vec3(0.0, 1.0, 0.0));
#else  // white, times the vertex colour after lighting
    vec3 base = vec3(1.0);
    vec4 multiplier = frag_colour;
    vec2 ds = diffuse_specular(normalize(frag_normal));
#endif
    vec3 colour = (base * ds.x + ds.y + base * ambient) * multiplier.rgb;
    out_colour = clamp(vec4(pow(colour, vec3(1.0 / 2.2)), multiplier.a), 0.0, 1.0);
#endif
}
"""


class _Stage:
    """One dance drawn off-screen: the figure, re-posed each frame, on a grid floor under soft shadows, lit
    as pyrender lights it (4x multisampled, as pyrender draws), read back as RGB.

    Raw OpenGL on pyrender's off-screen context, not a pyrender scene: for every frame pyrender re-uploads
    each mesh, looks up every uniform, runs its general shader (loops over absent lights and textures, an
    sRGB decode of each texture channel) and reads back depth, and on Mesa's software rasteriser that was
    most of a frame. Here the meshes stay in GPU buffers (only the figure's and shadows' vertices change),
    and a frame is three draw calls.
    """

    # (direction the light shines, intensity), white; ambient light
    _LIGHTS = (((-0.35, -1.0, -0.55), 2.6), ((0.8, -0.45, -0.3), 1.1))
    _AMBIENT = (0.32, 0.32, 0.34)

    def __init__(self, motion: Motion, width: int, height: int, floor: float) -> None:
        pyopengl_compat()
        import pyrender  # the render extra; it loads OpenGL, which must wait until a window system is chosen
        from OpenGL import GL

        self.gl = gl = GL
        skel = motion.skeleton
        self.size = (width, height)
        self.floor = floor
        self.unit = unit = figure_scale(skel)
        # pixels per metre (of a 1.70 m figure) at the follow camera's distance
        px_per_m = height / (2 * np.tan(YFOV / 2) * float(np.linalg.norm(_CAMERA_OFFSET)))
        self.figure = _build_figure(skel, unit, px_per_m)
        self.projection = _perspective(YFOV, width / height, 0.05 * unit, 4 * _FLOOR_MARGIN * unit)
        try:
            self.context = pyrender.OffscreenRenderer(width, height)  # used for its EGL or OSMesa context only
        except Exception as e:  # pyrender raises bare RuntimeError/ValueError/ctypes errors
            raise DanceNetError(
                f"cannot start off-screen OpenGL ({os.environ.get('PYOPENGL_PLATFORM')}): {e}"
            ) from e
        self._framebuffers(width, height)
        lights = np.array([-np.asarray(d) / np.linalg.norm(d) for d, _ in self._LIGHTS], np.float32)
        intensities = np.array([i for _, i in self._LIGHTS], np.float32)
        self.programs: dict[str, tuple[int, int, int]] = {}
        for kind, roughness in (("FIGURE", 0.55), ("FLOOR", 1.0), ("SHADOW", 1.0)):
            program = self._program(kind, len(self._LIGHTS))
            gl.glUseProgram(program)
            gl.glUniform3fv(gl.glGetUniformLocation(program, "to_light"), len(lights), lights)
            gl.glUniform1fv(gl.glGetUniformLocation(program, "intensity"), len(lights), intensities)
            gl.glUniform3f(gl.glGetUniformLocation(program, "ambient"), *self._AMBIENT)
            gl.glUniform1f(gl.glGetUniformLocation(program, "roughness"), roughness)
            gl.glUniform1i(gl.glGetUniformLocation(program, "tex"), 0)
            self.programs[kind] = (program, gl.glGetUniformLocation(program, "view_projection"),
                                   gl.glGetUniformLocation(program, "cam_pos"))
        fig = self.figure
        self.figure_mesh = self._mesh(fig.faces, {0: fig.vertices, 1: fig.normals, 2: fig.colours})
        corners, uv = floor_quad(motion, floor)
        self.floor_mesh = self._mesh(np.array([[0, 1, 2], [0, 2, 3]]), {0: corners, 3: uv})  # normal: +Y
        self._init_shadows(skel)
        self.floor_texture = self._texture(_grid_texture())
        self.shadow_texture = self._texture(_blob_texture())

    def _program(self, kind: str, lights: int) -> int:
        from OpenGL.GL import shaders

        gl = self.gl
        header = f"#version 330 core\n#define {kind}\n#define N_LIGHTS {lights}\n"
        return shaders.compileProgram(
            shaders.compileShader(header + _VERTEX_SHADER, gl.GL_VERTEX_SHADER),
            shaders.compileShader(header + _FRAGMENT_SHADER, gl.GL_FRAGMENT_SHADER),
            validate=False)  # validation wants a vertex array bound, which comes later

    def _framebuffers(self, width: int, height: int) -> None:
        """4x multisampled colour and depth to draw into, and plain colour to resolve them into and read."""
        gl = self.gl
        self.fb_multi, self.fb_resolved = gl.glGenFramebuffers(2)
        colour_multi, depth_multi, colour = gl.glGenRenderbuffers(3)
        for fb, buffer, attachment, fmt, samples in (
                (self.fb_multi, colour_multi, gl.GL_COLOR_ATTACHMENT0, gl.GL_RGBA8, 4),
                (self.fb_multi, depth_multi, gl.GL_DEPTH_ATTACHMENT, gl.GL_DEPTH_COMPONENT24, 4),
                (self.fb_resolved, colour, gl.GL_COLOR_ATTACHMENT0, gl.GL_RGBA8, 0)):
            gl.glBindRenderbuffer(gl.GL_RENDERBUFFER, buffer)
            gl.glRenderbufferStorageMultisample(gl.GL_RENDERBUFFER, samples, fmt, width, height)
            gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, fb)
            gl.glFramebufferRenderbuffer(gl.GL_FRAMEBUFFER, attachment, gl.GL_RENDERBUFFER, buffer)
        gl.glViewport(0, 0, width, height)
        gl.glEnable(gl.GL_DEPTH_TEST)
        gl.glDepthFunc(gl.GL_LESS)
        gl.glEnable(gl.GL_CULL_FACE)
        gl.glEnable(gl.GL_MULTISAMPLE)
        gl.glBlendFunc(gl.GL_SRC_ALPHA, gl.GL_ONE_MINUS_SRC_ALPHA)
        gl.glPixelStorei(gl.GL_PACK_ALIGNMENT, 1)
        gl.glPixelStorei(gl.GL_UNPACK_ALIGNMENT, 1)

    def _mesh(self, faces: np.ndarray, attributes: dict[int, np.ndarray]) -> tuple[int, int, dict[int, int]]:
        """(vertex array, index count, {attribute location: its buffer}) for float vertex attributes
        (0 position, 1 normal, 2 colour, 3 texture coordinates) and triangles."""
        gl = self.gl
        vao = gl.glGenVertexArrays(1)
        gl.glBindVertexArray(vao)
        buffers = {}
        for location, values in attributes.items():
            data = np.ascontiguousarray(values, np.float32)
            buffers[location] = gl.glGenBuffers(1)
            gl.glBindBuffer(gl.GL_ARRAY_BUFFER, buffers[location])
            gl.glBufferData(gl.GL_ARRAY_BUFFER, data.nbytes, data, gl.GL_DYNAMIC_DRAW)
            gl.glEnableVertexAttribArray(location)
            gl.glVertexAttribPointer(location, data.shape[1], gl.GL_FLOAT, False, 0, None)
        indices = np.ascontiguousarray(faces, np.uint32)
        gl.glBindBuffer(gl.GL_ELEMENT_ARRAY_BUFFER, gl.glGenBuffers(1))
        gl.glBufferData(gl.GL_ELEMENT_ARRAY_BUFFER, indices.nbytes, indices, gl.GL_STATIC_DRAW)
        gl.glBindVertexArray(0)
        return vao, indices.size, buffers

    def _texture(self, image: np.ndarray) -> int:
        """A one-channel texture with mipmaps, sampled as pyrender samples its textures (trilinear, repeating)."""
        gl = self.gl
        texture = gl.glGenTextures(1)
        gl.glBindTexture(gl.GL_TEXTURE_2D, texture)
        height, width = image.shape
        gl.glTexImage2D(gl.GL_TEXTURE_2D, 0, gl.GL_R8, width, height, 0, gl.GL_RED, gl.GL_UNSIGNED_BYTE,
                        np.ascontiguousarray(image[::-1]))  # first row at the top, as pyrender uploads images
        gl.glGenerateMipmap(gl.GL_TEXTURE_2D)
        for name, value in ((gl.GL_TEXTURE_MAG_FILTER, gl.GL_LINEAR),
                            (gl.GL_TEXTURE_MIN_FILTER, gl.GL_LINEAR_MIPMAP_LINEAR),
                            (gl.GL_TEXTURE_WRAP_S, gl.GL_REPEAT), (gl.GL_TEXTURE_WRAP_T, gl.GL_REPEAT)):
            gl.glTexParameteri(gl.GL_TEXTURE_2D, name, value)
        return texture

    def _init_shadows(self, skel: Skeleton) -> None:
        """Soft dark discs under the feet and the body, placed per frame: they fade and spread as they rise."""
        feet = [j for j, n in enumerate(skel.names) if any(w in n.lower() for w in ("ankle", *_FOOT_WORDS))]
        self.shadow_joints = np.array([0, *feet], dtype=int)
        self.shadow_size = np.array([0.45] + [0.14] * len(feet)) * self.unit
        self.shadow_alpha = np.array([0.5] + [0.6] * len(feet))
        self.shadow_fade = np.array([4.0] + [0.5] * len(feet)) * self.unit  # height where it is gone
        n = len(self.shadow_joints)
        quad = np.array([[-1.0, 0.0, -1.0], [-1.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 0.0, -1.0]])
        self.shadow_corners = np.tile(quad, (n, 1))
        faces = (np.array([[0, 1, 2], [0, 2, 3]]) + 4 * np.arange(n)[:, None, None]).reshape(-1, 3)
        self.shadow_mesh = self._mesh(faces, {0: self.shadow_corners, 2: np.zeros((4 * n, 4)),
                                              3: (self.shadow_corners[:, [0, 2]] + 1) / 2})

    def shadow_quads(self, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The shadows' corners [4n, 3] and opacity [4n] for joint positions [J, 3]."""
        feet = pos[self.shadow_joints]
        heights = np.maximum(feet[:, 1] - self.floor, 0.0)
        alpha = self.shadow_alpha * np.clip(1.0 - heights / self.shadow_fade, 0.0, 1.0) ** 2
        size = self.shadow_size * (1.0 + heights / self.unit)
        # each disc a hair above the one before, so overlapping discs never fight over depth
        centres = np.column_stack([feet[:, 0], self.floor + (1 + np.arange(len(feet))) * 5e-4 * self.unit,
                                   feet[:, 2]])
        return np.repeat(centres, 4, axis=0) + self.shadow_corners * np.repeat(size, 4)[:, None], np.repeat(alpha, 4)

    def _update(self, mesh: tuple[int, int, dict[int, int]], location: int, values: np.ndarray) -> None:
        gl = self.gl
        data = np.ascontiguousarray(values, np.float32)
        gl.glBindBuffer(gl.GL_ARRAY_BUFFER, mesh[2][location])
        gl.glBufferSubData(gl.GL_ARRAY_BUFFER, 0, data.nbytes, data)

    def _draw(self, kind: str, mesh: tuple[int, int, dict[int, int]], view_projection: np.ndarray,
              eye: np.ndarray) -> None:
        gl = self.gl
        program, view_projection_at, eye_at = self.programs[kind]
        gl.glUseProgram(program)
        gl.glUniformMatrix4fv(view_projection_at, 1, gl.GL_TRUE, view_projection)
        gl.glUniform3f(eye_at, *eye)
        gl.glBindVertexArray(mesh[0])
        gl.glDrawElements(gl.GL_TRIANGLES, mesh[1], gl.GL_UNSIGNED_INT, None)

    def render(self, pos: np.ndarray, rot: np.ndarray, camera: Camera) -> np.ndarray:
        """One frame [H, W, 3] uint8 of the pose given by world positions [J, 3] and rotations [J, 3, 3]."""
        gl = self.gl
        self.context._platform.make_current()  # pyrender 0.1.45 (pinned, its last release) keeps it there
        vertices, normals = self.figure.posed(pos, rot)
        self._update(self.figure_mesh, 0, vertices)
        self._update(self.figure_mesh, 1, normals)
        corners, alpha = self.shadow_quads(pos)
        self._update(self.shadow_mesh, 0, corners)
        colours = np.zeros((len(alpha), 4))
        colours[:, 3] = alpha
        self._update(self.shadow_mesh, 2, colours)

        pose = camera.pose
        view_projection = (self.projection @ _rigid_inverse(pose)).astype(np.float32)
        eye = pose[:3, 3]
        gl.glBindFramebuffer(gl.GL_DRAW_FRAMEBUFFER, self.fb_multi)
        gl.glClearColor(*(c / 255 for c in BACKGROUND_RGB), 1.0)
        gl.glClear(gl.GL_COLOR_BUFFER_BIT | gl.GL_DEPTH_BUFFER_BIT)
        self._draw("FIGURE", self.figure_mesh, view_projection, eye)  # first: the floor behind it is not shaded
        gl.glBindTexture(gl.GL_TEXTURE_2D, self.floor_texture)
        self._draw("FLOOR", self.floor_mesh, view_projection, eye)
        gl.glBindTexture(gl.GL_TEXTURE_2D, self.shadow_texture)
        gl.glEnable(gl.GL_BLEND)
        self._draw("SHADOW", self.shadow_mesh, view_projection, eye)
        gl.glDisable(gl.GL_BLEND)
        width, height = self.size
        gl.glBindFramebuffer(gl.GL_READ_FRAMEBUFFER, self.fb_multi)
        gl.glBindFramebuffer(gl.GL_DRAW_FRAMEBUFFER, self.fb_resolved)
        gl.glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, gl.GL_COLOR_BUFFER_BIT, gl.GL_NEAREST)
        gl.glBindFramebuffer(gl.GL_READ_FRAMEBUFFER, self.fb_resolved)
        image = np.empty((height, width, 3), np.uint8)
        gl.glReadPixels(0, 0, width, height, gl.GL_RGB, gl.GL_UNSIGNED_BYTE, image)
        return image[::-1]  # OpenGL's first row is the bottom one

    def close(self) -> None:
        self.context.delete()  # the context, and with it every buffer, texture and program here


# ------------------------------------------------------------------------------------------- frames


def _check_size(width: int, height: int) -> None:
    if width < 16 or height < 16 or width > 8192 or height > 8192:
        raise DanceNetError(f"image size {width}x{height} is out of range; use 16 to 8192 pixels a side")


def iter_frames(
    motion: Motion,
    frame_indices: Sequence[int] | np.ndarray | None = None,
    width: int = 640,
    height: int = 360,
    cameras: Sequence[Camera] | None = None,
    workers: int | None = None,
) -> Iterator[np.ndarray]:
    """Rendered frames [H, W, 3] uint8, one at a time and in order (all frames by default).

    `cameras` gives one camera per frame of the motion; by default `camera_path` (follows the dancer).
    From _PARALLEL_MIN_FRAMES frames on, `workers` processes (default: $DANCENET_WORKERS, else up to 2;
    1 inside Blender) draw chunks of frames side by side, each with its own OpenGL context.
    """
    _check_size(width, height)
    frames = np.arange(motion.num_frames) if frame_indices is None else np.asarray(frame_indices, dtype=int)
    if frames.size and (frames.min() < 0 or frames.max() >= motion.num_frames):
        raise DanceNetError(f"frame numbers must be in 0..{motion.num_frames - 1}")
    gl_platform()
    floor = floor_height(motion)
    cams = camera_path(motion, width, height) if cameras is None else list(cameras)
    if len(cams) != motion.num_frames:
        raise ValueError(f"need one camera per frame ({motion.num_frames}), got {len(cams)}")
    workers = default_workers() if workers is None else workers
    if workers > 1 and len(frames) >= _PARALLEL_MIN_FRAMES:
        yield from _iter_parallel(motion, frames, width, height, floor, cams, workers)
        return
    stage = _Stage(motion, width, height, floor)
    try:
        for chunk, pos, rot in _fk_chunks(motion, frames):
            for k, f in enumerate(chunk):
                yield stage.render(pos[k], rot[k], cams[f])
    finally:
        stage.close()


def _iter_parallel(motion: Motion, frames: np.ndarray, width: int, height: int, floor: float,
                   cams: list[Camera], workers: int) -> Iterator[np.ndarray]:
    """Chunks of frames drawn by worker processes, yielded in order. At most two chunks a worker are in
    flight, so memory stays bounded whatever the dance's length. Workers are forked (no start-up cost)
    while this process holds no OpenGL state, else spawned, since a forked copy of loaded Mesa state is not
    safe to draw with (spawning needs the usual `if __name__ == "__main__"` guard in a calling script)."""
    chunks = [frames[i:i + _WORKER_CHUNK] for i in range(0, len(frames), _WORKER_CHUNK)]
    pending: deque[Future] = deque()
    method = "fork" if "OpenGL" not in sys.modules and "fork" in mp.get_all_start_methods() else "spawn"
    with ProcessPoolExecutor(workers, mp_context=mp.get_context(method), initializer=_worker_start,
                             initargs=(os.getpid(), motion, width, height, floor, cams)) as pool:
        try:
            for chunk in chunks:
                pending.append(pool.submit(_worker_draw, chunk))
                if len(pending) >= 2 * workers:
                    yield from pending.popleft().result()
            while pending:
                yield from pending.popleft().result()
        finally:
            for fut in pending:
                fut.cancel()


_worker_state: dict = {}


def _worker_start(parent: int, motion: Motion, width: int, height: int, floor: float, cams: list[Camera]) -> None:
    """Keep a rendering worker's dance, ending with `parent` however it ends; with Mesa's software rasteriser,
    one thread each (the workers already fill the cores). The stage is built on the first chunk, so its errors
    reach the caller."""
    end_with_parent(parent)
    os.environ.setdefault("LP_NUM_THREADS", "1")
    _worker_state.update(motion=motion, size=(width, height), floor=floor, cams=cams)


def _worker_draw(chunk: np.ndarray) -> np.ndarray:
    """Frames [n, H, W, 3] of one chunk of frame numbers. Any error comes back as its one-line text: PyOpenGL's
    errors carry ctypes arguments that cannot be pickled, which hid the real cause behind `cannot pickle
    '_ctypes.CArgObject'` (issue 26 item 14)."""
    st = _worker_state
    try:
        if "stage" not in st:
            st["stage"] = _Stage(st["motion"], *st["size"], st["floor"])
        motion = st["motion"]
        pos, rot = fk_numpy(motion.skeleton, motion.rotations[chunk], motion.root_positions[chunk])
        return np.stack([st["stage"].render(pos[k], rot[k], st["cams"][f]) for k, f in enumerate(chunk)])
    except Exception as e:
        raise RuntimeError(f"the preview's renderer failed: {type(e).__name__}: {first_line(e)}") from None


def render_frames(
    motion: Motion,
    frame_indices: Sequence[int] | np.ndarray,
    width: int = 640,
    height: int = 360,
    cameras: Sequence[Camera] | None = None,
) -> list[np.ndarray]:
    """The given frames [H, W, 3] uint8, seen by `camera_path`'s cameras unless `cameras` are given."""
    return list(iter_frames(motion, frame_indices, width, height, cameras))


def _save_png(image: np.ndarray, path: Path) -> None:
    from PIL import Image  # Pillow comes with the render extra

    with atomic_path(path) as tmp:  # a killed run never leaves half a PNG
        Image.fromarray(image).save(tmp, compress_level=1)


def _make_dir(folder: Path) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise DanceNetError(f"cannot create the folder {folder}: {e.strerror}") from e


def write_frames(
    motion: Motion, folder: str | Path, width: int = 640, height: int = 360, progress: Progress | None = None
) -> list[Path]:
    """Every frame as `frame_00000.png`, ... in `folder` (created if missing)."""
    folder = Path(folder)
    _make_dir(folder)
    paths = []
    for i, image in enumerate(iter_frames(motion, None, width, height)):
        paths.append(folder / f"frame_{i:05d}.png")
        _save_png(image, paths[-1])
        if progress:
            progress((i + 1) / motion.num_frames)
    return paths


def contact_sheet(
    motion: Motion | Sequence[tuple[str, Motion]], out: str | Path, cols: int = 4, rows: int = 3,
    width: int = 320, height: int = 180,
) -> Path:
    """A PNG grid of `cols` x `rows` evenly spaced frames, each `width` x `height`, with its time stamp.

    Given (caption, motion) pairs instead, each motion gets its own block of `rows` rows, one under the other,
    with its caption on every cell: the same moments of a real and a generated dance, compared by eye.
    """
    from PIL import Image, ImageDraw, ImageFont  # Pillow comes with the render extra

    if cols < 1 or rows < 1:
        raise DanceNetError(f"a contact sheet needs at least 1x1 cells, got {cols}x{rows}")
    out = Path(out)
    blocks = [("", motion)] if isinstance(motion, Motion) else list(motion)
    sheet = Image.new("RGB", (cols * width, len(blocks) * rows * height))
    draw = ImageDraw.Draw(sheet)
    font = ImageFont.load_default(size=max(10, height // 12))
    for b, (caption, m) in enumerate(blocks):
        frames = np.linspace(0, m.num_frames - 1, cols * rows).round().astype(int)
        for k, (f, image) in enumerate(zip(frames, iter_frames(m, frames, width, height), strict=True)):
            x, y = (k % cols) * width, (b * rows + k // cols) * height
            sheet.paste(Image.fromarray(image), (x, y))
            t = f / m.fps
            label = f"{caption}  {int(t // 60)}:{t % 60:05.2f}".strip() if caption else \
                f"{int(t // 60)}:{t % 60:05.2f}  #{f}"
            box = draw.textbbox((x + 6, y + 4), label, font=font)
            draw.rectangle((box[0] - 4, box[1] - 3, box[2] + 4, box[3] + 3), fill=(20, 20, 24))
            draw.text((x + 6, y + 4), label, fill=(255, 255, 255), font=font)
            draw.rectangle((x, y, x + width - 1, y + height - 1), outline=(60, 60, 66))
    if out.parent != Path():
        _make_dir(out.parent)
    try:
        with atomic_path(out) as tmp:
            sheet.save(tmp)
    except ValueError as e:
        raise DanceNetError(f"cannot write the contact sheet {out}: {e}") from e
    return out


# -------------------------------------------------------------------------------------------- video


def _tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        raise DanceNetError(f"{name} not found; install it (Debian: apt-get install ffmpeg)")
    return path


def _check_audio(audio: Path) -> None:
    """Fail before rendering, not after, when the music is missing or holds no sound."""
    if not audio.is_file():
        raise DanceNetError(f"audio file not found: {audio}")
    proc = subprocess.run(
        [_tool("ffprobe"), "-v", "error", "-select_streams", "a:0", "-show_entries", "stream=codec_type",
         "-of", "csv=p=0", str(audio)], capture_output=True, text=True)
    if "audio" not in proc.stdout:
        raise DanceNetError(f"{audio} holds no audio that ffmpeg can read")


def _last_line(text: str) -> str:
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[-1] if lines else "no message"


def render_motion(
    motion: Motion,
    out: str | Path,
    audio: str | Path | None = None,
    width: int = 640,
    height: int = 360,
    progress: Progress | None = None,
    frames_dir: str | Path | None = None,
    audio_start: float = 0.0,
) -> Path:
    """An H.264 MP4 of the dance at the motion's fps, with `audio` from `audio_start` seconds (a dance of
    a part of the song) trimmed or padded to the dance, muxed in.

    `progress(fraction)` is called after each frame; `frames_dir` also gets every frame as a PNG.
    The file appears only when complete.
    """
    out = Path(out)
    if width % 2 or height % 2:
        raise DanceNetError(f"video size {width}x{height}: H.264 needs an even width and height")
    _check_size(width, height)
    audio = Path(audio) if audio is not None else None
    if audio is not None:
        _check_audio(audio)
    _make_dir(out.parent)
    if frames_dir is not None:
        frames_dir = Path(frames_dir)
        _make_dir(frames_dir)
    rate = Fraction(motion.fps).limit_denominator(1001)
    cmd = [_tool("ffmpeg"), "-y", "-hide_banner", "-nostdin", "-loglevel", "error", "-f", "rawvideo",
           "-pix_fmt", "rgb24", "-s", f"{width}x{height}", "-framerate", str(rate), "-i", "pipe:0"]
    if audio is not None:
        cmd += ["-ss", f"{audio_start:.6f}", "-i", str(audio), "-map", "0:v:0", "-map", "1:a:0", "-af", "apad",
                "-c:a", "aac", "-b:a", "192k"]
    # -t ends every stream at the last frame: the music is cut there, or padded with silence up to it.
    cmd += ["-t", f"{float(motion.num_frames / rate):.6f}", "-c:v", "libx264", "-preset", "veryfast",
            "-crf", "20", "-pix_fmt", "yuv420p", "-movflags", "+faststart", "-f", "mp4"]
    frames = iter_frames(motion, None, width, height)
    with atomic_path(out) as partial, tempfile.TemporaryFile() as log, contextlib.closing(frames):
        proc = subprocess.Popen([*cmd, str(partial)], stdin=subprocess.PIPE, stderr=log)
        stdin = cast(IO[bytes], proc.stdin)
        try:
            with contextlib.suppress(BrokenPipeError):  # ffmpeg quit early: its own message says why
                for i, image in enumerate(frames):
                    stdin.write(image.tobytes())
                    if frames_dir is not None:
                        _save_png(image, frames_dir / f"frame_{i:05d}.png")
                    if progress:
                        progress((i + 1) / motion.num_frames)
                stdin.close()
            code = proc.wait()
        except BaseException:
            proc.kill()
            proc.wait()
            raise
        if code != 0:
            log.seek(0)
            message = _last_line(log.read().decode(errors="replace"))
            raise DanceNetError(f"ffmpeg could not write {out}: {message}")
    return out

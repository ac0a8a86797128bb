"""Preview renderer: the dancer as capsules and spheres on a grid floor, drawn off-screen with pyrender.

pyrender because it draws headless from plain numpy (EGL, on a GPU or Mesa's llvmpipe; OSMesa where EGL
is missing), so the command line and CI make previews without Blender. Frames go raw (rgb24) down a pipe
to ffmpeg, which encodes H.264 and muxes the music from time zero, trimmed or padded to the dance, so
sound and picture start and end together. The camera looks from the front (+Z, where the rest pose
faces) and follows the dancer's low-pass-filtered root, so steps do not shake it.
"""

from __future__ import annotations

import contextlib
import functools
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
from typing import IO, TYPE_CHECKING, cast

import numpy as np
from scipy.ndimage import gaussian_filter1d

from .atomic import atomic_path
from .environment import default_workers
from .errors import DanceNetError
from .kinematics import fk_numpy
from .motion import Motion
from .progress import Progress
from .skeleton import Skeleton

if TYPE_CHECKING:
    import pyrender


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
        f"no off-screen OpenGL works here ({'; '.join(failures)}); install the Debian packages in "
        "scripts/apt-packages.txt (libegl1, libgl1-mesa-dri or libosmesa6)"
    )


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
    """One floor tile: light grey with darker lines on its edges (sRGB)."""
    tile = np.full((px, px, 3), 198, np.uint8)
    tile[:line] = tile[-line:] = tile[:, :line] = tile[:, -line:] = 140
    return tile


def _blob_texture(px: int = 64) -> np.ndarray:
    """A soft round shadow: black, alpha a Gaussian falling to ~0 at the quad's edge."""
    r2 = np.sum(np.square(np.mgrid[-1:1:px * 1j, -1:1:px * 1j]), axis=0)
    rgba = np.zeros((px, px, 4), np.uint8)
    rgba[..., 3] = np.round(255 * np.exp(-r2 / (2 * 0.35**2)) * (r2 < 1))
    return rgba


class _Stage:
    """A pyrender scene of one dance: the figure, re-posed each frame, on a floor, lit, with a camera."""

    def __init__(self, motion: Motion, width: int, height: int, floor: float) -> None:
        import pyrender  # the render extra; it loads OpenGL, which must wait until a window system is chosen

        self.pyrender = pyrender
        skel = motion.skeleton
        self.floor = floor
        self.unit = unit = figure_scale(skel)
        self.scene = pyrender.Scene(bg_color=[*(c / 255 for c in BACKGROUND_RGB), 1.0],
                                    ambient_light=[0.32, 0.32, 0.34])
        # pixels per metre (of a 1.70 m figure) at the follow camera's distance
        px_per_m = height / (2 * np.tan(YFOV / 2) * float(np.linalg.norm(_CAMERA_OFFSET)))
        self.figure = _build_figure(skel, unit, px_per_m)
        self.figure_material = pyrender.MetallicRoughnessMaterial(metallicFactor=0.0, roughnessFactor=0.55)
        self.nodes: dict[str, pyrender.Node] = {}
        self._add_floor(motion)
        self._init_shadows(skel)
        for direction, intensity in (((-0.35, -1.0, -0.55), 2.6), ((0.8, -0.45, -0.3), 1.1)):
            d = np.asarray(direction)
            self.scene.add(pyrender.DirectionalLight(intensity=intensity), pose=_look_at(-d, np.zeros(3)))
        self.camera_node = self.scene.add(pyrender.PerspectiveCamera(yfov=YFOV, znear=0.05 * unit,
                                                                     zfar=4 * _FLOOR_MARGIN * unit))
        try:
            self.renderer = pyrender.OffscreenRenderer(width, height)
        except Exception as e:  # pyrender raises bare RuntimeError/ValueError/ctypes errors
            raise DanceNetError(
                f"cannot start off-screen OpenGL ({os.environ.get('PYOPENGL_PLATFORM')}): {e}"
            ) from e

    def _add_floor(self, motion: Motion) -> None:
        """A grid floor under the whole dance, its texture anchored to the world so the grid stays put."""
        pr = self.pyrender
        root = motion.root_positions[:, [0, 2]] + motion.skeleton.offsets[0, [0, 2]]
        lo = root.min(axis=0) - _FLOOR_MARGIN * self.unit
        hi = root.max(axis=0) + _FLOOR_MARGIN * self.unit
        xz = np.array([[lo[0], lo[1]], [lo[0], hi[1]], [hi[0], hi[1]], [hi[0], lo[1]]])
        sampler = pr.Sampler(magFilter=pr.GLTF.LINEAR, minFilter=pr.GLTF.LINEAR_MIPMAP_LINEAR,
                             wrapS=pr.GLTF.REPEAT, wrapT=pr.GLTF.REPEAT)
        material = pr.MetallicRoughnessMaterial(
            baseColorTexture=pr.Texture(source=_grid_texture(), source_channels="RGB", sampler=sampler),
            metallicFactor=0.0, roughnessFactor=1.0)
        self.scene.add(pr.Mesh([pr.Primitive(
            positions=np.column_stack([xz[:, 0], np.full(4, self.floor), xz[:, 1]]),
            normals=np.tile([0.0, 1.0, 0.0], (4, 1)), texcoord_0=xz / (_FLOOR_TILE * self.unit),
            indices=np.array([[0, 1, 2], [0, 2, 3]]), material=material)]))

    def _init_shadows(self, skel: Skeleton) -> None:
        """Soft dark discs under the feet and the body, drawn per frame: they fade and spread as they rise."""
        pr = self.pyrender
        feet = [j for j, n in enumerate(skel.names) if any(w in n.lower() for w in ("ankle", *_FOOT_WORDS))]
        self.shadow_joints = np.array([0, *feet], dtype=int)
        self.shadow_size = np.array([0.45] + [0.14] * len(feet)) * self.unit
        self.shadow_alpha = np.array([0.5] + [0.6] * len(feet))
        self.shadow_fade = np.array([4.0] + [0.5] * len(feet)) * self.unit  # height where it is gone
        n = len(self.shadow_joints)
        quad = np.array([[-1.0, 0.0, -1.0], [-1.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 0.0, -1.0]])
        self.shadow_corners = np.tile(quad, (n, 1))
        self.shadow_uv = (self.shadow_corners[:, [0, 2]] + 1) / 2
        faces = np.array([[0, 1, 2], [0, 2, 3]])
        self.shadow_faces = (faces + 4 * np.arange(n)[:, None, None]).reshape(-1, 3)
        self.shadow_material = pr.MetallicRoughnessMaterial(
            baseColorFactor=[0.0, 0.0, 0.0, 1.0], alphaMode="BLEND", metallicFactor=0.0,
            baseColorTexture=pr.Texture(source=_blob_texture(), source_channels="RGBA"))

    def _replace(self, name: str, primitive: pyrender.Primitive) -> None:
        if name in self.nodes:
            self.scene.remove_node(self.nodes[name])
        self.nodes[name] = self.scene.add(self.pyrender.Mesh([primitive]))

    def render(self, pos: np.ndarray, rot: np.ndarray, camera: Camera) -> np.ndarray:
        """One frame [H, W, 3] uint8 of the pose given by world positions [J, 3] and rotations [J, 3, 3]."""
        pr = self.pyrender
        vertices, normals = self.figure.posed(pos, rot)
        self._replace("figure", pr.Primitive(positions=vertices, normals=normals, color_0=self.figure.colours,
                                             indices=self.figure.faces, material=self.figure_material))
        feet = pos[self.shadow_joints]
        heights = np.maximum(feet[:, 1] - self.floor, 0.0)
        alpha = self.shadow_alpha * np.clip(1.0 - heights / self.shadow_fade, 0.0, 1.0) ** 2
        size = self.shadow_size * (1.0 + heights / self.unit)
        # each disc a hair above the one before, so overlapping discs never fight over depth
        centres = np.column_stack([feet[:, 0], self.floor + (1 + np.arange(len(feet))) * 5e-4 * self.unit,
                                   feet[:, 2]])
        colours = np.zeros((4 * len(feet), 4), np.float32)
        colours[:, 3] = np.repeat(alpha, 4)
        self._replace("shadows", pr.Primitive(
            positions=np.repeat(centres, 4, axis=0) + self.shadow_corners * np.repeat(size, 4)[:, None],
            normals=np.tile([0.0, 1.0, 0.0], (4 * len(feet), 1)), texcoord_0=self.shadow_uv, color_0=colours,
            indices=self.shadow_faces, material=self.shadow_material))
        self.scene.set_pose(self.camera_node, camera.pose)
        colour, _ = self.renderer.render(self.scene)
        return colour

    def close(self) -> None:
        self.renderer.delete()


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
                             initargs=(motion, width, height, floor, cams)) as pool:
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


def _worker_start(motion: Motion, width: int, height: int, floor: float, cams: list[Camera]) -> None:
    """Keep a rendering worker's dance; with Mesa's software rasteriser, one thread each (the workers
    already fill the cores). The stage is built on the first chunk, so its errors reach the caller."""
    os.environ.setdefault("LP_NUM_THREADS", "1")
    _worker_state.update(motion=motion, size=(width, height), floor=floor, cams=cams)


def _worker_draw(chunk: np.ndarray) -> np.ndarray:
    """Frames [n, H, W, 3] of one chunk of frame numbers."""
    st = _worker_state
    if "stage" not in st:
        st["stage"] = _Stage(st["motion"], *st["size"], st["floor"])
    motion = st["motion"]
    pos, rot = fk_numpy(motion.skeleton, motion.rotations[chunk], motion.root_positions[chunk])
    return np.stack([st["stage"].render(pos[k], rot[k], st["cams"][f]) for k, f in enumerate(chunk)])


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
    partial = out.with_name(f".{out.name}.partial")
    frames = iter_frames(motion, None, width, height)
    with tempfile.TemporaryFile() as log, contextlib.closing(frames):
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
            partial.unlink(missing_ok=True)
            raise
        if code != 0:
            log.seek(0)
            partial.unlink(missing_ok=True)
            message = _last_line(log.read().decode(errors="replace"))
            raise DanceNetError(f"ffmpeg could not write {out}: {message}")
    os.replace(partial, out)
    return out

"""What is drawn, as meshes and textures: the figure (capsules and spheres, each part tessellated only as finely
as its size on screen needs) and the grid floor under the whole dance, with the soft shadows' texture."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..motion import Motion
from ..skeleton import Skeleton
from .camera import figure_scale

_FLOOR_MARGIN = 40.0  # floor beyond the dance's footprint, so its edge sits near the horizon
_FLOOR_TILE = 1.0  # grid spacing
_LOD_TOLERANCE_PX = 0.5  # the most a part's facets may stray from its true outline, in pixels

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

"""BVH motion files: read any of them, write our motion as one.

BVH is what Blender, MotionBuilder and the CMU/AMASS mocap archives all speak, so it is how dance
clips come in (training data, reference moves) and how generated dances go out to other tools.
The reader takes any hierarchy and channel layout and reports a malformed file as a
`BvhParseError` naming the file, the line and what was expected there.

Conventions: a joint's rotation is its rotation channels composed intrinsically in file order
(`ZXY` means R = Rz @ Rx @ Ry), in degrees. Position channels give the joint's position in its
parent's frame and replace its OFFSET (axis by axis), as Blender's importer and exporter treat them;
so the root's channels are its world position, which `Motion` splits into root_positions + offsets[0].
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NoReturn

import numpy as np
from scipy.spatial.transform import Rotation

from .atomic import atomic_open
from .errors import DanceNetError
from .motion import Motion
from .skeleton import DEFAULT_SKELETON, JOINT_NAMES, PARENTS, EndSite, Skeleton

CHANNEL_NAMES: tuple[str, ...] = (
    "Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation",
)  # fmt: skip
_CANONICAL_CHANNEL = {c.lower(): c for c in CHANNEL_NAMES}
_FRAMES_RE = re.compile(r"Frames:\s*(\S+)\s*$", re.IGNORECASE)
_FRAME_TIME_RE = re.compile(r"Frame\s+Time:\s*(\S+)\s*$", re.IGNORECASE)


# Deeper hierarchies are not skeletons (a human chain is ~10 deep); reading and writing them recursively would
# exhaust Python's stack.
MAX_DEPTH = 200
# More joints than any rig (a face-rigged character has a few hundred): a bound on what a file may ask for, read
# in time linear in the joints.
MAX_JOINTS = 10_000
# Frame rates a motion file may ask for (mocap runs at up to a few hundred fps): outside them, resampling to the
# model's 25 fps would make thousands of frames from each one (Frame Time 1000 asked for 41 GiB).
MIN_FPS, MAX_FPS = 1.0, 1000.0


class BvhParseError(DanceNetError):
    """A BVH file that cannot be read; the message is `file:line: what was expected, got what`."""

    def __init__(self, path: str | Path, line: int | None, message: str) -> None:
        self.path = str(path)
        self.line = line
        super().__init__(f"{self.path}:{line}: {message}" if line is not None else f"{self.path}: {message}")


@dataclass
class BvhData:
    """A BVH file as written: joints in file order (parents first), channels and raw frame values.

    offsets: [J, 3] OFFSET of each joint in its parent's frame.
    channels: per joint, its channel names in file order (from `CHANNEL_NAMES`).
    end_sites: the `End Site` points, named `<parent>_end`.
    values: [T, C] the MOTION block, columns in the order joints and their channels appear.
    """

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    end_sites: tuple[EndSite, ...]
    frame_time: float
    values: np.ndarray

    def __post_init__(self) -> None:
        self.offsets = np.asarray(self.offsets, dtype=np.float64)
        self.values = np.asarray(self.values, dtype=np.float64)
        nj = len(self.names)
        if len(self.parents) != nj or len(self.channels) != nj or self.offsets.shape != (nj, 3):
            raise ValueError("names, parents, channels and offsets must describe the same joints")
        for j, p in enumerate(self.parents):
            if p >= j:
                raise ValueError(f"joint {j} ({self.names[j]}) must come after its parent {p}")
        for chans in self.channels:
            if not set(chans) <= set(CHANNEL_NAMES) or len(set(chans)) != len(chans):
                raise ValueError(f"bad channel list {chans}; channels come from {CHANNEL_NAMES}")
        ncols = sum(len(c) for c in self.channels)
        if self.values.ndim != 2 or self.values.shape[1] != ncols or len(self.values) == 0:
            raise ValueError(f"values must be [T > 0, {ncols}], got {self.values.shape}")
        if not self.frame_time > 0:
            raise ValueError(f"frame_time must be positive, got {self.frame_time}")

    @property
    def num_joints(self) -> int:
        return len(self.names)

    @property
    def num_frames(self) -> int:
        return len(self.values)

    @property
    def fps(self) -> float:
        """Frames per second; a whole rate when Frame Time is one rounded (0.033333 -> 30, not 30.0003)."""
        fps = 1.0 / self.frame_time
        return float(round(fps)) if abs(fps - round(fps)) < 1e-4 * fps else fps

    def _columns(self) -> list[dict[str, int]]:
        """Per joint, channel name -> column in `values`."""
        cols: list[dict[str, int]] = []
        start = 0
        for chans in self.channels:
            cols.append({c: start + k for k, c in enumerate(chans)})
            start += len(chans)
        return cols

    def _local_rotation_objects(self) -> list[Rotation]:
        rots = []
        for chans, cols in zip(self.channels, self._columns(), strict=True):
            r = Rotation.identity(self.num_frames)
            for c in chans:
                if c.endswith("rotation"):
                    # angles as (N, 1): newer scipy reads a 1-D array for one axis as a single rotation
                    r = r * Rotation.from_euler(c[0], self.values[:, cols[c], None], degrees=True)
            rots.append(r)
        return rots

    def local_rotations(self) -> np.ndarray:
        """Rotation vectors [T, J, 3] (radians) of each joint relative to its parent."""
        return np.stack([r.as_rotvec() for r in self._local_rotation_objects()], axis=1)

    def local_translations(self) -> np.ndarray:
        """[T, J, 3] each joint's position in its parent's frame: its OFFSET, or its position channels."""
        out = np.repeat(self.offsets[None], self.num_frames, axis=0)
        for j, cols in enumerate(self._columns()):
            for k, axis in enumerate("XYZ"):
                if f"{axis}position" in cols:
                    out[:, j, k] = self.values[:, cols[f"{axis}position"]]
        return out

    def _fk(self) -> tuple[np.ndarray, np.ndarray]:
        """World positions [T, J, 3] and rotation matrices [T, J, 3, 3]."""
        local_r = np.stack([r.as_matrix() for r in self._local_rotation_objects()], axis=1)
        local_t = self.local_translations()
        world_r = np.empty_like(local_r)
        world_p = np.empty_like(local_t)
        for j, p in enumerate(self.parents):
            if p < 0:
                world_r[:, j] = local_r[:, j]
                world_p[:, j] = local_t[:, j]
            else:
                world_r[:, j] = world_r[:, p] @ local_r[:, j]
                world_p[:, j] = world_p[:, p] + np.einsum("tik,tk->ti", world_r[:, p], local_t[:, j])
        return world_p, world_r

    def world_positions(self) -> np.ndarray:
        """World joint positions [T, J, 3] in the file's units and axes."""
        return self._fk()[0]

    def end_site_positions(self) -> np.ndarray:
        """World positions [T, E, 3] of the End Sites."""
        pos, rot = self._fk()
        parents = [s.parent for s in self.end_sites]
        offsets = np.array([s.offset for s in self.end_sites], dtype=np.float64).reshape(-1, 3)
        return pos[:, parents] + np.einsum("teik,ek->tei", rot[:, parents], offsets)

    def to_motion(self, scale: float = 1.0) -> Motion:
        """The clip as a `Motion` (offsets and positions times `scale`).

        Only the root may move freely; position channels on other joints (Blender's exporter writes
        them on every unconnected bone) must hold still, and their value becomes the bone's offset.
        A file holding our 55-joint skeleton (as `write_bvh` writes it) comes back in our joint order
        with `DEFAULT_SKELETON`, so its end-effectors are the paper's five again.
        """
        roots = [j for j, p in enumerate(self.parents) if p < 0]
        if roots != [0]:
            raise DanceNetError(f"this BVH has {len(roots)} root joints; a motion needs exactly one")
        local_t = self.local_translations()
        size = max(1e-9, float(np.abs(self.offsets).max()))
        moving = np.ptp(local_t[:, 1:], axis=0).max(axis=-1) > 1e-5 * size
        if moving.any():
            name = self.names[1 + int(np.argmax(moving))]
            raise DanceNetError(
                f"BVH joint '{name}' changes its position over time; a motion lets only the root move"
            )
        offsets = np.concatenate([self.offsets[:1], local_t[0, 1:]]) * scale
        root = (local_t[:, 0] - self.offsets[0]) * scale
        rotations = self.local_rotations()
        perm = self._default_permutation(offsets)
        if perm is not None:
            return Motion(rotations[:, perm], root, self.fps, DEFAULT_SKELETON)
        ends = tuple(_scaled_site(s, scale) for s in self.end_sites)
        return Motion(rotations, root, self.fps, Skeleton(offsets, self.names, self.parents, ends))

    def _default_permutation(self, offsets: np.ndarray) -> list[int] | None:
        """File joint index of each of our 55 joints, when the file holds exactly our skeleton."""
        if sorted(self.names) != sorted(JOINT_NAMES):
            return None
        index = {n: i for i, n in enumerate(self.names)}
        perm = [index[n] for n in JOINT_NAMES]
        same_tree = all(self.parents[perm[j]] == (perm[p] if p >= 0 else -1) for j, p in enumerate(PARENTS))
        if same_tree and np.allclose(offsets[perm], DEFAULT_SKELETON.offsets, rtol=0.0, atol=1e-5):
            return perm
        return None


def _scaled_site(site: EndSite, scale: float) -> EndSite:
    x, y, z = site.offset
    return EndSite(site.name, site.parent, (x * scale, y * scale, z * scale))


# ----------------------------------------------------------------------------------------- reading


class _HierarchyParser:
    """Recursive descent over the HIERARCHY section; braces may share a line with other words."""

    def __init__(self, path: str | Path, lines: Sequence[str]) -> None:
        self.path = path
        self.lines = lines
        self.stmts: list[tuple[int, list[str]]] = []  # (1-based line, words), braces split out
        for i, line in enumerate(lines):
            words: list[str] = []
            for tok in line.split():
                if tok in ("{", "}"):
                    if words:
                        self.stmts.append((i + 1, words))
                        words = []
                    self.stmts.append((i + 1, [tok]))
                else:
                    words.append(tok)
            if words:
                self.stmts.append((i + 1, words))
            if line.split()[:1] == ["MOTION"]:
                break
        self.pos = 0
        self.names: list[str] = []
        # Names so far as sets: a lookup per name, not a search, so reading is linear in the joints.
        self.joint_names: set[str] = set()
        self.end_site_names: set[str] = set()
        self.parents: list[int] = []
        self.offsets: list[tuple[float, float, float]] = []
        self.channels: list[tuple[str, ...]] = []
        self.end_sites: list[EndSite] = []

    def error(self, line: int, expected: str, got: str | None = None) -> BvhParseError:
        if got is None:
            got = self.lines[line - 1].strip() if line <= len(self.lines) else ""
        shown = f"'{got[:80]}'" if got else "end of file"
        return BvhParseError(self.path, line, f"expected {expected}, got {shown}")

    def next(self, expected: str) -> tuple[int, list[str]]:
        if self.pos >= len(self.stmts):
            raise self.error(max(1, len(self.lines)), expected, got="")
        stmt = self.stmts[self.pos]
        self.pos += 1
        return stmt

    def expect(self, words: list[str], shown: str) -> int:
        line, got = self.next(shown)
        if got != words:
            raise self.error(line, shown)
        return line

    def parse(self) -> int:
        """Parse up to and including MOTION; returns MOTION's 0-based line index."""
        self.expect(["HIERARCHY"], "'HIERARCHY'")
        line, words = self.next("'ROOT'")
        while words[0] == "ROOT":
            self.joint(-1, line, words, 0)
            line, words = self.next("'ROOT' or 'MOTION'")
        if words != ["MOTION"] or not self.names:
            raise self.error(line, "'ROOT' or 'MOTION'" if self.names else "'ROOT'")
        return line - 1

    def offset(self) -> tuple[float, float, float]:
        line, words = self.next("'OFFSET' followed by 3 numbers")
        try:
            if words[0] != "OFFSET" or len(words) != 4:
                raise ValueError
            x, y, z = (float(w) for w in words[1:])
        except ValueError:
            raise self.error(line, "'OFFSET' followed by 3 numbers") from None
        if not np.isfinite([x, y, z]).all():
            raise self.error(line, "'OFFSET' followed by 3 finite numbers")
        return x, y, z

    def channel_list(self) -> tuple[str, ...]:
        shown = "'CHANNELS' followed by a count and that many channel names"
        line, words = self.next(shown)
        count_ok = len(words) >= 2 and words[1].isdigit() and len(words) == 2 + int(words[1])
        if words[0] != "CHANNELS" or not count_ok:
            raise self.error(line, shown)
        chans = []
        for w in words[2:]:
            c = _CANONICAL_CHANNEL.get(w.lower())
            if c is None or c in chans:
                what = "a channel name" if c is None else "each channel once"
                raise self.error(line, f"{what} ({', '.join(CHANNEL_NAMES)})", got=w)
            chans.append(c)
        return tuple(chans)

    def joint(self, parent: int, line: int, words: list[str], depth: int) -> None:
        if depth > MAX_DEPTH:
            raise BvhParseError(self.path, line, f"joints nested more than {MAX_DEPTH} deep: not a skeleton")
        name = " ".join(words[1:])
        if not name:
            raise self.error(line, f"'{words[0]}' followed by a joint name")
        if name in self.joint_names:
            raise self.error(line, "a joint name not used before")
        j = len(self.names)
        if j == MAX_JOINTS:
            raise BvhParseError(self.path, line, f"more than {MAX_JOINTS} joints: not a skeleton")
        self.names.append(name)
        self.joint_names.add(name)
        self.parents.append(parent)
        self.expect(["{"], "'{'")
        self.offsets.append(self.offset())
        self.channels.append(self.channel_list())
        while True:
            line, words = self.next("'JOINT', 'End Site' or '}'")
            if words[0] == "JOINT":
                self.joint(j, line, words, depth + 1)
            elif words == ["End", "Site"]:
                self.expect(["{"], "'{'")
                offset = self.offset()
                self.expect(["}"], "'}'")
                site = f"{name}_end"
                k = 2
                while site in self.end_site_names:
                    site, k = f"{name}_end{k}", k + 1
                self.end_site_names.add(site)
                self.end_sites.append(EndSite(site, j, offset))
            elif words == ["}"]:
                return
            elif words == ["MOTION"]:
                raise self.error(line, f"'}}' to close joint '{name}' (unbalanced braces)")
            else:
                raise self.error(line, "'JOINT', 'End Site' or '}'")


def _header_number(
    path: str | Path,
    lines: Sequence[str],
    i: int,
    pattern: re.Pattern[str],
    kind: type[int] | type[float],
    what: str,
) -> int | float:
    """The positive number on the `Frames:` or `Frame Time:` line `lines[i]`."""
    text = lines[i].strip()
    m = pattern.match(text)
    try:
        value = kind(m.group(1)) if m else 0
    except ValueError:
        value = 0
    if not 0 < value < float("inf"):
        raise BvhParseError(path, i + 1, f"expected {what}, got '{text[:80]}'")
    return value


def _motion_error(
    path: str | Path, data: Sequence[str], first_line: int, frames: int, ncols: int
) -> NoReturn:
    """Find and raise the first problem in the frame lines (the slow path, only for bad files)."""
    found = 0
    last = first_line - 1
    for i, text in enumerate(data):
        words = text.split()
        if not words:
            continue
        line = first_line + i
        if found == frames:
            raise BvhParseError(
                path,
                line,
                f"expected end of file after {frames} frames (see 'Frames:'), got another line of values",
            )
        if len(words) != ncols:
            raise BvhParseError(path, line, f"expected {ncols} values (one per channel), found {len(words)}")
        for w in words:
            try:
                float(w)
            except ValueError:
                raise BvhParseError(path, line, f"expected a number, got '{w[:40]}'") from None
        found += 1
        last = line
    raise BvhParseError(
        path,
        last + 1,
        f"expected frame {found + 1} of {frames} (see 'Frames:'), got end of file: the file is truncated",
    )


def _text(raw: bytes) -> str:
    """A BVH file's text: UTF-8, else Shift-JIS (MMD's Japanese bone names as Japanese tools write them), else
    UTF-8 with what it cannot decode replaced (a name may then read wrong, the numbers still right)."""
    for encoding in ("utf-8", "cp932"):
        try:
            return raw.decode(encoding)
        except UnicodeDecodeError:
            continue
    return raw.decode("utf-8", errors="replace")


def read_bvh(path: str | Path) -> BvhData:
    """Read a BVH file; a malformed one raises `BvhParseError` (file:line: what was expected)."""
    path_ = Path(path)
    if not path_.is_file():
        raise BvhParseError(path, None, "BVH file not found")
    try:
        lines = _text(path_.read_bytes()).splitlines()
    except OSError as e:
        raise BvhParseError(path, None, f"cannot read the file: {e.strerror}") from e
    if not any(line.strip() for line in lines):
        raise BvhParseError(path, 1, "expected 'HIERARCHY', got an empty file")

    parser = _HierarchyParser(path, lines)
    i = parser.parse() + 1
    header = []
    while len(header) < 2 and i < len(lines):
        if lines[i].strip():
            header.append(i)
        i += 1
    if len(header) < 2:
        raise BvhParseError(
            path,
            len(lines),
            f"expected '{'Frame Time:' if header else 'Frames:'}' after 'MOTION', got end of file",
        )
    what = "'Frames:' followed by a positive whole number"
    frames = int(_header_number(path, lines, header[0], _FRAMES_RE, int, what))
    what = "'Frame Time:' followed by a positive number of seconds"
    frame_time = _header_number(path, lines, header[1], _FRAME_TIME_RE, float, what)
    if not 1 / MAX_FPS <= frame_time <= 1 / MIN_FPS:
        raise BvhParseError(path, header[1] + 1, f"expected 'Frame Time:' from {1 / MAX_FPS:g} to {1 / MIN_FPS:g} "
                            f"seconds ({MIN_FPS:g} to {MAX_FPS:g} frames per second), got {frame_time:g}")

    data = lines[i:]
    ncols = sum(len(c) for c in parser.channels)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "empty input": a truncated file, caught below
            values = np.loadtxt(data, dtype=np.float64, comments=None, ndmin=2)
    except ValueError:
        values = None
    if values is None or values.shape != (frames, ncols):
        _motion_error(path, data, i + 1, frames, ncols)
    if not np.isfinite(values).all():
        row = int(np.flatnonzero(~np.isfinite(values).all(axis=1))[0])
        line = i + 1 + [k for k, text in enumerate(data) if text.strip()][row]
        raise BvhParseError(path, line, "expected finite numbers, got NaN or infinity")
    return BvhData(
        names=tuple(parser.names),
        parents=tuple(parser.parents),
        offsets=np.array(parser.offsets, dtype=np.float64),
        channels=tuple(parser.channels),
        end_sites=tuple(parser.end_sites),
        frame_time=frame_time,
        values=values,
    )


# ----------------------------------------------------------------------------------------- writing


def _write(
    path: str | Path,
    names: Sequence[str],
    parents: Sequence[int],
    offsets: np.ndarray,
    channels: Sequence[Sequence[str]],
    end_sites: Sequence[EndSite],
    columns: Sequence[np.ndarray],
    frame_time: float,
) -> None:
    """Write joints depth first (BVH's order) with `columns[j]` [T, len(channels[j])] as their values."""
    children: list[list[int]] = [[] for _ in names]
    for j, p in enumerate(parents):
        if p >= 0:
            children[p].append(j)
    sites: list[list[EndSite]] = [[] for _ in names]
    for s in end_sites:
        sites[s.parent].append(s)
    out = ["HIERARCHY"]
    order: list[int] = []

    def vec(v: Sequence[float]) -> str:
        return " ".join(f"{float(x):.6f}" for x in v)

    def block(j: int, depth: int) -> None:
        pad = "\t" * depth
        order.append(j)
        out.append(f"{pad}{'ROOT' if parents[j] < 0 else 'JOINT'} {names[j]}")
        out.append(f"{pad}{{")
        out.append(f"{pad}\tOFFSET {vec(offsets[j])}")
        out.append(f"{pad}\tCHANNELS {len(channels[j])}{''.join(' ' + c for c in channels[j])}")
        for c in children[j]:
            block(c, depth + 1)
        for s in sites[j]:
            out.extend([f"{pad}\tEnd Site", f"{pad}\t{{", f"{pad}\t\tOFFSET {vec(s.offset)}", f"{pad}\t}}"])
        out.append(f"{pad}}}")

    for j, p in enumerate(parents):
        if p < 0:
            block(j, 0)
    values = np.concatenate([np.asarray(columns[j], dtype=np.float64) for j in order], axis=1)
    out += ["MOTION", f"Frames: {len(values)}", f"Frame Time: {frame_time:.8f}"]
    with atomic_open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write("\n".join(out) + "\n")
        np.savetxt(f, values, fmt="%.6f")


def write_bvh(path: str | Path, motion: Motion, rotation_order: str = "ZXY", scale: float = 1.0) -> None:
    """Write a `Motion` as BVH: root with 3 position + 3 rotation channels, other joints 3 rotations.

    Offsets and positions are the motion's (metres) times `scale`. The skeleton's end sites become
    `End Site` blocks; a leaf joint without one gets an End Site half its own bone further on, so that
    Blender's importer gives the leaf bone a sensible length and direction.
    """
    order = rotation_order.upper()
    if sorted(order) != ["X", "Y", "Z"]:
        raise ValueError(f"rotation_order must be a permutation of XYZ, got {rotation_order!r}")
    sk = motion.skeleton
    t, nj = motion.num_frames, sk.num_joints
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # gimbal lock: the angles still give the rotation
        euler = Rotation.from_rotvec(motion.rotations.reshape(-1, 3)).as_euler(order, degrees=True)
    euler = euler.reshape(t, nj, 3)
    rot_channels = tuple(f"{a}rotation" for a in order)
    pos_channels = ("Xposition", "Yposition", "Zposition")
    offsets = sk.offsets * scale
    ends = [_scaled_site(s, scale) for s in sk.end_sites]
    has_child = {p for p in sk.parents if p >= 0} | {s.parent for s in sk.end_sites}
    for j in range(nj):
        if j not in has_child:
            tip = offsets[j] * 0.5 if sk.parents[j] >= 0 else np.zeros(3)
            ends.append(EndSite(f"{sk.names[j]}_end", j, (float(tip[0]), float(tip[1]), float(tip[2]))))
    channels = [pos_channels + rot_channels if p < 0 else rot_channels for p in sk.parents]
    columns = [
        np.concatenate([motion.root_positions * scale + offsets[j], euler[:, j]], axis=1)
        if p < 0
        else euler[:, j]
        for j, p in enumerate(sk.parents)
    ]
    _write(path, sk.names, sk.parents, offsets, channels, ends, columns, 1.0 / motion.fps)


def write_bvh_data(path: str | Path, data: BvhData) -> None:
    """Write `data` back in its own hierarchy and channel layout (values to 6 decimals)."""
    columns = [data.values[:, sorted(cols.values())] for cols in data._columns()]
    _write(
        path, data.names, data.parents, data.offsets, data.channels, data.end_sites, columns, data.frame_time
    )

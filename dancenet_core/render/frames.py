"""Frames in order, drawn in this process or, for longer dances, by a pool of worker processes, each with its
own OpenGL context; a worker ends with its parent and sends its errors back as one line of text."""

from __future__ import annotations

import multiprocessing as mp
import os
import sys
from collections import deque
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor

import numpy as np

from ..environment import default_workers, end_with_parent, stop_pool
from ..errors import DanceNetError, first_line
from ..kinematics import fk_numpy
from ..motion import Motion
from .camera import Camera, _fk_chunks, camera_path, floor_height
from .gl import gl_platform
from .stage import _Stage

_WORKER_CHUNK = 16  # frames a rendering worker draws per task
_PARALLEL_MIN_FRAMES = 100  # below this, starting worker processes costs more than they save


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
            if pending:  # stopped early (an error, a signal, the caller stopped reading)
                stop_pool(pool)


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
    '_ctypes.CArgObject'`."""
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

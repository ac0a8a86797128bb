"""FBX clips for a library build, without Blender in this process: each file's armature animation as Blender
samples it (`RigSample`: every bone's world rest and per-frame matrices, in metres), by worker processes that
import Blender's Python module (`fbx_worker.py`, where the `blender` extra is installed) or by the add-on in
Blender, cached by the file's content; the build then maps its bones onto our joints with the core's mapper
(`rigmap.humanoid_joints`, in `build._fbx_clip`).

A sample is cached under the cache folder by the digest of the file's bytes, so a rebuild samples only the FBX
files it has not seen; a file Blender could not read is cached as its one-line reason (a damaged file stays
damaged), while a worker that died or a missing Blender module is never cached.
"""

from __future__ import annotations

import importlib.util
import json
import os
import queue
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable, Sequence
from contextlib import suppress
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from ..environment import cache_root
from ..errors import DanceNetError
from ..rigmap import RestBone
from ..units import DANCER_HEIGHT_M, DANCER_M, SAMPLED_UNITS, dancer_unit
from .store import file_sha256

SAMPLE_VERSION = "fbx-sample-1"  # change whenever what a sample holds changes
WORKER = "dancenet_core.library.fbx_worker"  # the module a worker process runs
INSTALL_HINT = ("pip install 'dancenet[blender]' (Blender's Python module), or build the folder with Build Library "
                "in Blender's DanceNet add-on")


@dataclass
class RigSample:
    """An armature's animation as Blender evaluates it, in a Z-up world in metres: per bone (in the armature's
    order) its name, parent index (-1: none), world rest head and tail [B, 3] and rest matrix [B, 4, 4] (Blender's
    bone convention: the head at the translation, the Y axis along the bone) where the object stands at the first
    frame, and its world matrix per frame [T, B, 4, 4], at `fps`."""

    names: list[str]
    parents: np.ndarray
    heads: np.ndarray
    tails: np.ndarray
    rest: np.ndarray
    pose: np.ndarray
    fps: float

    def height(self) -> float:
        """How tall the rest pose is: the heads' extent along the world's longest axis."""
        return float(np.ptp(self.heads, axis=0).max()) if len(self.heads) else 0.0

    def in_metres(self) -> RigSample:
        """The sample in metres: as it is where its rest pose is a dancer's height, else scaled by the power of
        ten (or the inch) that makes it nearest `DANCER_HEIGHT_M`. A centimetre armature whose FBX node carries
        a 0.01 scale of its own in a centimetre file is imported by Blender at a hundredth of its size (the
        file's unit is applied on top of the node's scale): such a rig is read at its true size."""
        tall = self.height()
        if DANCER_M[0] <= tall <= DANCER_M[1] or tall <= 0:
            return self
        unit = dancer_unit(tall, DANCER_HEIGHT_M, SAMPLED_UNITS)
        rest, pose = self.rest.copy(), self.pose.copy()
        rest[..., :3, 3] *= unit
        pose[..., :3, 3] *= unit
        return RigSample(self.names, self.parents, self.heads * unit, self.tails * unit, rest, pose, self.fps)

    def rest_bones(self) -> list[RestBone]:
        return [RestBone(n, self.names[p] if p >= 0 else None, h, t)
                for n, p, h, t in zip(self.names, self.parents.tolist(), self.heads, self.tails, strict=True)]


def save_sample(path: Path, sample: RigSample | str) -> None:
    """A sample (or the line saying why the file has none, without the file's name: another file may have the
    same bytes) written whole to `path`."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        if isinstance(sample, str):
            np.savez(f, error=np.array(sample))
        else:
            np.savez(f, names=np.array(sample.names, dtype=str), parents=sample.parents, heads=sample.heads,
                     tails=sample.tails, rest=sample.rest, pose=sample.pose.astype(np.float32),
                     fps=np.float64(sample.fps))


def load_sample(path: Path) -> RigSample | str | None:
    """A cached sample, the line saying why its file has none, or None when there is none (or it is damaged)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            if "error" in z:
                return str(z["error"])
            return RigSample([str(n) for n in z["names"]], z["parents"].astype(int), z["heads"], z["tails"],
                             z["rest"], z["pose"].astype(np.float64), float(z["fps"]))
    except (OSError, ValueError, KeyError, EOFError):
        return None


def sample_path(path: Path) -> Path:
    """Where the sample of the FBX file `path` (by its content) is cached."""
    return cache_root() / SAMPLE_VERSION / f"{file_sha256(path).hex()[:32]}.npz"


def bpy_installed() -> bool:
    """Whether Blender's Python module can be imported here (by a worker process: this one never imports it)."""
    return importlib.util.find_spec("bpy") is not None


class Worker:
    """One `fbx_worker` process, fed one file at a time (Blender's module loads once per process)."""

    def __init__(self) -> None:
        root = str(Path(__file__).resolve().parents[2])
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p))
        self.log = tempfile.TemporaryFile()
        self.proc = subprocess.Popen([sys.executable, "-m", WORKER, str(os.getpid())],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.log, text=True,
                                     env=env)

    def sample(self, fbx: Path, out: Path) -> str | None:
        """None when the sample of `fbx` is written to `out`, else the line saying why it is not; a
        DanceNetError when the worker itself failed (it is not used again)."""
        assert self.proc.stdin is not None and self.proc.stdout is not None
        try:
            self.proc.stdin.write(json.dumps({"fbx": str(fbx), "out": str(out)}) + "\n")
            self.proc.stdin.flush()
            line = self.proc.stdout.readline()
        except OSError:
            line = ""
        if not line:
            raise DanceNetError(f"Blender's module stopped while reading it ({self._last_words()})")
        answer = json.loads(line)
        return None if answer.get("ok") else str(answer["error"])

    def _last_words(self) -> str:
        self.proc.wait()
        self.log.seek(0)
        lines = self.log.read().decode(errors="replace").strip().splitlines()
        return lines[-1][:160] if lines else f"exit status {self.proc.returncode}"

    def close(self) -> None:
        if self.proc.stdin is not None:
            self.proc.stdin.close()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.log.close()


def sample_files(files: Sequence[Path], workers: int, done: Callable[[Path], object] = lambda _p: None,
                 should_cancel: Callable[[], bool] | None = None) -> dict[Path, RigSample | str]:
    """Each FBX file's sample, from the cache or sampled now by up to `workers` worker processes side by side
    (each reads one file after another); `done` hears each file as it is read. A file that cannot be sampled
    gets the line saying why instead (without its name)."""
    out: dict[Path, RigSample | str] = {}
    todo: queue.SimpleQueue[tuple[Path, Path]] = queue.SimpleQueue()
    for f in files:
        where = sample_path(f)  # each file hashed once
        if (hit := load_sample(where)) is not None:
            out[f] = hit
            done(f)
        else:
            todo.put((f, where))
    lock = threading.Lock()

    def run() -> None:
        worker: Worker | None = None
        try:
            while not (should_cancel is not None and should_cancel()):
                try:
                    f, where = todo.get_nowait()
                except queue.Empty:
                    return
                worker = worker or Worker()
                try:
                    why = worker.sample(f.resolve(), where)
                except DanceNetError as e:  # the worker died: why, not cached; a fresh worker goes on
                    result: RigSample | str = str(e)
                    worker.close()
                    worker = None
                else:
                    if why is not None:  # the file's own fault: kept, so the next build does not try again
                        result = why
                        with suppress(DanceNetError):  # a cache that cannot be written costs only that
                            save_sample(where, why)
                    else:
                        result = load_sample(where) or "its sample could not be read back"
                with lock:
                    out[f] = result
                done(f)
        finally:
            if worker is not None:
                worker.close()

    threads = [threading.Thread(target=run, daemon=True) for _ in range(max(1, min(workers, todo.qsize())))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return {f: out[f] for f in files if f in out}

"""Preview rendering speed: the preview renderer (what `dancenet render` uses) vs Blender's Workbench engine.

Usage: `python bench/render.py [--frames 500] [--width 640] [--height 360] [--engine all]`. Prints JSON.

The same synthetic 55-joint dance is drawn by both. The preview renderer (engine "pyrender": OpenGL on
pyrender's off-screen context): frames per second through `iter_frames`
(forward kinematics, drawing, read-back), and through `render_motion` (the same plus H.264 encoding in
ffmpeg). Blender (only when `bpy` imports): the add-on's armature and mannequin mesh keyed with the dance,
a floor and a fixed camera, Workbench with FXAA and shadows, one `render(write_still=True)` per frame.
Each engine runs in its own child process, so their OpenGL contexts and start-up costs stay apart;
the first frame (context, shader compiles; with worker processes, their start and first chunk) is timed
on its own as `first_frame_s`. `--engine pyrender` also runs, in the same run and its own process, the
one-process pyrender renderer at commit d4eea3c (read from git at BEFORE_COMMIT: a pyrender scene drawn in one
process) under `before`, with the speed-ups `speedup_frames` and `speedup_video`; `video_frames_per_s` (drawing,
encoding, the mp4 written) is the figure a user waits on.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import ModuleType

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from dancenet_core.motion import Motion  # noqa: E402
from dancenet_core.skeleton import DEFAULT_SKELETON  # noqa: E402


def synthetic_dance(frames: int, fps: float = 30.0) -> Motion:
    """Every joint swinging at its own rate, the root swaying and travelling a little."""
    rng = np.random.default_rng(0)
    t = np.arange(frames)[:, None, None] / fps
    shape = (1, DEFAULT_SKELETON.num_joints, 3)
    phase = 2 * np.pi * rng.uniform(0.3, 2, shape) * t + rng.uniform(0, 6, shape)
    rot = rng.uniform(-0.5, 0.5, shape) * np.sin(phase)
    t1 = t[:, 0, 0]
    height = np.full(frames, DEFAULT_SKELETON.rest_pelvis_height())
    root = np.column_stack([0.4 * np.sin(t1), height, 0.2 * np.sin(0.5 * t1)])
    return Motion(rot, root, fps)


BEFORE_COMMIT = "d4eea3c"  # the one-process pyrender renderer (dancenet_core/render.py, finer fingers)


def render_before() -> ModuleType:
    """The renderer as of BEFORE_COMMIT, read from git and loaded as a module of dancenet_core."""
    src = subprocess.run(["git", "-C", str(REPO), "show", f"{BEFORE_COMMIT}:dancenet_core/render.py"],
                         capture_output=True, text=True, check=True).stdout
    module = ModuleType("dancenet_core._render_before")
    module.__package__ = "dancenet_core"
    sys.modules[module.__name__] = module  # dataclasses look their module up there
    exec(compile(src, f"{BEFORE_COMMIT}:dancenet_core/render.py", "exec"), module.__dict__)
    return module


def bench_pyrender(frames: int, width: int, height: int, before: bool = False) -> dict[str, object]:
    import dancenet_core.render

    renderer = render_before() if before else dancenet_core.render
    gl_platform, iter_frames, render_motion = renderer.gl_platform, renderer.iter_frames, renderer.render_motion

    motion = synthetic_dance(frames + 1)
    t = time.perf_counter()
    platform_ = gl_platform()
    probe_s = time.perf_counter() - t
    t = time.perf_counter()
    images = iter_frames(motion, None, width, height)
    next(images)
    first_s = time.perf_counter() - t
    t = time.perf_counter()
    count = sum(1 for _ in images)
    draw_s = time.perf_counter() - t
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        render_motion(motion[1:], Path(tmp) / "bench.mp4", width=width, height=height)
        video_s = time.perf_counter() - t
    return {
        "engine": "pyrender", "gl_platform": platform_, "platform_probe_s": round(probe_s, 2),
        "first_frame_s": round(first_s, 3), "frames": count, "frames_per_s": round(count / draw_s, 2),
        "video_frames_per_s": round(frames / video_s, 2),
        "video_note": "render_motion end to end: scene set-up, drawing, H.264 encoding, mp4 written",
    }  # fmt: skip


def bench_blender(frames: int, width: int, height: int, user: str) -> dict[str, object]:
    os.environ["HOME"] = user  # keep Blender's user folders out of the real home
    for var in ("BLENDER_USER_RESOURCES", "BLENDER_USER_CONFIG", "BLENDER_USER_SCRIPTS",
                "BLENDER_USER_DATAFILES", "BLENDER_USER_EXTENSIONS"):
        os.environ[var] = os.path.join(user, var.lower())
    import bpy

    from blender_addon import keyframes, rig
    from dancenet_core.skeleton import JOINT_NAMES

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = 30
    arm = rig.create_rig(bpy.context, with_mesh=True)
    keyframes.apply_motion(arm, synthetic_dance(frames + 1), {n: n for n in JOINT_NAMES}, "bench", 1, 30)
    bpy.ops.mesh.primitive_plane_add(size=20.0)
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    camera.data.lens = 28.0
    camera.location, camera.rotation_euler = (0.0, -4.5, 1.0), (np.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.display.shading.show_shadows = True
    scene.display.render_aa = "FXAA"
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = os.path.join(user, "frame.png")

    t = time.perf_counter()
    scene.frame_set(1)
    bpy.ops.render.render(write_still=True)
    first_s = time.perf_counter() - t
    t = time.perf_counter()
    for f in range(2, frames + 2):
        scene.frame_set(f)
        bpy.ops.render.render(write_still=True)
    draw_s = time.perf_counter() - t
    return {
        "engine": "blender_workbench", "blender": bpy.app.version_string, "first_frame_s": round(first_s, 3),
        "frames": frames, "frames_per_s": round(frames / draw_s, 2),
        "note": "frame_set (armature + mesh deform) and render(write_still=True) to PNG per frame",
    }  # fmt: skip


def _child(engine: str, args: argparse.Namespace) -> dict[str, object]:
    """Run one engine's benchmark in a fresh interpreter; its JSON, or why it could not run."""
    cmd = [sys.executable, __file__, "--engine", engine, "--frames", str(args.frames),
           "--width", str(args.width), "--height", str(args.height)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        lines = [line for line in proc.stderr.splitlines() if line.strip()]
        return {"engine": engine, "error": lines[-1] if lines else f"exit status {proc.returncode}"}
    return json.loads(proc.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=500)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=360)
    parser.add_argument("--engine", choices=["all", "pyrender", "pyrender-before", "blender"], default="all")
    args = parser.parse_args()
    if args.engine == "pyrender":
        result: dict[str, object] = bench_pyrender(args.frames, args.width, args.height)
        before = _child("pyrender-before", args)  # same run, its own process: the ratio is fair
        result["before"] = before
        if "error" not in before:
            result["speedup_frames"] = round(result["frames_per_s"] / before["frames_per_s"], 2)  # type: ignore[operator]
            result["speedup_video"] = round(result["video_frames_per_s"] / before["video_frames_per_s"], 2)  # type: ignore[operator]
    elif args.engine == "pyrender-before":
        result = bench_pyrender(args.frames, args.width, args.height, before=True) | {"commit": BEFORE_COMMIT}
    elif args.engine == "blender":
        # Blender prints a line per saved frame on fd 1: keep stdout for the JSON alone
        stdout = os.dup(1)
        with tempfile.TemporaryDirectory(prefix="dancenet-bench-", ignore_cleanup_errors=True) as user:
            with open(os.devnull, "w") as null:
                os.dup2(null.fileno(), 1)
            try:
                result = bench_blender(args.frames, args.width, args.height, user)
            finally:
                sys.stdout.flush()
                os.dup2(stdout, 1)
    else:
        import importlib.util

        results = [_child("pyrender", args)]
        if importlib.util.find_spec("bpy") is not None:
            results.append(_child("blender", args))
        result = {
            "width": args.width, "height": args.height, "frames": args.frames, "results": results,
            "cpu_count": os.cpu_count(), "load_average": [round(x, 2) for x in os.getloadavg()],
            "machine": platform.processor() or platform.machine(),
        }  # fmt: skip
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()

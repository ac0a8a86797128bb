"""Keyframe writing speed on the 55-joint rig: bulk foreach_set (what the add-on does) vs keyframe_insert.

Usage: `python bench/keyframes.py [--minutes 3] [--fps 60] [--insert-frames 120]`. Prints JSON.

A 30 fps synthetic dance of the given length is resampled to the scene's fps and written as one key per
frame on every bone (55 quaternions + the root's location). keyframe_insert is timed on a short span
(`--insert-frames` frames, every bone) and extrapolated per key to the full length, because the real
thing would take minutes; the JSON says so.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if "bpy" not in sys.modules:  # keep Blender's user folders out of $HOME
    _user = tempfile.mkdtemp(prefix="dancenet-bench-")
    for var in ("BLENDER_USER_RESOURCES", "BLENDER_USER_CONFIG", "BLENDER_USER_SCRIPTS"):
        os.environ.setdefault(var, os.path.join(_user, var.lower()))
sys.path.insert(0, str(REPO))

import bpy  # noqa: E402
import numpy as np  # noqa: E402

from blender_addon import retarget, rig  # noqa: E402
from dancenet_core.motion import Motion  # noqa: E402
from dancenet_core.skeleton import DEFAULT_SKELETON, JOINT_NAMES  # noqa: E402


def synthetic_dance(seconds: float, fps: float = 30.0) -> Motion:
    rng = np.random.default_rng(0)
    t = np.arange(round(seconds * fps))[:, None, None] / fps
    shape = (1, DEFAULT_SKELETON.num_joints, 3)
    rot = rng.uniform(-0.5, 0.5, shape) * np.sin(
        2 * np.pi * rng.uniform(0.3, 2, shape) * t + rng.uniform(0, 6, shape)
    )
    root = np.zeros((len(rot), 3))
    root[:, 1] = DEFAULT_SKELETON.rest_pelvis_height()
    return Motion(rot, root, fps)


def bench_insert(arm: bpy.types.Object, tracks: retarget.PoseTracks, frames: int) -> float:
    """Seconds to keyframe_insert `frames` frames on every bone (values set first, as a script would)."""
    scene = bpy.context.scene
    arm.animation_data_create()
    arm.animation_data.action = bpy.data.actions.new("keyframe_insert")
    bones = [arm.pose.bones[b] for b in tracks.rotations]
    root = arm.pose.bones[tracks.root_bone]
    start = time.perf_counter()
    for f in range(frames):
        for pb in bones:
            pb.rotation_quaternion = tracks.rotations[pb.name][f]
            pb.keyframe_insert("rotation_quaternion", frame=scene.frame_start + f)
        root.location = tracks.root_locations[f]
        root.keyframe_insert("location", frame=scene.frame_start + f)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=3.0)
    parser.add_argument("--fps", type=int, default=60)
    parser.add_argument("--insert-frames", type=int, default=120)
    args = parser.parse_args()

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.scene.render.fps = args.fps
    arm = rig.create_rig(bpy.context, with_mesh=False)
    motion = synthetic_dance(args.minutes * 60)
    identity = {n: n for n in JOINT_NAMES}

    t = time.perf_counter()
    resampled = motion.resampled(args.fps)
    resample_s = time.perf_counter() - t
    t = time.perf_counter()
    tracks = retarget.retarget(arm, resampled, identity)
    retarget_s = time.perf_counter() - t
    t = time.perf_counter()
    retarget.write_action(arm, tracks, "foreach_set", 1)
    write_s = time.perf_counter() - t
    frames = tracks.num_frames
    keys = frames * (4 * len(tracks.rotations) + 3)

    insert_s = bench_insert(arm, tracks, args.insert_frames)
    insert_full_s = insert_s / args.insert_frames * frames
    print(json.dumps({
        "dance_minutes": args.minutes, "scene_fps": args.fps, "frames": frames,
        "bones": len(tracks.rotations), "keys": keys,
        "foreach_set_write_s": round(write_s, 3),
        "resample_s": round(resample_s, 3), "retarget_s": round(retarget_s, 3),
        "foreach_set_total_s": round(resample_s + retarget_s + write_s, 3),
        "keyframe_insert_measured_frames": args.insert_frames,
        "keyframe_insert_measured_s": round(insert_s, 3),
        "keyframe_insert_extrapolated_s": round(insert_full_s, 1),
        "keyframe_insert_note": "measured on the first frames only, extrapolated linearly per key",
        "speedup_write": round(insert_full_s / write_s, 1),
        "target_foreach_set_write_under_1s": write_s < 1.0,
        "blender": bpy.app.version_string, "machine": platform.processor() or platform.machine(),
    }, indent=2))  # fmt: skip


if __name__ == "__main__":
    main()

"""The README's "For animators" pictures: the DanceNet panel drawn headless (scripts/panel_screenshot.py)
after each new step, and a Workbench still of a DAZ-named A-pose rig dancing the shipped model.

Runs the real model: Part of the Song (frames 1-480) with a root bone and three takes on the NLA, Continue
From Here at frame 241, then a DAZ Genesis-like armature (its bone names, one of them renamed, a 45-degree
A-pose, twist bones) mapped by Auto (the renamed elbow by the skeleton's shape), danced, skinned with one
capsule per bone and rendered.

    .venv/bin/python scripts/animator_screenshots.py [--song examples/example_song.ogg] [--out docs/animators]
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

import bpy
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "scripts"), str(ROOT / "tests" / "addon")]

from doubles import convention_rest  # noqa: E402 (the DAZ-like rig the landing test builds)
from panel_screenshot import paint, record_panel, song_in_project  # noqa: E402

from dancenet_core import rigmap  # noqa: E402

DAZ_TWISTS = {"left_shoulder": "lShldrTwist", "right_shoulder": "rShldrTwist", "left_elbow": "lForearmTwist",
              "right_elbow": "rForearmTwist", "left_hip": "lThighTwist", "right_hip": "rThighTwist"}


BODY_RADIUS = (  # metres, by the first match in the bone's name: a mannequin's proportions
    (("Thumb", "Index", "Mid", "Ring", "Pinky", "Carpal", "Toe", "Metatarsal", "Jaw", "Eye", "Ear", "Tongue"), 0.012),
    (("hip", "pelvis", "abdomen", "chest"), 0.11), (("Thigh",), 0.07), (("Shin", "neck", "Collar"), 0.05),
    (("head",), 0.095), (("Shldr",), 0.045), (("Forearm", "ForeArm", "Elbow", "Foot"), 0.04), (("Hand",), 0.035),
)


def _radius(bone: str) -> float:
    return next((r for keys, r in BODY_RADIUS if any(k in bone for k in keys)), 0.03)


def skin_capsules(rig: bpy.types.Object) -> None:
    """A capsule along each bone from head to tail, rounded over both joints so that neighbours meet, weighted
    fully to it: a mannequin body on a rig that has no mesh, so the render reads as a figure."""
    verts, faces, groups = [], [], []
    for bone in rig.data.bones:
        head, tail = np.array(bone.head_local), np.array(bone.tail_local)
        axis = tail - head
        length = float(np.linalg.norm(axis))
        y = axis / length
        x = np.cross(y, [0.0, 0.0, 1.0] if abs(y[2]) < 0.9 else [1.0, 0.0, 0.0])
        x /= np.linalg.norm(x)
        z = np.cross(x, y)
        r = _radius(bone.name)
        base = len(verts)
        rings, segs = 8, 12  # half the rings cap the head, half the tail
        for i in range(rings + 1):
            phi = np.pi * i / rings
            end = head if i <= rings // 2 else tail
            for k in range(segs):
                th = 2 * np.pi * k / segs
                verts.append(end - y * r * np.cos(phi) + r * np.sin(phi) * (np.cos(th) * x + np.sin(th) * z))
        for i in range(rings):
            for k in range(segs):
                a, b = base + i * segs + k, base + i * segs + (k + 1) % segs
                faces.append((a, b, b + segs, a + segs))
        groups.append((bone.name, range(base, len(verts))))
    mesh = bpy.data.meshes.new(f"{rig.name} body")
    mesh.from_pydata([tuple(v) for v in verts], [], faces)
    mesh.shade_smooth()
    body = bpy.data.objects.new(mesh.name, mesh)
    bpy.context.scene.collection.objects.link(body)
    body.parent = rig
    for name, indices in groups:
        body.vertex_groups.new(name=name).add(list(indices), 1.0, "REPLACE")
    body.modifiers.new("Armature", "ARMATURE").object = rig


def facing_frame(scene: bpy.types.Scene, rig: bpy.types.Object, feet: tuple[str, str], frames: range) -> int:
    """The frame of `frames` where the dancer's feet point most toward the camera's side (-Y)."""

    def toward_camera(frame: int) -> float:
        scene.frame_set(frame)
        left, right = (rig.pose.bones[f] for f in feet)
        forward = rig.matrix_world.to_3x3() @ (left.tail - left.head + right.tail - right.head)
        return -forward.y / max(forward.length, 1e-6)

    return max(frames, key=toward_camera)


def aim_camera(scene: bpy.types.Scene, rig: bpy.types.Object, hips: str) -> None:
    """The camera 4 m in front of the dancer and a little to its side, 1 m up, aimed at its waist: the whole
    figure, head to feet, large in the frame."""
    target = rig.matrix_world @ rig.pose.bones[hips].head
    target.z = 0.9
    camera = scene.camera
    camera.location = (target.x + 1.3, target.y - 3.8, 1.0)
    camera.rotation_euler = (target - camera.location).to_track_quat("-Z", "Y").to_euler()
    camera.data.lens = 50


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--song", type=Path, default=ROOT / "examples" / "example_song.ogg")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "animators")
    args = parser.parse_args(argv)
    import blender_addon

    bpy.ops.wm.read_factory_settings(use_empty=True)
    blender_addon.register()
    args.out.mkdir(parents=True, exist_ok=True)
    scene = bpy.context.scene
    scene.render.fps = 24
    props = scene.dancenet

    def shot(name: str) -> None:
        image = paint(record_panel(bpy.context))
        image.save(args.out / name, optimize=True)
        print(f"animator_screenshots: {args.out / name} ({image.width}x{image.height})")

    project = Path(tempfile.mkdtemp(prefix="dancenet-animators-"))  # the panel shows //example_song.ogg
    props.music_source, props.music_file = "FILE", song_in_project(args.song, project)
    props.use_part, props.part_start, props.part_end = True, 1, 480
    props.root_motion, props.takes, props.seed = "root-bone", 3, 1
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    shot("1_part_root_takes.png")
    scene.frame_set(241)
    assert bpy.ops.dancenet.continue_dance() == {"FINISHED"}
    shot("2_continue.png")

    daz = rigmap.load_shipped("DAZ").bones
    rows = convention_rest(daz, a_pose_deg=45.0, splits=DAZ_TWISTS)
    # One bone renamed by hand, as rigs often have: Auto finds it by the skeleton's shape, and the panel says so.
    rows = [tuple("lElbow_custom" if x == "lForearmBend" else x for x in row[:2]) + row[2:] for row in rows]
    rig = blender_addon.rig.armature_from_rows(bpy.context, "Genesis 8 (DAZ names)", rows)
    rig.location = (1.5, 0.0, 0.0)
    props.target, props.armature, props.bone_map = "EXISTING", rig, "AUTO"
    props.root_motion, props.takes, props.show_matches = "travel", 1, True
    shot("3_foreign_rig.png")
    assert bpy.ops.dancenet.generate() == {"FINISHED"}

    skin_capsules(rig)
    for obj in list(bpy.data.objects):  # only the DAZ rig in the picture
        if obj.type in {"ARMATURE", "MESH"} and obj != rig and obj.parent != rig:
            obj.hide_render = True
    from blender_addon import render

    render.setup_preview(scene, rig, args.out / "unused.mp4", (640, 480), root_bone="hip")
    frame = facing_frame(scene, rig, ("lFoot", "rFoot"), range(100, 241))
    scene.frame_set(frame)
    aim_camera(scene, rig, "hip")
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = str(args.out / "4_daz_rig_dancing.png")
    bpy.ops.render.render(write_still=True)
    print(f"animator_screenshots: {args.out / '4_daz_rig_dancing.png'} (frame {frame})")
    blender_addon.unregister()
    shutil.rmtree(project)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

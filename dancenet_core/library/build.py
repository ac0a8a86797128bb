"""`dancenet library build FOLDER`: a folder of BVH clips read onto our skeleton and analysed into a motion library
(`library/store.py`), once per content of the folder.

A BVH clip is read when its skeleton is a humanoid's (`bvhclip.py`): the bone mapper the add-on drives rigs with
(`rigmap`) finds our joints in it by their names (Mixamo, VRM, Unreal, Character Creator, Rokoko, DAZ, MMD, Rigify,
generic names, CMU's, ours: the shipped bone maps) or by the skeleton's shape, and its motion is read like a rig's in
Blender (`jointmap.armature_pose`): any rest pose, any up axis and facing, in the unit that makes it a dancer's size.
An FBX clip is its armature's animation as Blender samples it (`library/fbx.py`: every bone's world matrices, in
metres, cached by the file's content): by worker processes with Blender's Python module on the command line, by the
add-on in Blender; the same mapper finds our joints among its bones (`ArmatureClip`, as for an action of the open
file that the add-on samples), and `armature_motion` reads them whatever the rig's rest pose. Without Blender's
module the command line leaves the FBX files out in one line and builds the rest.
Clips are resampled to the library's 25 fps and put on the floor (`floor.floor_track`). A clip's style is its
folder's name below FOLDER, or the `style` column of a `manifest.csv` in FOLDER (columns `file`, `style`, and
optionally `bpm` and `meter`: the clip's tempo and beats per bar, taken over what `analysis.py` reads from the
motion; `bonemap`: a bone map's JSON file in FOLDER for a skeleton Auto does not read, for the clip, or for every
clip on a row whose `file` is `*`).
Anything else in the folder is left out with a one-line note.

Torch-free and without the data package (the add-on's Build Library runs it inside Blender on a worker thread:
`progress` and `should_cancel`); only building imports it, never dancing.
"""

from __future__ import annotations

import multiprocessing as mp
import os
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, wait
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..bvh import read_bvh
from ..csvtable import read_rows
from ..environment import default_workers, end_with_parent, stop_pool
from ..errors import DanceNetError, GenerationCancelled, first_line
from ..jointmap import armature_pose, character_frame, rotation_motion, up_rotation
from ..kinematics import fk_numpy
from ..motion import Motion
from ..progress import StageProgress
from ..rigmap import BoneMap, auto_map, load_file, load_shipped
from ..rigmap.humanoid import mapped_humanoid
from ..shaping.floor import floor_track
from ..shaping.rootmotion import dance_joints, dance_motion
from ..skeleton import JOINT_INDEX
from . import fbx
from .analysis import ClipAnalysis, analyze_clip
from .bvhclip import bvh_rig
from .match import frames_of
from .store import LIBRARY_FPS, MotionLibrary, built_path, clip_files, library_path

MIN_CLIP_S = 1.0  # shorter clips hold no bar of any dance


def read_clip(path: Path, bone_map: BoneMap | None = None) -> Motion:
    """A BVH clip of the folder on our 55 joints: metres, Y up, 25 fps, feet on the floor; a one-line DanceNetError
    when its skeleton is no humanoid's (by `bone_map` if given, else by Auto: `bvhclip.bvh_rig`)."""
    return _bvh_clip(path, bone_map)[0]


def _bvh_clip(path: Path, bone_map: BoneMap | None) -> tuple[Motion, str]:
    """`read_clip`, and the convention its skeleton was read in (the bone map that read it). A clip of our own 55
    joints (`dancenet generate`'s BVH, the Dance with Melody dances) whose rest pose stands Y up and faces +Z, as
    ours does, is read as written, on its own bones: read as a rig's, onto our T-pose's bone directions, the Dance
    with Melody dancers' collars and shoulders turned 2 degrees and moved 5 mm."""
    data = read_bvh(path)
    joints = dance_joints(data) if bone_map is None else None
    if joints is not None:
        motion = dance_motion(data, joints, path.name)
        rest = motion.skeleton.rest_positions()
        if np.allclose(character_frame(*rest[[JOINT_INDEX[n] for n in ("left_hip", "right_hip", "pelvis", "neck")]]),
                       np.eye(3), atol=1e-3):  # its rest stands and faces as ours: its rotations are ours
            return _as_clip(_upright(motion), path.name), load_shipped("SMPLX").name
    rig = bvh_rig(path, bone_map, data)
    motion = rotation_motion(armature_pose(rig.joints, rig.rest, rig.pose, rig.fps, path.name))
    return _as_clip(motion, path.name), rig.convention


def _upright(motion: Motion) -> Motion:
    """The motion turned so that its up axis (head above pelvis) is +Y."""
    pos = fk_numpy(motion.skeleton, motion.rotations[::10], motion.root_positions[::10])[0]
    turn = up_rotation(pos, JOINT_INDEX["pelvis"], JOINT_INDEX["head"])
    if np.allclose(turn.as_matrix(), np.eye(3)):
        return motion
    rot = motion.rotations.copy()
    rot[:, 0] = (turn * Rotation.from_rotvec(rot[:, 0])).as_rotvec()
    root = turn.apply(motion.root_positions + motion.skeleton.offsets[0]) - motion.skeleton.offsets[0]
    return Motion(rot, root, motion.fps, motion.skeleton)


def _as_clip(motion: Motion, name: str) -> Motion:
    """A clip read onto our skeleton, as the library keeps it: at 25 fps, feet on the floor; a one-line
    DanceNetError when it is too short to hold a bar."""
    motion = motion.resampled(LIBRARY_FPS)
    if motion.duration < MIN_CLIP_S:
        raise DanceNetError(f"{name}: {motion.duration:.2f} s, too short to hold a bar")
    motion.root_positions[:, 1] -= floor_track(motion, body=True)  # floor work (hands, back) stays on the floor
    return motion


@dataclass
class ArmatureClip:
    """A rig's animation as the add-on samples it in Blender: our joints the rig has bones for (`joints`),
    each one's bone's world rest matrix [K, 4, 4] (`rest`) and world matrix per frame [T, K, 4, 4] (`pose`), at
    `fps`; see `jointmap.armature_pose`. `name` and `style` are the clip's in the library."""

    name: str
    style: str
    joints: list[int]
    rest: np.ndarray
    pose: np.ndarray
    fps: float
    bpm: float | None = None  # the clip's tempo and beats per bar where the user gave them (else read from motion)
    meter: int | None = None

    @classmethod
    def from_sample(cls, sample: fbx.RigSample, joints: Mapping[int, str], name: str, style: str,
                    bpm: float | None = None, meter: int | None = None) -> ArmatureClip:
        """The clip of a rig Blender sampled (an FBX file's or an action of the add-on's file): the bones that
        `joints` (our joint -> the rig's bone) name, in our joints' order, at the sample's frame rate."""
        order = sorted(joints)
        index = [sample.names.index(joints[j]) for j in order]
        return cls(name, style, order, sample.rest[index], sample.pose[:, index], sample.fps, bpm, meter)


def armature_motion(clip: ArmatureClip) -> Motion:
    """A rig's clip as a library clip, like a BVH's (`read_clip`): on a skeleton of the rig's bone lengths, at
    25 fps, feet on the floor; a one-line DanceNetError when it cannot be one."""
    return _as_clip(rotation_motion(armature_pose(clip.joints, clip.rest, clip.pose, clip.fps, clip.name)), clip.name)


@dataclass(frozen=True)
class ClipHints:
    """What a library's folder says of a clip: its style (its folder's name, or the manifest's `style`) and, from
    the manifest, its tempo (`bpm`) and beats per bar (`meter`), which the analysis takes over what it reads."""

    style: str = ""
    bpm: float | None = None
    meter: int | None = None
    bone_map: BoneMap | None = None  # the manifest's `bonemap` (else Auto reads the skeleton)


MANIFEST_BPM = (30.0, 300.0)
MANIFEST_METERS = (2, 3, 4, 6)


def _manifest_number(folder: Path, line: int, column: str, text: str) -> float | None:
    """A manifest cell as a number (None when empty); a one-line DanceNetError when it is none."""
    text = text.strip()
    if not text:
        return None
    lo, hi = MANIFEST_BPM
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if column == "bpm" and lo <= value <= hi:
        return value
    if column == "meter" and value in MANIFEST_METERS:
        return value
    want = f"beats per minute, {lo:g}-{hi:g}" if column == "bpm" else "beats per bar: 2, 3, 4 or 6"
    raise DanceNetError(f"{folder / 'manifest.csv'}, line {line}: {column} '{text}' is not {want}; correct it or "
                        "leave it empty to read it from the motion")


def clip_hints(folder: Path, files: list[Path]) -> dict[Path, ClipHints]:
    """Each clip's hints: the manifest's `style`, `bpm`, `meter` and `bonemap` for its `file` (the `bonemap` of a
    row whose file is `*` for every clip that names none), the style else the name of its folder below `folder`."""
    hints = {f: ClipHints(f.relative_to(folder).parts[0] if len(f.relative_to(folder).parts) > 1 else "")
             for f in files}
    manifest = folder / "manifest.csv"
    if manifest.is_file():
        for line, row in read_rows(manifest, "library manifest")[1]:
            path = folder / str(row.get("file") or "")
            bone_map = _manifest_map(folder, line, str(row.get("bonemap") or ""))
            if str(row.get("file") or "").strip() == "*":
                hints = {f: h if h.bone_map else replace(h, bone_map=bone_map) for f, h in hints.items()}
            if path not in hints:
                continue
            bpm = _manifest_number(folder, line, "bpm", str(row.get("bpm") or ""))
            meter = _manifest_number(folder, line, "meter", str(row.get("meter") or ""))
            hints[path] = ClipHints(str(row.get("style") or "").strip() or hints[path].style, bpm,
                                    None if meter is None else int(meter), bone_map or hints[path].bone_map)
    return hints


def _manifest_map(folder: Path, line: int, name: str) -> BoneMap | None:
    """The bone map a manifest cell names (None when empty); a one-line DanceNetError when it cannot be read."""
    if not name.strip():
        return None
    try:
        return load_file(folder / name.strip())
    except DanceNetError as e:
        raise DanceNetError(f"{folder / 'manifest.csv'}, line {line}: {first_line(e)}") from e


def is_fbx(path: Path) -> bool:
    return path.suffix.lower() == ".fbx"


def cached(path: Path, force: bool, report: Callable[[str], object]) -> MotionLibrary | None:
    """The library built before at `path`, if any (None: build it, also when that one is damaged, or when it
    left its FBX files out for want of Blender's module, which is there now)."""
    if path.is_file() and not force:
        try:
            library = MotionLibrary.load(path)
        except ValueError as e:
            report(f"rebuilding the library: {first_line(e)}")
            return None
        if not any(n.startswith(NO_BLENDER) for n in library.notes) or not fbx.bpy_installed():
            return library
    return None


NO_BLENDER = "left out the FBX files"  # a build without Blender's module says so in its notes


def build_library(folder: str | Path, force: bool = False, report: Callable[[str], object] = print,
                  progress: StageProgress | None = None, should_cancel: Callable[[], bool] | None = None,
                  fbx_samples: Mapping[Path, fbx.RigSample | str] | None = None,
                  workers: int | None = None, saved_maps: Path | None = None) -> tuple[MotionLibrary, Path]:
    """The library of `folder`, built now (or read from the cache when its content was built before). `progress`
    hears each clip as it is read; `should_cancel` stops the build between clips (GenerationCancelled, nothing
    written). FBX files are read from what Blender sampled of them: `fbx_samples` where the caller sampled them
    (the add-on in Blender: each file's sample, or why it has none, without the file's name), else by worker processes
    with Blender's module (`library/fbx.py`); without that module they are left out in one line. `saved_maps`: a
    folder of the user's bone maps that Auto tries on the FBX files' rigs too (the add-on's Save Bone Map). Clips
    are read by `workers` processes side by side (default `environment.default_workers`)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise DanceNetError(f"motion library folder not found: {folder} (give a folder of BVH clips)")
    path = library_path(folder)
    if (library := cached(path, force, report)) is not None:
        return library, path
    files = clip_files(folder)
    if not files:
        raise DanceNetError(f"no BVH clips in {folder}; put .bvh files in it (subfolders name their style; .fbx "
                            "files too, with Blender's module)")
    workers = default_workers() if workers is None else workers
    fbx_files = [f for f in files if is_fbx(f)]
    notes = []
    if fbx_files and fbx_samples is None and not fbx.bpy_installed():
        many = f"{len(fbx_files)} FBX file{'s' if len(fbx_files) > 1 else ''}"
        notes.append(f"{NO_BLENDER} ({many}: {fbx_files[0].name}...): reading them needs Blender's Python "
                     f"module: {fbx.INSTALL_HINT}")
        report(notes[-1])
        files = [f for f in files if not is_fbx(f)]
        if not files:
            raise DanceNetError(f"{folder} holds only FBX files, and reading them needs Blender's Python module: "
                                f"{fbx.INSTALL_HINT}")
    elif fbx_files and fbx_samples is None:
        count = iter(range(1, len(fbx_files) + 1))

        def sampled(f: Path) -> None:
            if progress is not None:
                progress(f"sampling {f.name}", next(count) / len(fbx_files))

        fbx_samples = fbx.sample_files(fbx_files, workers, sampled, should_cancel)
    if should_cancel is not None and should_cancel():
        raise GenerationCancelled
    hints = clip_hints(folder, files)
    clips, skeletons, left = _read_clips(
        [(f.name, str(f.relative_to(folder)), hints[f],
          partial(_fbx_clip, f, (fbx_samples or {}).get(f), hints[f], saved_maps) if is_fbx(f)
          else partial(_bvh_clip, f, hints[f].bone_map)) for f in files], report, progress, should_cancel, workers)
    notes += left
    if not clips:
        first = left[0].removeprefix("left out ")
        raise DanceNetError(f"none of the {len(files)} clips in {folder} could be read: {first}")
    return _saved(MotionLibrary.from_clips(clips, tuple(notes), skeletons), path), path


def _fbx_clip(path: Path, sampled: fbx.RigSample | str | None, hint: ClipHints, saved_maps: Path | None
              ) -> tuple[Motion, str]:
    """An FBX file's clip from what Blender sampled of it, and the convention its bones were read in: its bones
    mapped onto our joints (by the manifest's bone map, else Auto, with the user's `saved_maps` where given)."""
    if not isinstance(sampled, fbx.RigSample):
        raise DanceNetError(f"{path.name}: {sampled or 'not sampled in Blender'}")
    bones = sampled.rest_bones()
    bone_map = hint.bone_map or (auto_map(bones, path.name, saved_maps) if saved_maps is not None else None)
    convention, joints = mapped_humanoid(bones, path.name, bone_map)
    clip = ArmatureClip.from_sample(sampled, joints, path.name, hint.style, hint.bpm, hint.meter)
    return armature_motion(clip), convention


def _saved(library: MotionLibrary, path: Path) -> MotionLibrary:
    if library.unlabelled:  # the learned match dances it: its motion features computed once, here
        frames_of(library)
    path.parent.mkdir(parents=True, exist_ok=True)
    library.save(path)
    return library


def build_armature_library(clips: Sequence[ArmatureClip | str], key: str, notes: Sequence[str] = (),
                           force: bool = False, report: Callable[[str], object] = print,
                           progress: StageProgress | None = None,
                           should_cancel: Callable[[], bool] | None = None) -> tuple[MotionLibrary, Path]:
    """A library of rigs' clips (the add-on's "Armature actions in this file"), cached as `key` (a digest of
    what the clips were sampled from: `store.built_path`): each clip as sampled, or the line saying why it could
    not be; `notes` are what was no clip to begin with, one line each. As `build_library` otherwise."""
    path = built_path(key)
    if (library := cached(path, force, report)) is not None:
        return library, path
    if not clips:
        raise DanceNetError(f"no action animates a humanoid armature in this file{': ' + notes[0] if notes else ''}")
    done, skeletons, left = _read_clips(
        [("a clip", c, ClipHints(), partial(_not_sampled, c)) if isinstance(c, str)
         else (c.name, c.name, ClipHints(c.style, c.bpm, c.meter), partial(_rig_clip, c)) for c in clips],
        report, progress, should_cancel)
    if not done:
        raise DanceNetError(f"none of the {len(clips)} actions could be read: {left[0].removeprefix('left out ')}")
    return _saved(MotionLibrary.from_clips(done, tuple([f"left out {n}" for n in notes] + left), skeletons),
                  path), path


def _rig_clip(clip: ArmatureClip) -> tuple[Motion, str]:
    """A rig's clip of the open file, read by the rig's own bone map (the add-on's choice for it)."""
    return armature_motion(clip), "the rig's bone map"


def _not_sampled(why: str) -> tuple[Motion, str]:
    """A clip Blender could not sample: the line it gave."""
    raise DanceNetError(why)


def _read_clips(items: Sequence[tuple[str, str, ClipHints, Callable[[], tuple[Motion, str]]]],
                report: Callable[[str], object],
                progress: StageProgress | None, should_cancel: Callable[[], bool] | None, workers: int = 1
                ) -> tuple[list[tuple[str, str, Motion, ClipAnalysis]], list[str], list[str]]:
    """Each (shown name, clip name, hints, read) read and analysed, by `workers` processes side by side where
    there are several (forked: nothing is imported again), between cancel checks: the clips in order, the
    convention each one's skeleton was read in, and a "left out ..." line (also reported) for each that could not
    be read."""
    results: list[tuple[str, str, Motion, ClipAnalysis] | str] = []
    if workers > 1 and len(items) > 1 and "fork" in mp.get_all_start_methods():
        pool = ProcessPoolExecutor(min(workers, len(items)), mp_context=mp.get_context("fork"),
                                   initializer=end_with_parent, initargs=(os.getpid(),))
        try:
            futures = [pool.submit(_read_one, item) for item in items]
            for i, future in enumerate(futures):
                while not future.done():
                    if should_cancel is not None and should_cancel():
                        raise GenerationCancelled
                    wait([future], timeout=0.1)
                if progress is not None:
                    progress(f"reading {items[i][0]}", (i + 1) / len(items))
                results.append(future.result())
        finally:
            stop_pool(pool) if len(results) < len(items) else pool.shutdown()
    else:
        for i, item in enumerate(items):
            if should_cancel is not None and should_cancel():
                raise GenerationCancelled
            if progress is not None:
                progress(f"reading {item[0]}", i / len(items))
            results.append(_read_one(item))
    clips, skeletons, notes = [], [], []
    for r in results:
        if isinstance(r, str):
            notes.append(r)
            report(r)
        else:
            clips.append(r[0])
            skeletons.append(r[1])
    return clips, skeletons, notes


def _read_one(item: tuple[str, str, ClipHints, Callable[[], tuple[Motion, str]]]
              ) -> tuple[tuple[str, str, Motion, ClipAnalysis], str] | str:
    """A clip read and analysed with the convention its skeleton was read in, or the "left out ..." line saying why
    it could not be."""
    _shown, name, hint, read = item
    try:
        motion, skeleton = read()
    except DanceNetError as e:
        return f"left out {first_line(e)}"
    return (name, hint.style, motion, analyze_clip(motion, hint.style, bpm=hint.bpm, meter=hint.meter)), skeleton

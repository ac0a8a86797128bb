"""Test doubles and fixtures data for the Blender add-on tests (no tests here; no bpy import).

`fake_generate_dance` stands in for dancenet_core.generate.generate_dance until the end-to-end test
runs the real model: same signature, same GenerationResult, a real Motion of smooth synthetic
rotations as long as the song, progress reports and cancellation.
"""

from __future__ import annotations

import math
import time
import wave
from collections.abc import Callable
from pathlib import Path

import numpy as np

from dancenet_core.errors import GenerationCancelled
from dancenet_core.generate import GenerationResult
from dancenet_core.motion import Motion
from dancenet_core.progress import StageProgress
from dancenet_core.request import DanceRequest
from dancenet_core.skeleton import DEFAULT_SKELETON

FAKE_STYLES = ["ballet", "hiphop", "jazz"]
FAKE_FPS = 30.0
FAKE_TEMPO = 120.0
# The keyword arguments of every fake generation, oldest first (tests read what the add-on asked for).
CALLS: list[dict] = []


def write_song(path: Path, seconds: float = 2.0, rate: int = 22050) -> Path:
    """A mono 16-bit WAV: a 440 Hz tone with a click every half second (120 BPM)."""
    t = np.arange(int(seconds * rate)) / rate
    signal = 0.2 * np.sin(2 * np.pi * 440 * t) + 0.6 * (np.mod(t, 0.5) < 0.01)
    with wave.open(str(path), "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(rate)
        w.writeframes((np.clip(signal, -1, 1) * 32767).astype("<i2").tobytes())
    return path


def song_seconds(path: Path) -> float:
    with wave.open(str(path), "rb") as w:
        return w.getnframes() / w.getframerate()


def synthetic_motion(seconds: float, seed: int, fps: float = FAKE_FPS) -> Motion:
    """Smooth sinusoidal joint rotations (up to ~0.6 rad), a bobbing, swaying, turning root."""
    rng = np.random.default_rng(seed)
    n = max(2, round(seconds * fps))
    t = np.arange(n)[:, None, None] / fps
    amp = rng.uniform(-0.6, 0.6, (1, DEFAULT_SKELETON.num_joints, 3))
    freq = rng.uniform(0.3, 1.2, (1, DEFAULT_SKELETON.num_joints, 3))
    phase = rng.uniform(0, 2 * np.pi, (1, DEFAULT_SKELETON.num_joints, 3))
    rotations = amp * np.sin(2 * np.pi * freq * t + phase)
    rotations[:, 0] = 0.0
    rotations[:, 0, 1] = 0.8 * t[:, 0, 0]  # slow turn about +Y
    tt = t[:, 0, 0]
    root = np.stack(
        [0.3 * np.sin(tt), DEFAULT_SKELETON.rest_pelvis_height() + 0.04 * np.sin(4 * tt), 0.2 * tt], axis=-1
    )
    return Motion(rotations, root, fps)


def make_fake_generator(step_delay: float = 0.0, steps: int = 10) -> Callable[..., GenerationResult]:
    """A generate_dance stand-in; `step_delay` seconds per progress step (for the cancel test)."""

    def fake_generate_dance(request: DanceRequest, progress: StageProgress | None = None,
                            should_cancel: Callable[[], bool] | None = None) -> GenerationResult:
        CALLS.append(vars(request))
        song, style, seed, start_s, end_s = request.song, request.style, request.seed, request.start_s, request.end_s
        continue_from, at_s = request.continue_from, request.at_s
        end = song_seconds(Path(song)) if end_s is None else min(end_s, song_seconds(Path(song)))
        seconds = end - start_s
        for k in range(steps):
            if should_cancel is not None and should_cancel():
                raise GenerationCancelled
            if progress is not None:
                progress("dancing", k / steps)
            time.sleep(step_delay)
        probabilities = {"hiphop": 0.7, "jazz": 0.2, "ballet": 0.1}
        chosen = max(probabilities, key=probabilities.get) if style == "auto" else style
        beats = np.arange(0.0, end, 60.0 / FAKE_TEMPO)
        beats = beats[beats >= start_s] - start_s
        motions = [synthetic_motion(seconds, 1000 * seed + k) for k in range(request.takes)]
        if continue_from is not None:  # the kept frames, then the new dance (no care for the join: a stand-in)
            j = round(at_s * FAKE_FPS)
            kept = continue_from.resampled(FAKE_FPS)
            motions = [Motion(np.concatenate([kept.rotations[:j], m.rotations[j:]]),
                              np.concatenate([kept.root_positions[:j], m.root_positions[j:]]), FAKE_FPS)
                       for m in motions]
        return GenerationResult(
            motions=motions,
            beat_times=beats,
            downbeat_times=beats[::4],
            tempo_bpm=FAKE_TEMPO,
            duration_s=seconds,
            style=chosen,
            style_probabilities=probabilities if style == "auto" else {},
            timings={"fake_s": steps * step_delay},
            start_s=start_s,
        )

    return fake_generate_dance


def _armature_bones(skeleton, pos: np.ndarray, names: dict[str, str], main: dict[str, str]):
    """(bone, parent bone | None, head, tail) for the joints in `names`, tails at the main child."""
    bones = []
    for joint, bone in names.items():
        j = skeleton.index(joint)
        kids = [c for c in skeleton.children(j) if skeleton.names[c] in names]
        child = skeleton.index(main[joint]) if joint in main else (kids[0] if kids else None)
        p = skeleton.parents[j]
        tail = pos[child] if child is not None else pos[j] + (pos[j] - pos[p]) * 0.8
        bones.append((bone, names[skeleton.names[p]] if p >= 0 else None, pos[j], tail))
    return bones


def mixamo_rest(prefix: str = "mixamorig:", scale: float = 0.9, a_pose_deg: float = 40.0):
    """A Mixamo-like skeleton in an A-pose: (bone name, parent name | None, head, tail) in centimetres, Y up.

    Shaped after our skeleton (scaled by `scale`), arms lowered by `a_pose_deg`, with an unmapped
    HeadTop_End leaf and only the index finger, as some Mixamo downloads have.
    """
    from dancenet_core.kinematics import fk_numpy

    s = DEFAULT_SKELETON.scaled(scale)
    rot = np.zeros((s.num_joints, 3))
    a = math.radians(a_pose_deg)
    rot[s.index("left_shoulder")] = (0.0, 0.0, -a)
    rot[s.index("right_shoulder")] = (0.0, 0.0, a)
    pos = fk_numpy(s, rot, np.array([0.0, s.rest_pelvis_height(), 0.0]))[0] * 100.0
    names = {"pelvis": "Hips", "spine1": "Spine", "spine2": "Spine1", "spine3": "Spine2", "neck": "Neck",
             "head": "Head"}  # fmt: skip
    for side, cap in (("left", "Left"), ("right", "Right")):
        names.update({
            f"{side}_hip": f"{cap}UpLeg", f"{side}_knee": f"{cap}Leg", f"{side}_ankle": f"{cap}Foot",
            f"{side}_foot": f"{cap}ToeBase", f"{side}_collar": f"{cap}Shoulder",
            f"{side}_shoulder": f"{cap}Arm", f"{side}_elbow": f"{cap}ForeArm", f"{side}_wrist": f"{cap}Hand",
            f"{side}_index1": f"{cap}HandIndex1", f"{side}_index2": f"{cap}HandIndex2",
            f"{side}_index3": f"{cap}HandIndex3",
        })  # fmt: skip
    names = {j: prefix + b for j, b in names.items()}
    main = {"pelvis": "spine1", "spine3": "neck", "left_wrist": "left_index1", "right_wrist": "right_index1"}
    bones = _armature_bones(s, pos, names, main)
    head = pos[s.index("head")]
    bones.append((prefix + "HeadTop_End", prefix + "Head", head + (0, 18.0, 0), head + (0, 28.0, 0)))
    return bones


def rigify_rest(bone_map: dict[str, str], scale: float = 1.05):
    """A Rigify-like deform skeleton, Z up in metres, T-pose, named by `bone_map` (the shipped Rigify map).

    Adds what a generated rig has around the mapped bones: a `root` parent and the unmapped upper-neck
    bone DEF-spine.005 between the neck and the head.
    """
    s = DEFAULT_SKELETON.scaled(scale)
    z_up = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    pos = (s.rest_positions() + (0.0, s.rest_pelvis_height(), 0.0)) @ z_up.T
    main = {"pelvis": "spine1", "spine3": "neck"} | {f"{x}_wrist": f"{x}_middle1" for x in ("left", "right")}
    reparent = {bone_map["pelvis"]: "root", bone_map["head"]: "DEF-spine.005"}
    bones = [(b, reparent.get(b, p), h, t) for b, p, h, t in _armature_bones(s, pos, bone_map, main)]
    neck, head = pos[s.index("neck")], pos[s.index("head")]
    return [
        ("root", None, np.zeros(3), np.array([0.0, 0.3, 0.0])),
        *bones,
        ("DEF-spine.005", bone_map["neck"], (neck + head) / 2, head),
    ]


def convention_rest(bones: dict[str, str | list[str]], scale: float = 1.0, a_pose_deg: float = 0.0,
                    arm_scale: float = 1.0, leg_scale: float = 1.0, root: str | None = None,
                    splits: dict[str, str] | None = None, names: dict[str, str] | None = None, skeleton=None):
    """An armature as another tool makes it, Z up in metres: (bone, parent | None, head, tail) rows.

    Shaped after `skeleton` (ours by default; scaled; arms and legs stretched by their own factors, so the rig's
    proportions are not ours), arms lowered by `a_pose_deg`, bones named by the first name of each joint
    in `bones` (or `names`), a `root` bone on the floor above the hips if named, and `splits`: joint ->
    an extra bone halfway to its main child (a twist or in-between spine bone), as those rigs have.
    """
    from dancenet_core.kinematics import fk_numpy

    offsets = (skeleton or DEFAULT_SKELETON).offsets.copy()
    for j, n in enumerate(DEFAULT_SKELETON.names):
        if any(k in n for k in ("elbow", "wrist", "shoulder")):
            offsets[j] *= arm_scale
        if any(k in n for k in ("knee", "ankle")):
            offsets[j] *= leg_scale
    s = type(DEFAULT_SKELETON)(offsets * scale)
    rot = np.zeros((s.num_joints, 3))
    a = math.radians(a_pose_deg)
    rot[s.index("left_shoulder")], rot[s.index("right_shoulder")] = (0.0, 0.0, -a), (0.0, 0.0, a)
    pos = fk_numpy(s, rot, np.array([0.0, s.rest_pelvis_height(), 0.0]))[0]
    pos = pos @ np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]).T
    names = names or {j: (b if isinstance(b, str) else b[0]) for j, b in bones.items()}
    main = {"pelvis": "spine1", "spine3": "neck"} | {f"{x}_wrist": f"{x}_middle1" for x in ("left", "right")}
    rows = _armature_bones(s, pos, names, main)
    for joint, extra in (splits or {}).items():
        j = s.index(joint)
        child = s.index(main.get(joint) or next(s.names[c] for c in s.children(j) if s.names[c] in names))
        mid = (pos[j] + pos[child]) / 2
        rows = [(b, extra if b == names[s.names[child]] else p, h, t) for b, p, h, t in rows]
        rows.append((extra, names[joint], mid, pos[child]))
    if root is not None:
        rows = [(b, root if b == names["pelvis"] else p, h, t) for b, p, h, t in rows]
        rows.insert(0, (root, None, np.zeros(3), np.array([0.0, 0.3, 0.0])))
    return rows

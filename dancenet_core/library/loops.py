"""Clips that loop: a clip whose last pose meets its first (a Mixamo download, a game's dance loop) is danced around
the loop, its copies laid end to end as the dancer would go on, so that the plan can dance more bars of it than it
holds and cut anywhere in it, and its tempo is read from several turns of it instead of one.

A loop is told by its seam: the body's pose (joints relative to the pelvis, in the dancer's heading frame) one step
on from the last frame against the first (or, where the last frame repeats the first, as many exporters write it,
from the frame before the last). Each copy is turned about +Y and shifted on the floor so that it
goes on from the one before: from where that one's last frame stands (or would step to next), facing its way,
so a loop that travels or turns goes on travelling and turning.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from ..motion import Motion
from ..representation import heading
from ..skeleton import BODY_JOINTS
from .analysis import ClipAnalysis, analyze_clip, heading_local

# A seam loops when the pose one step across it is where the clip's last (or first) step leads, within this many of
# its typical changes of step and this much (RMS over the body joints relative to the pelvis, heading frame)
SEAM_ACCELERATIONS = 2.0
LOOP_POSE_M = 0.005
REPEAT_M = 0.002  # a last frame this close to the first repeats it
LOOP_MIN_S = 16.0  # a loop is laid end to end at least this long (at least twice)
LOOP_MAX_COPIES = 16


def _body(motion: Motion) -> np.ndarray:
    """Body joints relative to the pelvis in the heading frame [T, J, 3]."""
    pos = motion.positions()[:, :BODY_JOINTS]
    return heading_local(pos - pos[:, :1], heading(motion.rotations[:, 0]))


def loop_period(motion: Motion) -> int | None:
    """The frames of one turn of the loop (T, or T - 1 where the last frame repeats the first), or None where the
    clip does not loop: the pose one step on from the last frame (carried on by its last step) is the first, and
    one step back from the first is the last, within `SEAM_ACCELERATIONS` times the clip's typical change of step
    (its median, so that a capture's frame-to-frame noise counts as the clip's own) and `LOOP_POSE_M`."""
    if motion.num_frames < 8:
        return None
    pose = _body(motion)

    def rms(x: np.ndarray) -> np.ndarray:
        return np.sqrt((x**2).sum(-1).mean(-1))

    period = motion.num_frames - 1 if rms(pose[-1] - pose[0]) < REPEAT_M else motion.num_frames
    pose = pose[:period]
    typical = float(np.median(rms(pose[2:] - 2 * pose[1:-1] + pose[:-2])))
    seam = max(float(rms(pose[0] - 2 * pose[-1] + pose[-2])), float(rms(pose[-1] - 2 * pose[0] + pose[1])))
    return period if seam <= SEAM_ACCELERATIONS * typical + LOOP_POSE_M else None


def around_loop(motion: Motion, period: int) -> tuple[Motion, int]:
    """The loop's turns (`period` frames each) laid end to end, each going on from the one before, at least
    `LOOP_MIN_S` long and twice; and how many turns."""
    turns = int(np.clip(np.ceil(LOOP_MIN_S / (period / motion.fps)), 2, LOOP_MAX_COPIES))
    rot, root = motion.rotations[:period], motion.root_positions[:period]
    rots, roots = [rot], [root]
    yaw0 = float(heading(rot[:1, 0])[0])
    for _ in range(turns - 1):
        # the next turn starts one step on from the last frame (which is where a repeated last frame stood)
        yaw = heading(rots[-1][-2:, 0])
        turn_to = float(yaw[1] + np.angle(np.exp(1j * (yaw[1] - yaw[0]))))
        at = 2 * roots[-1][-1] - roots[-1][-2]
        r = Rotation.from_euler("y", turn_to - yaw0)
        placed = rot.copy()
        placed[:, 0] = (r * Rotation.from_rotvec(rot[:, 0])).as_rotvec()
        moved = r.apply(root - root[0]) + np.array([at[0], root[0, 1], at[2]])
        rots.append(placed)
        roots.append(moved)
    return Motion(np.concatenate(rots), np.concatenate(roots), motion.fps, motion.skeleton), turns


def danced_around(clip: tuple[str, str, Motion, ClipAnalysis]) -> tuple[str, str, Motion, ClipAnalysis]:
    """A library clip (name, style, motion, analysis) as the library keeps it: a loop shorter than `LOOP_MIN_S`
    laid end to end (`around_loop`) and analysed again over its turns (the tempo and meter the user gave kept), its
    source saying so; any other clip as it is (a long one holds bars enough to dance and to read)."""
    name, style, motion, analysis = clip
    if analysis.source == "music" or motion.duration >= LOOP_MIN_S:
        return clip
    period = loop_period(motion)
    if period is None:
        return clip
    looped, turns = around_loop(motion, period)
    given = analysis.source.startswith("tempo: manifest")
    again = analyze_clip(looped, style, bpm=analysis.tempo_bpm if given else None,
                         meter=analysis.meter if "meter: manifest" in analysis.source else None)
    return name, style, looped, replace(again, source=f"{again.source}; a loop of {period / motion.fps:.1f} s, "
                                                      f"danced {turns} times round")

"""Where the floor is under a dancer, from the lowest toe end (or, for a motion library's clips, the body's lowest
point): a constant height for a clip (`floor_offset`, the dataset fits), a height per frame that follows a
capture's drift (`floor_track`, the paired dataset and a motion library's clips) or a generated dance's own
contacts (`floor_shift`, the last step of generation). Torch-free: a library build in Blender uses it."""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d, minimum_filter1d

from ..kinematics import fk_numpy
from ..motion import Motion
from ..skeleton import BODY_JOINTS, TOE_ENDS


def floor_offset(motion: Motion) -> float:
    """Height of the floor under this clip: a low percentile of the lower toe end."""
    toes = motion.end_effectors()[:, list(TOE_ENDS), 1].min(axis=1)
    return float(np.percentile(toes, 2))


def lowest_point(motion: Motion) -> np.ndarray:
    """The height [T] of the body's lowest point, its body joints and end sites: a toe when the dancer stands, a
    hand, a knee, the back or the head in floor work. The finger joints are left out: a hand on the floor is its
    palm (the hand's end site), and captures track fingers poorly (the Dance with Melody rumbas' reach 2-7 cm under
    the standing dancer's toes)."""
    pos, _, ends = fk_numpy(motion.skeleton, motion.rotations, motion.root_positions, with_end_sites=True)
    return np.minimum(pos[:, :BODY_JOINTS, 1].min(axis=1), ends[..., 1].min(axis=1))


def floor_track(motion: Motion, window_s: float = 2.0, smooth_s: float = 0.5, body: bool = False) -> np.ndarray:
    """The floor's height under the dancer, frame by frame [T].

    Most captures drift upward by 0.2-0.5 m over a minute (the toes of a waltz end up 0.4 m above where
    they started). A ballroom dancer has a foot on the floor within any two seconds, so the lowest toe
    end over a 2-s window, smoothed, follows the floor; subtracting it removes the drift. With `body` (a motion
    library's clips, which may hold floor work: freezes, head spins, a hand or the back on the floor) the lowest
    point of the whole body (`lowest_point`) stands for the toes: a dancer on their hands is still on the floor.
    The paired dataset keeps the toes, which DanceNet's foot clean-up and contacts are measured from.
    """
    low = lowest_point(motion) if body else motion.end_effectors()[:, list(TOE_ENDS), 1].min(axis=1)
    low = minimum_filter1d(low, size=max(1, int(window_s * motion.fps)), mode="nearest")
    return gaussian_filter1d(low, smooth_s * motion.fps, mode="nearest")


def floor_lift(low: np.ndarray) -> np.ndarray:
    """Root lift [T] (metres) that keeps the lowest point `low` [T] (a toe end, or the body's `lowest_point`) at or
    above the floor (y = 0): the dip, widened and smoothed so the lift eases in and out rather than jerking, and
    never less than the dip."""
    need = np.maximum(0.0, -low)
    return np.maximum(need, gaussian_filter1d(maximum_filter1d(need, 9), 2.0, mode="nearest"))


def toe_ends(motion: Motion) -> np.ndarray:
    """World positions [T, 2, 3] of the toe ends (left, right), by the forward kinematics of the body alone
    (`Skeleton.feet`)."""
    return fk_numpy(motion.skeleton.feet(), motion.rotations[:, :BODY_JOINTS], motion.root_positions,
                    with_end_sites=True)[2]


def contact_floor(toes: np.ndarray, contacts: np.ndarray, fps: float, window_s: float = 2.0,
                  smooth_s: float = 0.5) -> np.ndarray:
    """The floor's height under a generated dance, frame by frame [T], from its toe ends' heights [T, 2] and its
    predicted contacts [T, 2].

    A planted toe (contact predicted) is on the floor: the floor over a 2-s window is the lowest planted toe in
    it, or the lowest toe of any frame where the model predicts no contact in the whole window; smoothed as
    `floor_track`, so the correction is a slow rise and fall of the whole body, never a jolt.
    """
    planted = np.where(np.asarray(contacts) > 0.5, toes, np.inf).min(axis=1)
    size = max(1, int(window_s * fps))
    low = minimum_filter1d(planted, size=size, mode="nearest")
    any_low = minimum_filter1d(toes.min(axis=1), size=size, mode="nearest")
    return gaussian_filter1d(np.where(np.isfinite(low), low, any_low), smooth_s * fps, mode="nearest")


def floor_shift(motion: Motion, contacts: np.ndarray) -> np.ndarray:
    """Height change of the root [T] (metres) that stands a generated dance's planted feet on the floor (y = 0),
    frame by frame, and lifts it where a toe would still go through the floor. Only the root's height is to
    change: the pose and the path on the floor are kept.

    Why: the network's pelvis height wanders a few centimetres from its legs' length (the Latin dances hovered,
    never a toe within 3 cm of the floor in 2 s), and the foot model only ever lifts."""
    toes = toe_ends(motion)[:, :, 1]
    shift = -contact_floor(toes, contacts, motion.fps)
    return shift + floor_lift((toes + shift[:, None]).min(axis=1))

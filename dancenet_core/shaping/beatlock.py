"""The beat lock: a dance's own beats moved onto its song's beats by a time-warp, played within the library engine's
real-time limit.

Why: DanceNet hears the beat and onset features, but the motion history drowns them out: its dances score a Beat
Align Score about as high against other songs' beats as against their own. After sampling, the dance's beats (the
kinematic beats the Beat Align Score counts, `beats.motion_beats`) are paired with the song's beats and the dance
is played faster or slower between them, piecewise linearly as the library engine lays its figures on the beats,
so that each paired dance beat lands on its song beat. No frame plays more than `constants.WARP_RANGE` faster or
slower than danced, the dance keeps its length, its first and last frames (and the frames a continued dance keeps),
and its path across the floor. It runs on the model's features, before the foot clean-up, which then holds the
warped dance's feet.

The pairing is dynamic programming over (song beat, dance beat) pairs no further apart than `REACH_BEATS` of the
song's beat interval: the chain of pairs that the speed limit allows from the first kept frame to the last frame
with the most pairs (a nearer pair wins a tie).
"""

from __future__ import annotations

import numpy as np

from ..beats import motion_beats
from ..constants import WARP_RANGE
from ..kinematics import fk_numpy
from ..representation import FeatureLayout, decode, heading_frames, root_steps
from ..series import interp_frames
from ..skeleton import BODY_JOINTS, Skeleton

# A dance beat is paired with a song beat at most this share of the song's median beat interval away: half an
# interval pairs each dance beat with its nearest song beat at most.
REACH_BEATS = 0.5
NEAR_WEIGHT = 0.1  # a pair's score: 1 less this much per unit of its distance over the reach (a nearer pair wins)


def beat_warp(dance_beats: np.ndarray, song_beats: np.ndarray, frames: int, keep: int = 0,
              max_warp: float = WARP_RANGE, reach_beats: float = REACH_BEATS) -> np.ndarray:
    """The source frame (fractional) [frames] of each frame of the warped dance: the identity up to frame `keep`,
    then piecewise linear through the chosen (song beat, dance beat) pairs to the last frame, every piece's speed
    within 1 +- `max_warp`. `dance_beats` are source frames, `song_beats` frames of the warped dance (fractional)."""
    out = np.arange(frames, dtype=np.float64)
    last = frames - 1
    song = np.asarray(song_beats, np.float64)
    if len(song) < 2 or last - keep < 2:
        return out
    reach = reach_beats * float(np.median(np.diff(song)))
    dance = np.asarray(dance_beats, np.float64)
    song = song[(song > keep) & (song < last)]
    dance = dance[(dance > keep) & (dance < last)]
    if len(song) == 0 or len(dance) == 0:
        return out
    j, k = np.nonzero(np.abs(song[:, None] - dance[None, :]) <= reach)
    o = np.r_[keep, song[j], last]  # nodes: the start, the pairs by song beat, the end
    s = np.r_[keep, dance[k], last]
    gain = np.r_[0.0, 1.0 - NEAR_WEIGHT * np.abs(o[1:-1] - s[1:-1]) / max(reach, 1e-9), 0.0]
    best = np.full(len(o), -np.inf)
    back = np.zeros(len(o), dtype=np.int64)
    best[0] = 0.0
    for q in range(1, len(o)):
        do, ds = o[q] - o[:q], s[q] - s[:q]
        ok = (do > 0) & (ds >= (1 - max_warp) * do - 1e-9) & (ds <= (1 + max_warp) * do + 1e-9) & np.isfinite(best[:q])
        if ok.any():
            p = int(np.argmax(np.where(ok, best[:q], -np.inf)))
            best[q], back[q] = best[p] + gain[q], p
    chain = [len(o) - 1]  # the end is always reached: straight from the start at the dance's own speed, if no pair
    while chain[-1] != 0:
        chain.append(int(back[chain[-1]]))
    chain.reverse()
    out[keep:] = np.interp(out[keep:], o[chain], s[chain])
    return out


def lock_to_beats(feats: np.ndarray, fps: float, skeleton: Skeleton, song_beats_s: np.ndarray, keep: int = 0,
                  max_warp: float = WARP_RANGE, reach_beats: float = REACH_BEATS) -> tuple[np.ndarray, np.ndarray]:
    """A dance's features [T, D] (`representation.py`) time-warped so that its beats land on `song_beats_s`
    (seconds from its first frame), its frames up to `keep` as they are, and the source frame of every frame [T].

    Every channel is sampled linearly at the warped times (the model makes them as continuous channels, and its
    output smoothing treats them so), but the root's steps and turns, which count per frame, are taken from its path
    and heading sampled at those times, so the dance crosses the floor as it did; contacts are their nearest
    frame's."""
    motion = decode(feats, fps, skeleton)
    body = fk_numpy(skeleton, motion.rotations, motion.root_positions, joints=BODY_JOINTS)[0]
    src = beat_warp(motion_beats(body, fps), np.asarray(song_beats_s) * fps, len(feats), keep, max_warp, reach_beats)
    layout = FeatureLayout.for_skeleton(skeleton)
    out = interp_frames(feats, src).astype(feats.dtype)
    root, yaw = interp_frames(motion.root_positions, src), interp_frames(heading_frames(motion), src)
    out[:, [0, 2, 3]] = root_steps(root, yaw)
    out[:, layout.contacts] = feats[np.round(src).astype(int), layout.contacts]
    return out, src

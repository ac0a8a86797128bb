"""One clip's musical structure, read from its motion alone: its beats, tempo, bars and what a cut at each beat
has to match (pose, velocity, foot contact).

Beats are kinematic beats (the dancer's speed minima, `beats.py`), tracked as Ellis' dynamic-programming beat
tracker does for audio onsets: the tempo from the autocorrelation of the speed's dips (a log-normal preference
around 110 BPM, as librosa's), then the beat sequence that best trades dip depth against even spacing. The meter
(3 or 4 beats per bar) is the one whose two-bar lag repeats the pose best, unless the clip's style names one; the
downbeat is the phase whose beats start the most energetic steps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..beats import BAS_SMOOTH_S, kinematic_velocity, local_minima
from ..kinematics import fk_numpy
from ..motion import Motion
from ..representation import foot_contacts, heading_frames
from ..skeleton import BODY_JOINTS, TOE_ENDS

MIN_BPM, MAX_BPM = 50.0, 200.0
PRIOR_BPM, PRIOR_OCTAVES = 110.0, 1.0  # the tempo prior: log-normal around 110 BPM, one octave wide
TIGHTNESS = 100.0  # Ellis' (and librosa's) weight on even beat spacing
TREND_S = 0.6  # the speed's slow trend, removed so that dips count against their surroundings
STYLE_METER = {"waltz": 3}  # styles whose bars are known; others are read from the motion
POSE_DIM = BODY_JOINTS * 3
FEATURE_DIM = 2 * POSE_DIM + 2  # pose, velocity, foot contacts


@dataclass
class ClipAnalysis:
    """beats: frame positions (sub-frame) of the clip's beats; downbeat: [B] bool, first beat of a bar;
    features: [B, FEATURE_DIM] at each beat: body joints relative to the pelvis in the dancer's heading frame (m),
    their velocities in that frame (m/s), left and right foot contact; energy: [B] mean joint speed (m/s) from
    each beat to the next (the last: to the clip's end)."""

    beats: np.ndarray
    downbeat: np.ndarray
    tempo_bpm: float
    meter: int
    features: np.ndarray
    energy: np.ndarray


def heading_local(vectors: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Vectors [T, ..., 3] turned by -yaw about +Y, so that the dancer's heading is the same in every frame."""
    c, s = np.cos(yaw), np.sin(yaw)
    shape = (-1,) + (1,) * (vectors.ndim - 2)
    c, s = c.reshape(shape), s.reshape(shape)
    x, z = vectors[..., 0], vectors[..., 2]
    return np.stack([c * x - s * z, vectors[..., 1], s * x + c * z], axis=-1)


def frame_features(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Per frame: the boundary features [T, FEATURE_DIM] and the mean joint speed [T] (m/s)."""
    pos, _, ends = fk_numpy(motion.skeleton, motion.rotations, motion.root_positions, with_end_sites=True)
    body = pos[:, :BODY_JOINTS]
    yaw = heading_frames(motion)
    vel = np.gradient(body, axis=0) * motion.fps if len(body) > 1 else np.zeros_like(body)
    pose = heading_local(body - body[:, :1], yaw)
    contacts = foot_contacts(ends[:, list(TOE_ENDS)], motion.fps, floor=0.0)
    feats = np.concatenate([pose.reshape(len(body), -1), heading_local(vel, yaw).reshape(len(body), -1), contacts],
                           axis=1)
    return feats.astype(np.float32), kinematic_velocity(body) * motion.fps


def dip_train(speed: np.ndarray, fps: float) -> np.ndarray:
    """How deep each speed minimum dips below the speed's slow trend, at the minimum's frame (0 elsewhere),
    lightly smoothed: the motion's onset envelope, with one pulse per step."""
    v = gaussian_filter1d(speed, BAS_SMOOTH_S * fps)
    depth = np.zeros_like(v)
    at = local_minima(v)
    depth[at] = np.maximum(gaussian_filter1d(speed, TREND_S * fps)[at] - v[at], 0.0)
    return gaussian_filter1d(depth, 1.0)


def tempo_period(dips: np.ndarray, fps: float) -> float:
    """The beat period in frames: the highest autocorrelation peak of the dip train, weighted by the tempo
    prior (peaks only: the lobe around lag 0 is not a tempo)."""
    lags = np.arange(1, int(np.ceil(fps * 60 / MIN_BPM)) + 2)
    lags = lags[lags < len(dips) - 1]
    x = dips - dips.mean()
    ac = np.array([np.dot(x[:-lag], x[lag:]) / (len(x) - lag) for lag in lags])
    prior = np.exp(-0.5 * (np.log2(fps * 60 / lags / PRIOR_BPM) / PRIOR_OCTAVES) ** 2)
    peaks = local_minima(-ac)
    peaks = peaks[(lags[peaks] >= fps * 60 / MAX_BPM) & (lags[peaks] <= fps * 60 / MIN_BPM)] if len(peaks) else peaks
    if len(peaks) == 0:
        return fps * 60 / PRIOR_BPM
    k = int(peaks[np.argmax(ac[peaks] * prior[peaks])])
    a, b, c = ac[k - 1 : k + 2]
    den = a - 2 * b + c  # parabolic peak: a tempo between whole-frame lags
    return float(lags[k] + (0.5 * (a - c) / den if den < 0 else 0.0))


def track_beats(dips: np.ndarray, period: float) -> np.ndarray:
    """Ellis' dynamic-programming beat tracker on the dip signal: frame indices of the beats."""
    n = len(dips)
    score = dips / (dips.std() + 1e-9)
    best = score.copy()
    back = np.full(n, -1)
    lo, hi = int(round(period / 2)), int(round(2 * period))
    offsets = np.arange(lo, hi + 1)
    penalty = -TIGHTNESS * np.log(offsets / period) ** 2
    for t in range(lo, n):
        prev = t - offsets
        ok = prev >= 0
        cand = best[prev[ok]] + penalty[ok]
        k = int(np.argmax(cand))
        if cand[k] > 0:
            best[t] = score[t] + cand[k]
            back[t] = prev[ok][k]
    # The last beat: the best-scoring frame within one period of the end.
    t = n - 1 - int(np.argmax(best[::-1][: max(1, int(round(period)))]))
    beats = [t]
    while back[t] >= 0:
        t = back[t]
        beats.append(t)
    return np.array(beats[::-1], dtype=np.int64)


def refine(v: np.ndarray, beats: np.ndarray) -> np.ndarray:
    """Beats moved to the bottom of the speed's dip, to a fraction of a frame (a parabola through 3 frames)."""
    out = beats.astype(np.float64)
    inner = (beats > 0) & (beats < len(v) - 1)
    b = beats[inner]
    a, m, c = v[b - 1], v[b], v[b + 1]
    den = a - 2 * m + c
    shift = np.where(den > 1e-12, 0.5 * (a - c) / np.where(den > 1e-12, den, 1.0), 0.0)
    out[inner] = b + np.clip(shift, -0.5, 0.5)
    return out


def choose_meter(features: np.ndarray, style: str) -> int:
    """3 or 4 beats per bar: from the style when it names one, else the meter whose two-bar lag repeats the
    pose best (ballroom figures repeat every two bars)."""
    if style in STYLE_METER:
        return STYLE_METER[style]
    pose = features[:, :POSE_DIM]
    dist = {m: float(np.linalg.norm(pose[2 * m :] - pose[: -2 * m], axis=1).mean())
            for m in (3, 4) if len(pose) > 2 * m + 2}
    return min(dist, key=dist.get) if len(dist) == 2 else 4


def analyze_clip(motion: Motion, style: str = "", beat_times: np.ndarray | None = None,
                 downbeat_times: np.ndarray | None = None) -> ClipAnalysis:
    """Beats, tempo, meter, downbeats and boundary features of one clip (at any frame rate).

    With `beat_times` (seconds into the clip: the beats of the music it was danced to, when known) the clip is cut
    on those, bars from `downbeat_times`; otherwise on its kinematic beats, as the module's docstring says.
    """
    feats, speed = frame_features(motion)
    if beat_times is not None and len(beat_times) >= 2:
        beats = np.asarray(beat_times, np.float64) * motion.fps
        keep = (beats >= 0) & (beats <= motion.num_frames - 1)
        downs = np.asarray(downbeat_times if downbeat_times is not None else beat_times[:1], np.float64) * motion.fps
        beats = beats[keep]
        downbeat = np.isin(np.round(beats, 3), np.round(downs, 3))
        counts = np.diff(np.flatnonzero(downbeat))
        meter = int(np.median(counts)) if len(counts) else 4
    else:
        v = gaussian_filter1d(speed, BAS_SMOOTH_S * motion.fps)
        dips = dip_train(speed, motion.fps)
        beats = refine(v, track_beats(dips, tempo_period(dips, motion.fps)))
        meter = choose_meter(feats[np.round(beats).astype(np.int64)], style)
        downbeat = None
    at = np.clip(np.round(beats).astype(np.int64), 0, motion.num_frames - 1)
    edges = np.append(at, motion.num_frames)
    csum = np.concatenate([[0.0], np.cumsum(speed)])
    energy = (csum[edges[1:]] - csum[edges[:-1]]) / np.maximum(edges[1:] - edges[:-1], 1)
    if downbeat is None:
        phase = int(np.argmax([energy[p::meter].mean() if len(energy[p::meter]) else -1.0 for p in range(meter)]))
        downbeat = (np.arange(len(beats)) % meter) == phase
    tempo = 60.0 * motion.fps / float(np.median(np.diff(beats))) if len(beats) > 1 else 0.0
    return ClipAnalysis(beats, downbeat, tempo, meter, feats[at], energy.astype(np.float32))

"""Dance metrics as the field computes them (see REFERENCE.md section 2), on world joint positions.

Time constants are in seconds, so a metric means the same at 25, 30 or 60 fps: Bailando's Beat Align
Score uses sigma = 3 frames at 60 fps (50 ms) and smooths velocity with sigma = 5 frames (83 ms); we keep
those durations at any frame rate.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import linalg
from scipy.spatial.distance import pdist

from ..beats import kinematic_velocity, motion_beats

BAS_SIGMA_S = 3 / 60
HIT_WINDOW_S = 0.25

# Foot contact and sliding, after Lodge's foot_skating: toe within 5 cm of the floor; sliding above 1 cm
# per frame at 25 fps = 0.25 m/s of horizontal toe speed. Lodge also asks the ankle to be within 8 cm;
# ballroom dancers stand on the balls of their feet (our capture's planted ankles sit 8-15 cm up), so
# the toe alone decides here.
CONTACT_TOE_M = 0.05
SLIDE_SPEED_MPS = 0.25

# EDGE's PFC measures foot speed in metres per frame at 30 fps; we turn m/s into that unit at any rate.
PFC_FPS = 30.0
PFC_SCALE = 1e4
PFC_FEET = (7, 10, 8, 11)  # left ankle, left foot, right ankle, right foot (SMPL and SMPL-X order)
PFC_STILL_ACC = 1e-6  # m/s^2: a root never accelerating more than this is steady (rounding, not motion)
FID_EPS = 1e-5  # Bailando's diagonal offset when the covariance product is singular
NORM_EPS = 1e-10  # Bailando's guard on the real set's standard deviation


def _beat_distances(positions: np.ndarray, fps: float, music_beats_s: np.ndarray) -> np.ndarray:
    """For each music beat within the dance, the distance (s) to the nearest dance beat; empty if none."""
    duration = len(positions) / fps
    beats = np.asarray(music_beats_s)
    beats = beats[(beats >= 0) & (beats < duration)]
    dance = motion_beats(positions, fps) / fps
    if len(beats) == 0 or len(dance) == 0:
        return np.zeros(0)
    return np.abs(beats[:, None] - dance[None, :]).min(axis=1)


def beat_align_score(positions: np.ndarray, fps: float, music_beats_s: np.ndarray) -> float:
    """Bailando's BAS: mean over music beats of exp(-d^2 / 2 sigma^2), d = distance to the nearest dance beat."""
    d = _beat_distances(positions, fps, music_beats_s)
    return float(np.mean(np.exp(-(d**2) / (2 * BAS_SIGMA_S**2)))) if len(d) else 0.0


def own_song_bas_ratio(positions: Sequence[np.ndarray], fps: float, beats_s: Sequence[np.ndarray]) -> float:
    """Mean BAS of each dance against its own song's beats over its mean BAS against the other songs' beats
    (each other song of the set once, however many dances share it).

    Why: a dance that moves rhythmically but ignores its song scores a BAS as high against any song of a similar
    tempo as against its own (ratio about 1); one that follows its song's beats scores higher against them.
    NaN when every dance is to the same song: there is no other song to compare with.
    """
    songs: list[np.ndarray] = []
    for b in beats_s:
        if not any(len(b) == len(o) and np.array_equal(b, o) for o in songs):
            songs.append(np.asarray(b))
    if len(songs) < 2:
        return float("nan")
    own, other = [], []
    for pos, b in zip(positions, beats_s, strict=True):
        own.append(beat_align_score(pos, fps, b))
        other.append(np.mean([beat_align_score(pos, fps, o) for o in songs
                              if not (len(o) == len(b) and np.array_equal(o, b))]))
    return float(np.mean(own) / max(np.mean(other), 1e-9))


def rhythm_hit_rate(positions: np.ndarray, fps: float, music_beats_s: np.ndarray) -> float:
    """The paper's rhythm hit rate: share of music beats with a dance beat within 0.25 s."""
    d = _beat_distances(positions, fps, music_beats_s)
    return float(np.mean(d <= HIT_WINDOW_S)) if len(d) else 0.0


@dataclass
class FootSliding:
    slide_ratio: float  # share of contact frames whose toe moves faster than SLIDE_SPEED_MPS
    mean_slide_m: float  # mean horizontal toe travel per contact frame (metres)
    contact_ratio: float  # share of foot-frames in contact


def foot_sliding(toes: np.ndarray, fps: float, floor: float | None = None) -> FootSliding:
    """Sliding of feet in contact. toes: [T, 2, 3] world positions of the toe ends (left, right)."""
    if floor is None:
        floor = float(np.percentile(toes[:, :, 1].min(axis=1), 2))
    step = np.zeros(toes.shape[:2])
    step[1:] = np.linalg.norm(np.diff(toes[:, :, [0, 2]], axis=0), axis=-1)
    contact = toes[:, :, 1] <= floor + CONTACT_TOE_M
    contact[0] = False
    n = contact.sum()
    if n == 0:
        return FootSliding(0.0, 0.0, 0.0)
    slide = step[contact] * fps > SLIDE_SPEED_MPS
    return FootSliding(float(slide.mean()), float(step[contact].mean()), float(contact.mean()))


FLOOR_WINDOW_S = 2.0
FLOOR_REACH_M = 0.015


def floor_reach(lowest_toe: np.ndarray, fps: float) -> float:
    """Share of 2-s windows [0, 1] in which the lowest toe end `lowest_toe` [T] (height above the floor, y = 0)
    comes within 1.5 cm of the floor, above or below: a ballroom dancer has a foot on the floor within any two
    seconds, so a window where no toe gets near it is a hovering (or sinking) dancer."""
    n = max(1, int(round(FLOOR_WINDOW_S * fps)))
    k = len(lowest_toe) // n
    if k == 0:
        return float(abs(np.min(lowest_toe)) <= FLOOR_REACH_M)
    lowest = np.asarray(lowest_toe)[: k * n].reshape(k, n).min(axis=1)
    return float(np.mean(np.abs(lowest) <= FLOOR_REACH_M))


def jitter(positions: np.ndarray, fps: float) -> float:
    """Mean joint acceleration magnitude (m/s^2)."""
    acc = np.diff(positions, n=2, axis=0) * fps * fps
    return float(np.linalg.norm(acc, axis=-1).mean())


def longest_freeze_s(positions: np.ndarray, fps: float, speed_mps: float = 0.05) -> float:
    """Longest stretch (seconds) in which the mean joint speed stays below `speed_mps`."""
    still = kinematic_velocity(positions) * fps < speed_mps
    best = run = 0
    for s in still:
        run = run + 1 if s else 0
        best = max(best, run)
    return best / fps


def root_extent_m(root: np.ndarray) -> float:
    """Largest horizontal distance of the root from where it started."""
    return float(np.linalg.norm(root[:, [0, 2]] - root[0, [0, 2]], axis=-1).max())


def frechet_distance(real: np.ndarray, gen: np.ndarray) -> float:
    """Frechet distance between Gaussians fitted to two sets of feature rows [N, F], as Bailando's calc_fid:
    |mu_r - mu_g|^2 + tr(S_r + S_g - 2 (S_r S_g)^(1/2)). A singular product (fewer samples than features)
    is retried with FID_EPS on the diagonals; an imaginary part from rounding is dropped."""
    real, gen = np.atleast_2d(np.asarray(real, np.float64)), np.atleast_2d(np.asarray(gen, np.float64))
    if real.shape[1] != gen.shape[1] or min(len(real), len(gen)) < 2:
        raise ValueError(f"need two sets of >= 2 rows with the same width, got {real.shape} and {gen.shape}")
    mu_r, mu_g = real.mean(axis=0), gen.mean(axis=0)
    s_r, s_g = np.atleast_2d(np.cov(real, rowvar=False)), np.atleast_2d(np.cov(gen, rowvar=False))
    covmean = linalg.sqrtm(s_r @ s_g)  # no `disp`: scipy 1.18 removed it, and the default returns the same root
    if not np.isfinite(covmean).all():
        offset = np.eye(len(s_r)) * FID_EPS
        covmean = linalg.sqrtm((s_r + offset) @ (s_g + offset))
    diff = mu_r - mu_g
    return float(diff @ diff + np.trace(s_r) + np.trace(s_g) - 2 * np.trace(covmean.real))


def normalize_by(reference: np.ndarray, feats: np.ndarray) -> np.ndarray:
    """feats in units of the reference set's per-feature mean and standard deviation (Bailando's normalize)."""
    reference = np.asarray(reference, np.float64)
    return (np.asarray(feats, np.float64) - reference.mean(axis=0)) / (reference.std(axis=0) + NORM_EPS)


def fid(real_feats: np.ndarray, gen_feats: np.ndarray) -> float:
    """FID_k / FID_g as Bailando's metrics_new.py: both sets normalised by the real set's mean and std,
    then the Frechet distance. A feature constant over the real set (std 0) makes any generated deviation
    in it huge: that is Bailando's convention, kept so numbers compare."""
    return frechet_distance(normalize_by(real_feats, real_feats), normalize_by(real_feats, gen_feats))


def diversity(feats: np.ndarray, reference: np.ndarray | None = None) -> float:
    """Div_k / Div_g: mean L2 distance over all pairs of rows [N, F] (Bailando's calculate_avg_distance),
    after normalising by the reference (real) set's mean and std when one is given, as Bailando does."""
    x = np.asarray(feats, np.float64) if reference is None else normalize_by(reference, feats)
    if x.ndim != 2 or len(x) < 2:
        raise ValueError(f"diversity needs [N >= 2, F] features, got {x.shape}")
    return float(pdist(x).mean())


def physical_foot_contact(positions: np.ndarray, fps: float) -> float:
    """EDGE's PFC (eval_pfc.py) on world positions [T, J >= 12, 3], Y up; lower is better.

    Per frame: the root's acceleration (its upward part clamped at 0: rising needs a push from the floor,
    falling does not), divided by its maximum over the dance, times min(ankle, foot) horizontal speed of the
    left and of the right foot (EDGE's unit: metres per 30-fps frame); mean over frames, x 1e4. A dance
    whose root never accelerates scores 0 (EDGE would divide by 0).
    """
    p = np.asarray(positions, np.float64)
    if p.ndim != 3 or p.shape[1] < 12 or p.shape[2] != 3 or len(p) < 3:
        raise ValueError(f"expected [T >= 3, J >= 12, 3] positions, got {p.shape}")
    root_a = np.diff(p[:, 0], n=2, axis=0) * fps * fps  # [T-2, 3]
    root_a[:, 1] = np.maximum(root_a[:, 1], 0.0)
    root_a = np.linalg.norm(root_a, axis=1)
    peak = root_a.max()
    if peak <= PFC_STILL_ACC:
        return 0.0
    feet = p[:, list(PFC_FEET)][:, :, [0, 2]]
    foot_v = np.linalg.norm(feet[2:] - feet[1:-1], axis=-1) * fps / PFC_FPS  # [T-2, 4]
    left, right = np.minimum(foot_v[:, 0], foot_v[:, 1]), np.minimum(foot_v[:, 2], foot_v[:, 3])
    return float((left * right * root_a / peak).mean() * PFC_SCALE)


def mean_joint_speed(positions: np.ndarray, fps: float) -> float:
    """Mean speed of the joints [T, J, 3] in m/s: how much the dance moves, travel included."""
    return float(kinematic_velocity(positions).mean() * fps)


REPLAY_SEGMENT_S = 5.0
REPLAY_FRAME_STEP = 5  # every 5th frame: the distance changes little and costs 25x less


def body_relative_segments(positions: np.ndarray, fps: float, hop_s: float) -> np.ndarray:
    """5-s segments [N, F] of joint positions [T, J >= 3, 3] relative to the pelvis and turned so that the
    segment's first frame faces +Z (hips along X): where and which way the dancer stands does not count."""
    n, hop = int(round(REPLAY_SEGMENT_S * fps)), max(1, int(round(hop_s * fps)))
    out = []
    for s in range(0, len(positions) - n + 1, hop):
        seg = positions[s : s + n : REPLAY_FRAME_STEP] - positions[s : s + n : REPLAY_FRAME_STEP, :1]
        hips = positions[s, 1] - positions[s, 2]  # left hip - right hip (SMPL order)
        yaw = np.arctan2(hips[2], hips[0])
        c, si = np.cos(yaw), np.sin(yaw)
        x, z = seg[..., 0] * c + seg[..., 2] * si, -seg[..., 0] * si + seg[..., 2] * c
        out.append(np.stack([x, seg[..., 1], z], -1).ravel())
    return np.asarray(out, np.float64).reshape(len(out), -1)


def nearest_segment_distance(segments: np.ndarray, library: np.ndarray) -> np.ndarray:
    """For each segment [N, F], the RMS joint distance (m) to its nearest segment of `library` [M, F]: a
    dance that replays its training data sits much nearer to it than a real, unseen dance does."""
    sq = (segments**2).sum(1)[:, None] + (library**2).sum(1)[None] - 2 * segments @ library.T
    joints_frames = segments.shape[1] / 3
    return np.sqrt(np.maximum(sq.min(axis=1), 0.0) / joints_frames)


def balanced_accuracy(confusion: Sequence[Sequence[int]] | np.ndarray) -> float:
    """Mean recall over the classes present (rows: truth, columns: prediction): the fair accuracy when one
    class has most of the items (always answering it scores 1 / classes here)."""
    recalls = [row[i] / sum(row) for i, row in enumerate(confusion) if sum(row)]
    return float(sum(recalls) / max(1, len(recalls)))

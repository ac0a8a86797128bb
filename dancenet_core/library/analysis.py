"""One clip's musical structure, read from its motion alone: its beats, tempo, bars and what a cut at each beat
has to match (pose, velocity, foot contact).

A clip from a capture session or a download has no music, so its tempo and bars come from how the dancer moves:

- Bars: dancers repeat their figures, so the legs' pose (joints relative to the pelvis, in the dancer's heading
  frame, so that turning and travelling do not count; the legs carry the steps, where arms in a hold or styled
  figure by figure add noise) comes back every bar, two bars and four bars. For each meter (3 or 4 beats a bar)
  and each beat period from 50 to 200 BPM, the score is how close the pose comes back after one bar (or its
  mirror: the feet alternate, so one bar on a dancer often stands in the mirror of the pose, LRL then RLR), two
  and four of its bars (`pose_return`: the RMS pose distance at that lag against its mean), plus the rhythm of
  the steps and the body (`LAG_WEIGHTS`: the autocorrelations at one and two beats of the speed's dips, one pulse
  per step, and of the feet's speed over the floor; the pelvis's bob at one beat; the feet's speed after one bar),
  less a 3:2 guard (the feet's speed and the pelvis's height repeating every three beats of a reading count
  against it: a 4/4 dancer's half-bar pattern read at 3/2 of the tempo repeats so, where a real 3/4 bar is still
  found by the pose's return), and a slight preference for tempi near 110 BPM (between readings that score
  alike). The best (meter, period) is the clip's, unless the clip's style names its meter (`STYLE_METER`: waltz
  3/4; cha-cha, rumba, tango, salsa, swing 4/4...) or the user gave the tempo or meter (`manifest.csv`, an
  action's custom properties in Blender), which are taken as given. The weights were chosen on the training
  split's dances, with made-up stepping figures at 60-120 steps a minute in 3/4 and 4/4 read right.
- Octave: where the pelvis rises and falls once a bar at half the tempo read (`bar_octave`: a waltz's rise and
  fall), the tempo is halved, so that a bar is the dancers' bar and not half of it; the plan would lay either
  octave at the dancers' speed, but figures start on bars.
- Confidence: how much better that period scores than the best one that is neither it nor its half or double (an
  octave off is harmless: the plan lays a figure at 1, 2 or 1/2 clip beats per song beat, whichever plays it at
  its captured speed), and, where the meter was read from the motion, how much better it scores than the other.
- Beats are kinematic beats (the dancer's speed minima, `beats.py`) tracked as Ellis' dynamic-programming beat
  tracker does for audio onsets, at that period: the beat sequence that best trades dip depth against even
  spacing. The downbeat is the phase whose beats start the most energetic steps.

On the 56 Dance with Melody dances against their songs' beats (`scripts/clip_analysis.py`, the scoring of
`dancenet evaluate --library`; figures in docs/library.md) this reads every meter from the motion alone and the
tempo (or its half or double, within 8%) of 51; with the style's meter the same. Four of the five it misses are
captures stretched against their songs (three cha-chas by the data's own 25-fps re-export, a tango compressed about
2.3x): at their older export's length they read right. On the 52 that keep time with their songs it reads 51.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.signal import correlate, fftconvolve

from ..beats import BAS_SMOOTH_S, kinematic_velocity, local_minima
from ..kinematics import fk_numpy
from ..motion import Motion
from ..representation import foot_contacts, heading_frames
from ..skeleton import BODY_JOINTS, JOINT_NAMES, TOE_ENDS

MIN_BPM, MAX_BPM = 50.0, 200.0
TIGHTNESS = 100.0  # Ellis' (and librosa's) weight on even beat spacing
TREND_S = 0.6  # the speed's slow trend, removed so that dips count against their surroundings
# Styles whose bars are known (dance teachers' and competitions' meters); others are read from the motion.
STYLE_METER = {"waltz": 3, "viennese waltz": 3, "viennese_waltz": 3, "cha-cha": 4, "chacha": 4, "cha_cha": 4,
               "rumba": 4, "tango": 4, "salsa": 4, "swing": 4, "foxtrot": 4, "quickstep": 4, "jive": 4, "samba": 4,
               "mambo": 4, "bachata": 4, "merengue": 4, "lindy": 4, "hiphop": 4, "hip-hop": 4, "house": 4,
               "pop": 4, "disco": 4, "latin": 4}
METERS = (3, 4)
# The legs' pose is compared after one, two and four bars; after one, its mirror counts too (the feet alternate: a
# bar later a dancer often stands in the mirror of the pose, LRL then RLR in a waltz). These weights and the ones
# below were chosen on the training split's dances (docs/library.md).
BAR_RETURNS, BAR_WEIGHTS = (1, 2, 4), (1.0, 1.0, 1.0)
# How each signal's autocorrelation at so many beats adds to a reading's score: the speed's dips and the feet's
# speed (a pulse a step) at one and two beats, the pelvis's bob at one; at three beats the feet's speed and the
# pelvis's height count against (the 3:2 guard: a 4/4 dancer's half-bar pattern read at 3/2 the tempo repeats every
# three of those beats; a 3/4 bar is still found by the pose's return).
LAG_WEIGHTS = {"dips": ((1, 0.2), (2, 0.2)), "feet": ((1, 0.3), (2, 0.3), (3, -0.2)),
               "height": ((1, 0.05), (3, -0.1))}
BAR_LAG_WEIGHTS = {"feet": 0.05}  # the feet's speed after one bar of the meter read
PRIOR_BPM, PRIOR_WEIGHT = 110.0, 0.3  # a slight preference for tempi near 110 BPM, between equal readings
FALLBACK_METER = 4  # the meter assumed for a clip too short to read when no clip of the library is long enough
# The pelvis's rise and fall once a bar (its height's autocorrelation after a bar less after half a bar) beyond
# which a reading is taken at half its tempo: 0.72-1.47 for the 31 waltzes read at twice their songs' tempo, at most
# 0.67 for the 4/4 dances (0 for a body that bobs once a beat); chosen on the training split, used for the octave
# only (the plan lays either octave at the dancers' speed).
RISE_FALL = 0.7
HEIGHT_TREND_S = 2.0  # the pelvis's slow drift (a capture's floor creeping up, a dip): removed from its height
CANDIDATES = 600  # beat periods tried, evenly in log tempo between MIN_BPM and MAX_BPM
UNSURE = 0.25  # a confidence under this: `library build` names the clip (give its tempo and meter in the manifest)
# A clip shorter than this, or than READ_BARS bars at the tempo read from it, is too short for its tempo to be read
# (the pose has to come back after a bar, and again): it takes the library's tempo (`with_assumed_tempi`).
MIN_READ_S = 4.0
READ_BARS = 2
OCTAVE_TOLERANCE = 0.08  # a period within 8% of the best's half, whole or double is the same tempo for the plan
POSE_DIM = BODY_JOINTS * 3
LEG_JOINTS = [i for i, n in enumerate(JOINT_NAMES[:BODY_JOINTS])
              if n.split("_")[-1] in ("hip", "knee", "ankle", "foot")]
# each body joint's other side (itself on the spine)
BODY_MIRROR = [JOINT_NAMES.index(n.replace("left_", "?").replace("right_", "left_").replace("?", "right_"))
               for n in JOINT_NAMES[:BODY_JOINTS]]
FEATURE_DIM = 2 * POSE_DIM + 2  # pose, velocity, foot contacts


@dataclass
class ClipAnalysis:
    """beats: frame positions (sub-frame) of the clip's beats; downbeat: [B] bool, first beat of a bar;
    features: [B, FEATURE_DIM] at each beat: body joints relative to the pelvis in the dancer's heading frame (m),
    their velocities in that frame (m/s), left and right foot contact; energy: [B] mean joint speed (m/s) from
    each beat to the next (the last: to the clip's end); confidence and source: how sure the tempo and meter are
    and where they came from."""

    beats: np.ndarray
    downbeat: np.ndarray
    tempo_bpm: float
    meter: int
    features: np.ndarray
    energy: np.ndarray
    confidence: float = 1.0  # how sure the tempo and meter are (0-1): see the module's docstring
    source: str = "motion"  # what the tempo and meter were read from


def heading_local(vectors: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Vectors [T, ..., 3] turned by -yaw about +Y, so that the dancer's heading is the same in every frame."""
    c, s = np.cos(yaw), np.sin(yaw)
    shape = (-1,) + (1,) * (vectors.ndim - 2)
    c, s = c.reshape(shape), s.reshape(shape)
    x, z = vectors[..., 0], vectors[..., 2]
    return np.stack([c * x - s * z, vectors[..., 1], s * x + c * z], axis=-1)


def frame_features(motion: Motion) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per frame: the boundary features [T, FEATURE_DIM], the mean joint speed [T] (m/s), the feet's speed over
    the floor [T] (m/s, both toes': each step moves a foot) and the pelvis's height [T] (m: its rise and fall)."""
    pos, _, ends = fk_numpy(motion.skeleton, motion.rotations, motion.root_positions, with_end_sites=True)
    body = pos[:, :BODY_JOINTS]
    yaw = heading_frames(motion)
    vel = np.gradient(body, axis=0) * motion.fps if len(body) > 1 else np.zeros_like(body)
    pose = heading_local(body - body[:, :1], yaw)
    contacts = foot_contacts(ends[:, list(TOE_ENDS)], motion.fps, floor=0.0)
    feats = np.concatenate([pose.reshape(len(body), -1), heading_local(vel, yaw).reshape(len(body), -1), contacts],
                           axis=1)
    toes = ends[:, list(TOE_ENDS)][..., [0, 2]]
    feet = np.linalg.norm(np.gradient(toes, axis=0), axis=-1).sum(axis=1) * motion.fps if len(toes) > 1 else \
        np.zeros(len(toes))
    return feats.astype(np.float32), kinematic_velocity(body) * motion.fps, feet, body[:, 0, 1]


def dip_train(speed: np.ndarray, fps: float) -> np.ndarray:
    """How deep each speed minimum dips below the speed's slow trend, at the minimum's frame (0 elsewhere),
    lightly smoothed: the motion's onset envelope, with one pulse per step."""
    v = gaussian_filter1d(speed, BAS_SMOOTH_S * fps)
    depth = np.zeros_like(v)
    at = local_minima(v)
    depth[at] = np.maximum(gaussian_filter1d(speed, TREND_S * fps)[at] - v[at], 0.0)
    return gaussian_filter1d(depth, 1.0)


def _lagged(x: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """x [T] or [T, D] at fractional `lags` (linear between whole ones) of a function tabulated at lags 0, 1, ..."""
    return np.interp(lags, np.arange(len(x)), x, right=np.nan)


def _rms_after(x: np.ndarray, y: np.ndarray, max_lag: int) -> np.ndarray:
    """[max_lag]: for each lag L (frames), the RMS over t of |x_t - y_{t+L}| (x, y [T, D], centred alike). Per
    dimension through the FFT, so a long clip costs about as much as reading it."""
    n = len(x)
    # sum over t and dimensions of x_t . y_{t+L}: x reversed in time, convolved with y, at lag L
    cross = fftconvolve(x[::-1], y, axes=0)[n - 1 : n - 1 + max_lag].sum(axis=1)
    sx = np.concatenate([[0.0], np.cumsum((x**2).sum(axis=1))])
    sy = np.concatenate([[0.0], np.cumsum((y**2).sum(axis=1))])
    lags = np.arange(max_lag)
    # mean over t of |x_t|^2 + |y_{t+L}|^2 - 2 x_t.y_{t+L}
    ms = (sx[n - lags] + (sy[n] - sy[lags]) - 2.0 * cross) / np.maximum(n - lags, 1)
    return np.sqrt(np.maximum(ms, 0.0))


def pose_return(pose: np.ndarray, max_lag: int, joints: Sequence[int] = LEG_JOINTS
                ) -> tuple[np.ndarray, np.ndarray]:
    """Two [max_lag] curves: for each lag (frames), how close the pose of `joints` (`pose`: `frame_features`' body
    joints relative to the pelvis, heading frame) comes back after it, and how close its mirror (left and right
    swapped) does: 1 - the RMS distance over the distance's mean across lags of 1 to 8 s (1: the same pose; about
    0: as far as any). The legs by default: they carry a figure's steps, where arms in a hold or styled figure by
    figure mostly add noise to the tempo's reading."""
    body = pose.reshape(len(pose), BODY_JOINTS, 3)
    chosen = body[:, list(joints)]
    mirror = body[:, [BODY_MIRROR[j] for j in joints]] * np.array([-1.0, 1.0, 1.0])
    x = (chosen - chosen.mean(axis=0)).reshape(len(pose), -1)
    y = (mirror - mirror.mean(axis=0)).reshape(len(pose), -1)
    same = _rms_after(x, x, max_lag)
    scale = max(float(same[min(max_lag - 1, 25) : min(max_lag, 200)].mean()), 1e-9)
    return 1.0 - same / scale, 1.0 - _rms_after(x, y, max_lag) / scale


def _autocorrelation(x: np.ndarray, max_lag: int) -> np.ndarray:
    """[max_lag] normalised autocorrelation (1 at lag 0), unbiased."""
    n = len(x)
    x = x - x.mean()
    ac = correlate(x, x, mode="full", method="fft")[n - 1 : n - 1 + max_lag]
    ac = np.pad(ac / np.maximum(n - np.arange(len(ac)), 1), (0, max_lag - len(ac)))  # lags past the clip: 0
    return ac / max(float(ac[0]), 1e-12)


def rhythm_signals(speed: np.ndarray, feet: np.ndarray, height: np.ndarray, fps: float) -> dict[str, np.ndarray]:
    """The signals of `LAG_WEIGHTS` from `frame_features`' speed, feet's speed and pelvis height."""
    return {"dips": dip_train(speed, fps), "feet": gaussian_filter1d(feet, 1.0),
            "height": gaussian_filter1d(height - gaussian_filter1d(height, HEIGHT_TREND_S * fps), 1.0)}


def tempo_scores(pose: np.ndarray, signals: dict[str, np.ndarray], fps: float
                 ) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """Beat periods (frames, [CANDIDATES]) and, per meter, each period's score (the module's docstring); `signals`:
    `rhythm_signals`, whose autocorrelations count as `LAG_WEIGHTS` says."""
    periods = fps * 60.0 / np.exp(np.linspace(np.log(MIN_BPM), np.log(MAX_BPM), CANDIDATES))
    max_lag = int(np.ceil(max(BAR_RETURNS) * max(METERS) * periods.max())) + 2
    back, mirrored = pose_return(pose, min(max_lag, len(pose)))
    steps = np.zeros(len(periods))
    acs = {name: _autocorrelation(x, min(max_lag, len(x))) for name, x in signals.items()}
    for name, lags in LAG_WEIGHTS.items():
        for k, w in lags:
            steps += w * np.nan_to_num(_lagged(acs[name], k * periods))
    prior = PRIOR_WEIGHT * np.exp(-0.5 * np.log2(fps * 60.0 / periods / PRIOR_BPM) ** 2)
    scores = {}
    for m in METERS:
        # after one bar, the pose or its mirror; after two and four, the pose itself
        returns = np.stack([np.fmax(_lagged(back, k * m * periods), _lagged(mirrored, k * m * periods)) if k == 1
                            else _lagged(back, k * m * periods) for k in BAR_RETURNS])
        bar_steps = sum(w * np.nan_to_num(_lagged(acs[name], m * periods)) for name, w in BAR_LAG_WEIGHTS.items())
        seen = np.isfinite(returns)  # a clip too short for four bars is scored on the bars it has
        weight = np.array(BAR_WEIGHTS)[:, None] * seen
        pose_score = (np.where(seen, returns, 0.0) * weight).sum(0) / np.maximum(weight.sum(0), 1e-9)
        scores[m] = np.where(seen.any(0), pose_score, -np.inf) + steps + bar_steps + prior
    return periods, scores


def choose_tempo(periods: np.ndarray, scores: dict[int, np.ndarray], meter: int | None
                 ) -> tuple[float, int, float]:
    """(beat period in frames, meter, confidence 0-1) from `tempo_scores`; `meter` given: that meter's best."""
    meters = [meter] if meter in scores else list(scores)
    best = {m: int(np.argmax(scores[m])) for m in meters}
    m = max(meters, key=lambda k: scores[k][best[k]])
    k = best[m]
    top = float(scores[m][k])
    # the best period that is no octave of this one, in this meter
    ratio = np.log2(periods / periods[k])
    other = np.abs(ratio - np.round(ratio)) > np.log2(1 + OCTAVE_TOLERANCE)
    rival = float(scores[m][other].max()) if other.any() else -np.inf
    confidence = _margin(top, rival)
    if meter is None and len(meters) > 1:
        confidence = min(confidence, _margin(top, max(float(scores[o][best[o]]) for o in meters if o != m)))
    return float(periods[k]), m, confidence


def bar_octave(period: float, meter: int, height: np.ndarray, fps: float) -> float:
    """`period`, or twice it where the pelvis rises and falls once a bar at twice it (`RISE_FALL`: its height's
    autocorrelation after that bar less after half of it), as a waltz's does: the two octaves score alike (the
    plan lays either at the dancers' speed), but at the faster one a bar is half the dancers' bar, and figures
    would start mid-bar."""
    slower = 2.0 * period
    if fps * 60.0 / slower < MIN_BPM or meter * slower >= len(height):
        return period
    ac = _autocorrelation(height, int(np.ceil(meter * slower)) + 1)
    rise = np.nan_to_num(_lagged(ac, np.array([meter * slower, meter * period])))
    return slower if rise[0] - rise[1] > RISE_FALL else period


def _margin(top: float, rival: float) -> float:
    """How much better `top` is than `rival`, as a confidence: 0 (as good) to 1 (twice as good or more)."""
    if not np.isfinite(rival) or rival <= 0:
        return 1.0 if top > 0 else 0.0
    return float(np.clip(top / rival - 1.0, 0.0, 1.0))


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


def analyze_clip(motion: Motion, style: str = "", beat_times: np.ndarray | None = None,
                 downbeat_times: np.ndarray | None = None, bpm: float | None = None,
                 meter: int | None = None) -> ClipAnalysis:
    """Beats, tempo, meter, downbeats and boundary features of one clip (at any frame rate).

    With `beat_times` (seconds into the clip: the beats of the music it was danced to, when known) the clip is cut
    on those, bars from `downbeat_times`; otherwise on its kinematic beats, as the module's docstring says, at the
    tempo `bpm` and `meter` where given (the user's), the meter of its `style` where known.
    """
    feats, speed, feet, height = frame_features(motion)
    if beat_times is not None and len(beat_times) >= 2:
        beats = np.asarray(beat_times, np.float64) * motion.fps
        keep = (beats >= 0) & (beats <= motion.num_frames - 1)
        downs = np.asarray(downbeat_times if downbeat_times is not None else beat_times[:1], np.float64) * motion.fps
        beats = beats[keep]
        downbeat = np.isin(np.round(beats, 3), np.round(downs, 3))
        counts = np.diff(np.flatnonzero(downbeat))
        meter = int(np.median(counts)) if len(counts) else 4
        confidence, source = 1.0, "music"
    else:
        v = gaussian_filter1d(speed, BAS_SMOOTH_S * motion.fps)
        signals = rhythm_signals(speed, feet, height, motion.fps)
        dips = signals["dips"]
        told = meter if meter is not None else STYLE_METER.get(style.strip().lower())
        if bpm is not None:
            period, confidence = motion.fps * 60.0 / bpm, 1.0
            if told is None:
                periods, scores = tempo_scores(feats[:, :POSE_DIM], signals, motion.fps)
                k = int(np.argmin(np.abs(np.log(periods / period))))
                told = max(scores, key=lambda m: scores[m][k])
        else:
            periods, scores = tempo_scores(feats[:, :POSE_DIM], signals, motion.fps)
            period, told, confidence = choose_tempo(periods, scores, told)
            period = bar_octave(period, told, signals["height"], motion.fps)
        beats = refine(v, track_beats(dips, period))
        source = _source(bpm, meter, style)
        meter = int(told)
        downbeat = None
    at = np.clip(np.round(beats).astype(np.int64), 0, motion.num_frames - 1)
    edges = np.append(at, motion.num_frames)
    csum = np.concatenate([[0.0], np.cumsum(speed)])
    energy = (csum[edges[1:]] - csum[edges[:-1]]) / np.maximum(edges[1:] - edges[:-1], 1)
    if downbeat is None:
        phase = int(np.argmax([energy[p::meter].mean() if len(energy[p::meter]) else -1.0 for p in range(meter)]))
        downbeat = (np.arange(len(beats)) % meter) == phase
    tempo = 60.0 * motion.fps / float(np.median(np.diff(beats))) if len(beats) > 1 else 0.0
    if bpm is not None and beat_times is None:
        tempo = float(bpm)  # the user's word, whatever the steps' spacing
    return ClipAnalysis(beats, downbeat, tempo, meter, feats[at], energy.astype(np.float32), confidence, source)


def too_short(seconds: float, analysis: ClipAnalysis) -> bool:
    """Whether a clip of `seconds` is too short for the tempo read from its motion to stand (`MIN_READ_S`,
    `READ_BARS`); a tempo given by the user or the clip's music always stands."""
    if not analysis.source.startswith("tempo: motion") or analysis.tempo_bpm <= 0:
        return False
    return seconds < max(MIN_READ_S, READ_BARS * analysis.meter * 60.0 / analysis.tempo_bpm)


def with_assumed_tempi(clips: list[tuple[str, str, Motion, ClipAnalysis]]
                       ) -> list[tuple[str, str, Motion, ClipAnalysis]]:
    """The clips (name, style, motion, analysis), each one too short for its tempo to be read (`too_short`)
    analysed again at the library's tempo: the median over the clips long enough to read, weighted by their
    length (`PRIOR_BPM` when none is), and the meter its style names or else the library's commonest; its source
    says "assumed" and its confidence is 0, so `library build` names it among the clips to check. A dancer's clip of
    a few seconds holds too few bars to tell its tempo from its motion, but its steps still fall on beats: laid at
    the library's tempo, the plan plays it within its speed limit like any other clip."""
    short = [too_short(m.duration, a) for _, _, m, a in clips]
    read = [(a.tempo_bpm, a.meter, m.duration) for (_, _, m, a), s in zip(clips, short, strict=True) if not s]
    if not any(short):
        return clips
    if read:
        tempi, meters, weights = (np.array(x, np.float64) for x in zip(*read, strict=True))
        order = np.argsort(tempi)
        half = np.searchsorted(np.cumsum(weights[order]), weights.sum() / 2)
        bpm = float(tempi[order][min(half, len(order) - 1)])
        meter = int(max(set(meters.tolist()), key=lambda m: weights[meters == m].sum()))
        why = f"the library's {bpm:.0f} BPM"
    else:
        bpm, meter, why = PRIOR_BPM, FALLBACK_METER, f"{PRIOR_BPM:.0f} BPM, no clip long enough to read"
    out = []
    for (name, style, motion, a), s in zip(clips, short, strict=True):
        if s:
            told = STYLE_METER.get(style.strip().lower(), meter)
            again = analyze_clip(motion, style, bpm=bpm, meter=told)
            bars = f"style ({style.strip()})" if style.strip().lower() in STYLE_METER else "assumed"
            a = replace(again, confidence=0.0, source=f"tempo: assumed ({why}; too short to read), meter: {bars}")
        out.append((name, style, motion, a))
    return out


def _source(bpm: float | None, meter: int | None, style: str) -> str:
    """Where a clip's tempo and meter came from, as `library build` says it."""
    tempo = "manifest" if bpm is not None else "motion"
    if meter is not None:
        bars = "manifest"
    elif style.strip().lower() in STYLE_METER:
        bars = f"style ({style.strip()})"
    else:
        bars = "motion"
    return f"tempo: {tempo}, meter: {bars}"

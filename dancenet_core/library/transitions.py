"""Figures of a plan turned into one dance: each figure's frames sampled at its time-warped positions, the root
path and heading carried across cuts, and every cut inertialised.

A run is a stretch of figures that continue one clip; it is placed once (a turn about +Y and a shift on the floor),
so that its first frame stands where the run before it would have gone on to (its next frame in its own clip)
and faces the same way. At each cut the difference between that run's continuation and the new run (joint
rotations and the root, over the two frames before the cut) fades out over `CUT_BLEND_S` with the same
quintic as continuing a dance (no jump in place, speed or acceleration), as game engines inertialise. Last, the
root is moved on the floor so that a standing foot steps as in its clip, not as a blend drags it (`hold_stance`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial.transform import Rotation

from ..motion import Motion
from ..representation import foot_contacts, heading
from ..shaping.continuation import _fade
from ..shaping.floor import floor_lift, lowest_point
from ..shaping.placing import sample_frames, turned
from ..skeleton import BODY_JOINTS, TOE_ENDS
from .store import MotionLibrary

# How long a cut's offset takes to fade: longer than continuing a dance's 0.4 s (`continuation.BLEND_S`), because
# a cut joins unrelated poses; longer, a large velocity difference carries the offset further (docs/experiments.md).
CUT_BLEND_S = 0.5
# A cut whose fading offset would move some joint further in a frame than the library's dancers do (its 99th
# percentile step) fades longer, up to this: a slower fade moves the joints less per frame.
MAX_BLEND_S = 1.2
# Shares of a cut's velocity difference its fade carries, tried in turn until no joint steps past its percentile:
# carrying all of it, the fade must take back the ground the difference covers (about half the difference again,
# 0.6 into the fade, whatever its length).
VELOCITY_KEPT = (1.0, 0.5, 0.25, 0.0)
# A foot is held while it stands: near the floor and slower than this in its source clip. The capture's own contacts
# (`representation.CONTACT_SPEED_MPS`, 0.35 m/s) at the largest time-warp (about 30% faster) are 0.45 m/s.
HOLD_SPEED_MPS = 0.5
# The hold's root correction is smoothed over this many frames (a Gaussian's sigma): one that starts and stops
# with each contact shakes the body (see `hold_stance`).
HOLD_SMOOTH_FRAMES = 2.0
# A blend between two poses can take a foot (or a hand in floor work) through the floor that neither pose has there:
# the body is lifted, easing in and out, where its lowest point sinks further than this under the floor.
SINK_M = 0.04


@dataclass
class Figure:
    """A bar of the dance: `beats` song beats, at song times `times` ([beats + 1] seconds, one per beat and the next
    bar's first), danced by the library's beats from the library beat `start` (maybe between two beats: a figure
    that carries on from one that ended there), `ratio` of them per song beat (2: two
    clip beats in each song beat; 0.5: one in two; between two beats of the clip, its frames in proportion). The
    figure's first and last clip beats fall on the bar's first beat and the next bar's; between them it plays at
    one speed, so the dancer's own timing within the bar is kept (and a song's or a clip's unevenly tracked beats
    do not hurry one beat and drag the next)."""

    start: float
    beats: int
    times: np.ndarray
    ratio: float = 1.0

    @property
    def end(self) -> float:
        """The library beat (maybe between two) where the figure ends: the next figure's start if it carries on."""
        return self.start + self.ratio * self.beats

    def carries_on(self, nxt: Figure) -> bool:
        """Whether `nxt` starts where this figure ends (the clip's own continuation, no cut)."""
        return abs(self.end - nxt.start) < 1e-5

    def frames(self, library: MotionLibrary) -> np.ndarray:
        """[beats + 1]: the library frames (sub-frame) played at `times`."""
        first, last = beat_frames(library, np.array([self.start, self.end], np.float64))
        return first + (last - first) * (self.times - self.times[0]) / (self.times[-1] - self.times[0])


def beat_frames(library: MotionLibrary, position: np.ndarray) -> np.ndarray:
    """Library frames (sub-frame) at beat positions that may fall between two beats (linearly between them)."""
    lo = np.clip(np.floor(position).astype(np.int64), 0, len(library.beats) - 1)
    hi = np.minimum(lo + 1, len(library.beats) - 1)
    return library.beats[lo] * (1.0 - (position - lo)) + library.beats[hi] * (position - lo)


def _sample(library: MotionLibrary, pos: np.ndarray, clip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotations [T, J, 3] and root positions [T, 3] at fractional library frames `pos`, each within its clip
    `clip` (held at the clip's ends): `placing.sample_frames`."""
    first, last = library.clip_starts[clip], library.clip_starts[clip + 1] - 1
    return sample_frames(library.rotations, library.root_positions, np.clip(pos, first, last), first, last)


@dataclass
class Rendered:
    """A dance cut from a library: its frames, its cuts (first frame of each new run), how many frames each cut's
    blend took, and how far each body joint may step from each frame to the next ([T - 1, J] metres): its 99th
    percentile in the library, or the step its source clip makes there (time-warped and placed) where that is
    further; the step across a cut has no source step."""

    motion: Motion
    cuts: list[int]
    blends: list[int]
    step_bound: np.ndarray


def cut_window(cut: int, blend: int, fps: float) -> slice:
    """The steps a cut is answerable for: from the frame before it to the end of its blend (at least `CUT_BLEND_S`)."""
    return slice(max(cut - 1, 0), cut + max(blend, int(round(CUT_BLEND_S * fps)) + 1))


def cut_steps(rendered: Rendered) -> list[float]:
    """Per cut, the largest step the cut made over its window (`cut_window`): each joint's step over its bound
    (`Rendered.step_bound`), so that a clip's own fast frames, which a cut can only pass on, do not count against it."""
    pos = rendered.motion.positions()[:, :BODY_JOINTS]
    made = np.linalg.norm(np.diff(pos, axis=0), axis=-1) / rendered.step_bound
    return [float(made[cut_window(c, m, rendered.motion.fps)].max())
            for c, m in zip(rendered.cuts, rendered.blends, strict=True)]


def render(library: MotionLibrary, figures: list[Figure], start_s: float, end_s: float,
           kept: Motion | None = None) -> Rendered:
    """The dance from `start_s` to `end_s` (song seconds) at the library's frame rate (see `Rendered`).
    With `kept` (a dance at the library's frame rate that ends where this one starts) the first run goes on from
    its last pose as a run goes on after a cut: placed where the kept root would have gone on to, facing its way,
    and the difference from its last two frames faded out."""
    fps = library.fps
    n = max(2, int(round((end_s - start_s) * fps)))
    t = start_s + np.arange(n) / fps
    pos = np.empty(n)
    which = np.searchsorted([f.times[0] for f in figures], t, "right") - 1
    which = np.clip(which, 0, len(figures) - 1)
    for k, f in enumerate(figures):
        sel = which == k
        if sel.any():
            pos[sel] = np.interp(t[sel], f.times, f.frames(library))
    clip = library.beat_clip[np.floor(np.array([f.start for f in figures]) + 1e-6).astype(np.int64)][which]
    rot, root = _sample(library, pos, clip)

    # Runs: figures that continue one clip. Each is placed once; a cut starts a new run.
    new_run = np.array([k == 0 or not figures[k - 1].carries_on(f) for k, f in enumerate(figures)])
    run_of_figure = np.cumsum(new_run) - 1
    run = run_of_figure[which]
    cuts = [int(c) for c in np.flatnonzero(np.diff(run)) + 1]
    turn, shift = -float(heading(rot[:1, 0])[0]), np.zeros(2)
    placed_rot, placed_root = np.empty_like(rot), np.empty_like(root)
    contact = np.zeros((n, len(TOE_ENDS)), bool)  # the source clips' foot contacts, before any blend
    # the source clips' own toe steps on the floor, before any blend (none for an in-place clip: see `hold_stance`)
    own_toes = np.zeros((n - 1, len(TOE_ENDS), 2))
    own_steps = np.zeros((n - 1, BODY_JOINTS))  # the source clips' own steps, before any blend (0 across a cut)
    blends: list[int] = []  # frames each cut's offset takes to fade
    bounds = [0, *cuts, n]
    for r, (a, b) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
        if r == 0 and kept is None:
            shift = -Rotation.from_euler("y", turn).apply(root[0])[[0, 2]]
        elif r == 0:  # the kept dance's last pose, its root carried on by its last step
            turn, shift = _follow(kept.rotations[-1:], 2 * kept.root_positions[-1:] - kept.root_positions[-2:-1],
                                  rot[0], root[0])
        else:
            # Where the previous run would have gone on to, and which way it would have faced.
            prev_clip = np.array([clip[a - 1]])
            step = pos[a - 1] - pos[a - 2] if a >= 2 else 1.0
            nrot, nroot = _sample(library, np.array([pos[a - 1] + step]), prev_clip)
            turn, shift = _follow(*turned(nrot, nroot, turn, shift), rot[a], root[a])
        placed_rot[a:b], placed_root[a:b] = turned(rot[a:b], root[a:b], turn, shift)
        source = Motion(placed_rot[a:b], placed_root[a:b], fps, library.skeleton)
        toes = source.end_effectors()[:, list(TOE_ENDS)]
        contact[a:b] = foot_contacts(toes, fps, speed=HOLD_SPEED_MPS) > 0
        if not library.in_place[clip[a]]:
            own_toes[a : b - 1] = np.diff(toes[:, :, [0, 2]], axis=0)
        own_steps[a : b - 1] = np.linalg.norm(np.diff(source.positions()[:, :BODY_JOINTS], axis=0), axis=-1)
        # what the blend's steps may reach: from the step into frame a (none in the source) on
        bound = np.maximum(library.step_p99, np.concatenate([np.zeros((1, BODY_JOINTS)), own_steps[a : b - 1]]))
        if r > 0:  # the two frames before the cut (one twice when the dance's first figure is a frame long)
            before = [max(a - 2, 0), a - 1]
            blends.append(_inertialise(library, placed_rot, placed_root, placed_rot[before], placed_root[before],
                                       pos, clip, a, b, turn, shift, bound))
        elif kept is not None:
            _inertialise(library, placed_rot, placed_root, kept.rotations[-2:], kept.root_positions[-2:], pos, clip,
                         a, b, turn, shift, bound)
    stance = contact[1:] & contact[:-1]
    stance[np.array(cuts, np.int64) - 1] = False  # a cut's step is no stance of one clip
    motion = Motion(placed_rot, placed_root, fps, library.skeleton)
    step_bound = np.maximum(library.step_p99, own_steps)
    held = Motion(placed_rot, hold_stance(motion, stance, step_bound, own_toes), fps, library.skeleton)
    held.root_positions[:, 1] += floor_lift(lowest_point(held) + SINK_M)
    return Rendered(held, cuts, blends, step_bound)


def hold_stance(motion: Motion, stance: np.ndarray, step_limit: np.ndarray | None = None,
                own: np.ndarray | None = None) -> np.ndarray:
    """Root positions [T, 3] moved on the floor so that a foot standing from one frame to the next (`stance`
    [T - 1, 2]: the source clip's foot contact at both) steps as it does in its source clip (`own` [T - 1, 2, 2]:
    each toe's step on the floor there, placed and time-warped; without it, or 0 for a clip exported in place,
    stays where it is), two standing feet by their mean step, the body carried by the standing foot as a dancer's
    is. The contacts are the source's, so that a blend's motion of a planted foot is taken back. The correction is
    smoothed (`HOLD_SMOOTH_FRAMES`).

    Why: a blend moves a planted foot, and an in-place clip's standing feet slide by the travel taken out of it;
    moving the root rather than the legs keeps every pose of the capture and turns the in-place steps into travel.
    A captured foot's own glide or creep while it stands (a swivel, a ballroom dancer's foot gliding on the floor:
    half the dancers' contact frames slide) is the dancers' and is kept: taking it away too moved the whole body in
    jerks at each contact's start and end, the library's dances' torsos accelerating more than any dancer's
    (docs/experiments.md).

    With `step_limit` (how far each body joint may step, [BODY_JOINTS] or per step [T - 1, BODY_JOINTS]: its 99th
    percentile, or its source clip's own step where that is further) a frame's correction is scaled down (by
    quarters) where it would move some joint further than that while the motion itself does not: the blend
    moves a planted foot, and carrying the body after it pushes the hands past their percentile a few frames into
    a cut."""
    toes = motion.end_effectors()[:, list(TOE_ENDS)]
    step = np.diff(toes[:, :, [0, 2]], axis=0)
    if own is not None:
        step = step - own
    count = stance.sum(1, keepdims=True)
    slip = (step * stance[..., None]).sum(1) / np.maximum(count, 1)
    root = motion.root_positions.copy()
    slip = gaussian_filter1d(slip, HOLD_SMOOTH_FRAMES, axis=0)
    if step_limit is not None:
        slip *= _within_limit(np.diff(motion.positions()[:, :BODY_JOINTS], axis=0), slip, step_limit)[:, None]
    root[1:, [0, 2]] -= np.cumsum(slip, axis=0)
    return root


def _within_limit(steps: np.ndarray, slip: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """Per frame, the largest share (0, 1/4, ..., 1) of the floor correction `slip` [T - 1, 2] that keeps every
    joint's step (`steps` [T - 1, J, 3], less the correction) within `limit` ([J] or [T - 1, J]); where none does,
    the share whose largest step is least."""
    shares = np.linspace(0.0, 1.0, 5)
    worst = np.stack([(np.linalg.norm(steps - s * np.stack([slip[:, 0], np.zeros(len(slip)), slip[:, 1]], -1)[:, None],
                                      axis=-1) / limit).max(axis=1) for s in shares], axis=1)
    ok = worst <= 1.0
    largest = np.where(ok.any(axis=1), len(shares) - 1 - np.argmax(ok[:, ::-1], axis=1), np.argmin(worst, axis=1))
    return shares[largest]


def _follow(next_rot: np.ndarray, next_root: np.ndarray, rot: np.ndarray, root: np.ndarray) -> tuple[float, np.ndarray]:
    """The turn and floor shift that put a frame (rotations [J, 3], root [3]) where another run would have gone on
    to (its next frame, placed: [1, J, 3], [1, 3]), facing the same way."""
    turn = float(heading(next_rot[:, 0])[0] - heading(rot[None, 0])[0])
    return turn, next_root[0, [0, 2]] - Rotation.from_euler("y", turn).apply(root)[[0, 2]]


def _damped(history: np.ndarray, keep: float) -> np.ndarray:
    """The last two frames of a difference [2, ...] with its change per frame scaled by `keep`."""
    return np.stack([history[1] - keep * (history[1] - history[0]), history[1]])


def _inertialise(library: MotionLibrary, rot: np.ndarray, root: np.ndarray, old_rot: np.ndarray,
                 old_root: np.ndarray, pos: np.ndarray, clip: np.ndarray, a: int, b: int, turn: float,
                 shift: np.ndarray, bound: np.ndarray) -> int:
    """Fade the new run's (from frame `a`) difference from the old one's last two frames (`old_rot` [2, J, 3],
    `old_root` [2, 3]) out over its first frames (in place): over `CUT_BLEND_S`, or longer (up to `MAX_BLEND_S`),
    carrying less of the velocity difference (`VELOCITY_KEPT`), until no body joint steps further in a frame than
    `bound` [b - a, J] allows (its 99th percentile in the library, or its source clip's own step there: see
    `Rendered.step_bound`), where a longer fade gets there (else the fade whose largest step is least). Returns the
    frames it took."""
    step = pos[a + 1] - pos[a] if a + 1 < b else 1.0
    lead_rot, lead_root = _sample(library, pos[a] - step * np.array([2.0, 1.0]), np.repeat(clip[a], 2))
    lead_rot, lead_root = turned(lead_rot, lead_root, turn, shift)
    nj = rot.shape[1]
    rot_diff = (Rotation.from_rotvec(old_rot.reshape(-1, 3))
                * Rotation.from_rotvec(lead_rot.reshape(-1, 3)).inv()).as_rotvec().reshape(2, nj, 3)
    shortest = min(b - a, max(2, int(round(CUT_BLEND_S * library.fps))))
    longest = min(b - a, max(shortest, int(round(MAX_BLEND_S * library.fps))))
    before = Motion(old_rot[-1:], old_root[-1:], library.fps, library.skeleton).positions()[:, :BODY_JOINTS]
    root_diff = old_root - lead_root
    best = None
    for keep in VELOCITY_KEPT:
        for m in range(shortest, longest + 1, 2):
            offsets = Rotation.from_rotvec(_fade(m, _damped(rot_diff, keep)).reshape(-1, 3))
            blended = (offsets * Rotation.from_rotvec(rot[a : a + m].reshape(-1, 3))).as_rotvec().reshape(m, nj, 3)
            moved = root[a : a + m] + _fade(m, _damped(root_diff, keep))
            after = Motion(blended, moved, library.fps, library.skeleton).positions()[:, :BODY_JOINTS]
            worst = float((np.linalg.norm(np.diff(np.concatenate([before, after]), axis=0), axis=-1)
                           / bound[:m]).max())
            if best is None or worst < best[0]:
                best = (worst, m, blended, moved)
            if worst <= 1.0:
                break
        if best[0] <= 1.0:
            break
    _, m, blended, moved = best
    rot[a : a + m], root[a : a + m] = blended, moved
    return m

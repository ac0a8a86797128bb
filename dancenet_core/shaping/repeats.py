"""Returns danced again: where the music comes back (the song's form, `music.form`), the dance comes back too.

Any engine's take is rewritten section by section after it is danced: a section whose label was heard before (A2
after A1) takes the frames danced at an earlier occurrence of the label, bar by bar (each bar's time stretched onto
the new bar's, as the tempo may drift), either as they were ("repeat") or left and right swapped ("mirror"). A run
of returning sections that repeats a run of earlier music (A2 B2 after A1 B1) is one copy of that run, with one join
in and one out, as every join crossfades two dances that need not be alike. No copied bar plays more than
`constants.WARP_RANGE` faster or slower than its source (a downbeat the tracker missed makes a bar twice as long),
the engines' real-time limit. The copy is laid where the dancer stands and faces when it begins (the source's
heading turned onto the dancer's, its path moved to the dancer's place), and the dance after it is carried on from
where the copy ends (turned and moved rigidly), so the path and the heading never jump. Each join moves up to
JOIN_SLACK_S from the section's boundary, to where the two dances' poses are most alike, and crossfades over
JOIN_BLEND_S.

Sections are taken in order and copy from the dance as rewritten so far, so a third occurrence repeats the first
as it finally stands. A section whose source lies before the danced part (a part of the song), or within the
frames kept by a continued dance, is danced anew.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..constants import WARP_RANGE
from ..motion import Motion
from ..music.form import SongForm
from ..representation import heading_frames, yaw_and_swing
from .floor import toe_ends
from .placing import mixed, sample_frames, turned

JOIN_SLACK_S = 0.25  # a join may move this far from the section's boundary, to where the two dances are most alike
# How long a join's crossfade lasts: long enough that the join between two unrelated dances costs the dance's
# realism about nothing, short enough that the return stays alike to its source (measured in docs/experiments.md).
JOIN_BLEND_S = 1.2


def dance_returns(motion: Motion, form: SongForm, start_s: float, mode: str, keep_until_s: float = 0.0,
                  section_modes: dict[str, str] | None = None) -> tuple[Motion, np.ndarray]:
    """`motion` (danced from `start_s` seconds into the song) with each returning section danced as its first
    occurrence, and the source frame of every output frame [T] (its own index where nothing was copied), for
    whatever else follows the frames (the predicted foot contacts). `section_modes` gives some sections (by
    name: A2) a mode of their own."""
    frame_map = np.arange(motion.num_frames, dtype=float)
    edges = form.bar_starts - start_s  # bar boundaries in the dance's time
    fps = motion.fps
    slack = int(round(JOIN_SLACK_S * fps))
    for target, target_end, source, how in copies_danced(form, start_s, fps, motion.num_frames, mode, keep_until_s,
                                                         section_modes):
        n_bars = target_end - target
        first, last = int(np.ceil(edges[target] * fps)), min(int(np.ceil(edges[target_end] * fps)), motion.num_frames)
        # Source time of every frame the copy may cover (the joins may move by up to `slack` frames either way,
        # the crossfade out runs on after the section), bar against bar, carried on at the first and last bars'
        # pace beyond them.
        blend = int(round(JOIN_BLEND_S * fps))
        frames = np.arange(first - slack - 1, last + slack + blend, dtype=float)
        src_frames = _bar_map(frames, edges[target:target + n_bars + 1] * fps, edges[source:source + n_bars + 1] * fps)
        copy = _sample(motion, src_frames)
        if how == "mirror":
            copy = copy.mirrored()
        offset = first - slack - 1  # copy frame i stands for dance frame offset + i
        entry = _best_join(motion, copy, offset, range(first - slack, first + slack + 1))
        leave = motion.num_frames if last >= motion.num_frames else _best_join(
            motion, copy, offset, range(last - slack, min(last + slack, motion.num_frames) + 1))
        motion = _laid(motion, copy, offset, entry, leave, blend)
        frame_map[entry:leave] = frame_map[np.clip(np.round(src_frames[entry - offset:leave - offset]).astype(int), 0,
                                                   motion.num_frames - 1)]
    return motion, frame_map


def copies_danced(form: SongForm, start_s: float, fps: float, num_frames: int, mode: str, keep_until_s: float = 0.0,
                  section_modes: dict[str, str] | None = None) -> list[tuple[int, int, int, str]]:
    """The copies `dance_returns` lays on a dance of `num_frames` frames at `fps` (see its arguments): (first bar,
    end bar, source's first bar, mode) for each of `_copies` whose source lies within the danced part, after the
    frames kept, and that is long enough for its joins."""
    edges = form.bar_starts - start_s
    slack = int(round(JOIN_SLACK_S * fps))
    out = []
    for target, target_end, source, how in _copies(form, mode, section_modes or {}):
        t0, t1, s0 = edges[target] * fps, edges[target_end] * fps, edges[source] * fps
        first, last = int(np.ceil(t0)), min(int(np.ceil(t1)), num_frames)
        if s0 >= 0 and first - slack >= max(keep_until_s * fps, s0 + slack + 1) and last - first >= 4 * slack:
            out.append((target, target_end, source, how))
    return out


def _laid(motion: Motion, copy: Motion, offset: int, entry: int, leave: int, blend: int) -> Motion:
    """`motion` with frames [entry, leave) danced by `copy` (its frame i at dance frame offset + i), laid where
    the dancer stands and faces just before `entry`, and the dance after `leave` carried on from the copy
    (`carry_on`). The entry crossfades over `blend` frames from the dance to the copy, as animation systems
    blend two clips: both keep moving as they move, so the join adds no motion of its own."""
    placed = _placed(copy, entry - 1 - offset, motion[entry - 1:entry])
    rots = np.concatenate([motion.rotations[:entry], placed.rotations[entry - offset:]])
    root = np.concatenate([motion.root_positions[:entry], placed.root_positions[entry - offset:]])
    n = min(blend, leave - entry)
    _crossfade(motion, rots, root, entry, (motion.rotations[entry:entry + n], motion.root_positions[entry:entry + n]),
               (rots[entry:entry + n].copy(), root[entry:entry + n].copy()))
    head = Motion(rots, root, motion.fps, motion.skeleton)
    return carry_on(head, motion, leave)


def carry_on(head: Motion, dance: Motion, last: int) -> Motion:
    """`head`'s frames up to `last`, then `dance`'s from `last` on, carried on from where `head` is at `last`
    (turned and moved rigidly); `head`'s frames after `last` (a dance that runs on past the join) crossfade into
    them over JOIN_BLEND_S. As long as `dance`, or `head` cut there when nothing of `dance` follows."""
    t = dance.num_frames
    if last >= t:
        return head[:t]
    rest = _placed(dance[last - 1:], 0, head[last - 1:last])
    rots = np.concatenate([head.rotations[:last], rest.rotations[1:]])
    root = np.concatenate([head.root_positions[:last], rest.root_positions[1:]])
    n = min(int(round(JOIN_BLEND_S * dance.fps)), t - last, head.num_frames - last)
    _crossfade(dance, rots, root, last, (head.rotations[last:last + n], head.root_positions[last:last + n]),
               (rots[last:last + n].copy(), root[last:last + n].copy()))
    return Motion(rots, root, dance.fps, dance.skeleton)


def _crossfade(motion: Motion, rots: np.ndarray, root: np.ndarray, at: int, a: tuple[np.ndarray, np.ndarray],
               b: tuple[np.ndarray, np.ndarray]) -> None:
    """Frames from `at` on (as many as `a`'s rotations have) written as `a` (rotations, root) turning into `b` (a
    smoothstep of weights), both going on from frame `at - 1`; the hips raised or lowered so that the lower toe is
    as high as the two dances' weighted, so a foot on the floor in both stays on it through the blend (`motion`:
    the skeleton and rate). The heading and the path over the floor take the weighted mean of the two dances' turns
    and of their steps (each in its own heading), and the frames after the blend turn and move with them: a
    weighted mean of two headings or places would add the rate at which the dances part, a spin or a slide (up to
    a metre per second) where they turn or travel different ways."""
    (a_rot, a_root), (b_rot, b_root) = a, b
    n = len(a_rot)
    if n == 0:
        return
    x = np.arange(1, n + 1) / (n + 1)
    w = (x * x * (3 - 2 * x))[:, None]
    qa = Rotation.from_rotvec(a_rot.reshape(-1, 3)).as_quat().reshape(n, -1, 4)
    qb = Rotation.from_rotvec(b_rot.reshape(-1, 3)).as_quat().reshape(n, -1, 4)
    rots[at:at + n] = _blend(qa, qb, w)
    before = max(at - 1, 0)
    yaw0 = yaw_and_swing(rots[before:before + 1, 0])[0][0]
    (yaw_a, swing_a), (yaw_b, swing_b) = yaw_and_swing(a_rot[:, 0]), yaw_and_swing(b_rot[:, 0])
    yaw_a, yaw_b = (np.unwrap(np.concatenate([[yaw0], y])) for y in (yaw_a, yaw_b))  # from frame at - 1
    yaw = yaw0 + np.cumsum((1 - w[:, 0]) * np.diff(yaw_a) + w[:, 0] * np.diff(yaw_b))
    swing = _blend(Rotation.from_rotvec(swing_a).as_quat()[:, None], Rotation.from_rotvec(swing_b).as_quat()[:, None],
                   w)[:, 0]
    rots[at:at + n, 0] = (Rotation.from_euler("y", yaw[:, None]) * Rotation.from_rotvec(swing)).as_rotvec()

    def own_steps(path: np.ndarray, turned: np.ndarray) -> np.ndarray:
        """Each frame's step over the floor [n, 3] in the heading its dance had the frame before."""
        step = np.diff(path * [1.0, 0.0, 1.0], axis=0, prepend=root[before:before + 1] * [1.0, 0.0, 1.0])
        return Rotation.from_euler("y", -turned[:-1, None]).apply(step)

    steps = (1 - w) * own_steps(a_root, yaw_a) + w * own_steps(b_root, yaw_b)
    heading = Rotation.from_euler("y", np.concatenate([[yaw0], yaw[:-1]])[:, None])
    root[at:at + n] = root[before] * [1.0, 0.0, 1.0] + np.cumsum(heading.apply(steps), axis=0)
    root[at:at + n, 1] = a_root[:, 1] * (1 - w[:, 0]) + b_root[:, 1] * w[:, 0]
    if at + n < len(root):  # the rest of b goes on from its last frame, placed where the blend's last stands
        end = at + n
        b_on = Motion(np.concatenate([b_rot[-1:], rots[end:]]), np.concatenate([b_root[-1:], root[end:]]), motion.fps,
                      motion.skeleton)
        rest = _placed(b_on, 0, Motion(rots[end - 1:end], root[end - 1:end], motion.fps, motion.skeleton))
        rots[end:], root[end:] = rest.rotations[1:], rest.root_positions[1:]

    def lowest(r: np.ndarray, p: np.ndarray) -> np.ndarray:
        return toe_ends(Motion(r, p, motion.fps, motion.skeleton))[..., 1].min(axis=1)

    want = lowest(a_rot, a_root) * (1 - w[:, 0]) + lowest(b_rot, b_root) * w[:, 0]
    root[at:at + n, 1] += want - lowest(rots[at:at + n], root[at:at + n])


def _blend(q0: np.ndarray, q1: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Rotation vectors [N, J, 3] of two runs of quaternions [N, J, 4] blended frame by frame at weights [N, 1]
    (normalised linear interpolation) without a jump: each run's sign carried on from frame to frame, and `q1`'s
    set per joint for the whole blend, the short way where the blend weighs both most. The short way chosen frame
    by frame flips to the other way round at a joint whose two poses are about half a turn apart mid-blend: a
    jump of up to a full turn in one frame."""
    def carried(q: np.ndarray) -> np.ndarray:
        flips = np.concatenate([np.zeros((1, q.shape[1])), (q[1:] * q[:-1]).sum(-1) < 0])
        return q * np.where(np.cumsum(flips, axis=0) % 2 == 1, -1.0, 1.0)[..., None]

    q0, q1 = carried(q0), carried(q1)
    side = ((q0 * q1).sum(-1) * w * (1 - w)).sum(0)  # [J]
    return mixed(q0, np.where(side[:, None] < 0, -q1, q1), w)


def _bar_map(frames: np.ndarray, target: np.ndarray, source: np.ndarray) -> np.ndarray:
    """Source frame of each target frame: bar against bar within the bars, at the first and last bars' pace
    before and after them."""
    out = np.interp(frames, target, source)
    before, after = frames < target[0], frames > target[-1]
    out[before] = source[0] - (target[0] - frames[before]) * (source[1] - source[0]) / (target[1] - target[0])
    out[after] = source[-1] + (frames[after] - target[-1]) * (source[-1] - source[-2]) / (target[-1] - target[-2])
    return out


def _best_join(motion: Motion, copy: Motion, offset: int, candidates: range) -> int:
    """The frame among `candidates` where the dance and the copy (its frame i at dance frame offset + i) are most
    alike just before it: the sum over the joints below the root of the turn between their local rotations (the
    root's heading and place are laid on by the join itself)."""
    frames = np.array([c for c in candidates if 0 < c <= motion.num_frames and 0 < c - offset <= copy.num_frames])
    a = Rotation.from_rotvec(motion.rotations[frames - 1, 1:].reshape(-1, 3))
    b = Rotation.from_rotvec(copy.rotations[frames - 1 - offset, 1:].reshape(-1, 3))
    turn = (a * b.inv()).magnitude().reshape(len(frames), -1).sum(axis=1)
    return int(frames[np.argmin(turn)])


def _copies(form: SongForm, mode: str, section_modes: dict[str, str]) -> list[tuple[int, int, int, str]]:
    """(first bar, end bar, source's first bar, mode) for each run of returning sections danced again (repeat or
    mirror, by its own mode or the dance's): a return and the returns right after it copy the earlier occurrence of
    its label that the most of them carry on from (A3 C2 copy A2 C1 rather than A1 and C1 apart; the first
    occurrence when none carries further), as one copy; bars against bars, as many as both have, cut where a bar's
    length is off its source's by more than WARP_RANGE."""
    sections = form.sections
    modes = [section_modes.get(s.name, mode) for s in sections]
    runs: list[tuple[int, int, int, str]] = []
    i = 0
    while i < len(sections):
        if sections[i].occurrence == 1 or modes[i] == "anew":
            i += 1
            continue
        target = sections[i].first_bar
        best: tuple[int, int, int] = (0, 0, 0)  # sections covered, bars, source's first bar
        for source in (s for s in sections[:i] if s.label == sections[i].label):
            bars = min(sections[i].bars, source.bars, target - source.first_bar)  # never reads what it writes
            covered = 1
            for j in range(i + 1, len(sections)):
                carry = source.first_bar + bars  # where the run's source goes on
                on = next((s for s in sections[:j] if s.first_bar == carry and s.label == sections[j].label), None)
                if (on is None or modes[j] != modes[i] or sections[j].occurrence == 1
                        or sections[j].first_bar != target + bars or carry + sections[j].bars > target):
                    break
                bars, covered = bars + min(sections[j].bars, on.bars), covered + 1
                if on.bars < sections[j].bars:
                    break
            if covered > best[0]:
                best = (covered, bars, source.first_bar)
        covered, bars, source_bar = best
        runs += _within_warp(form.bar_starts, target, target + bars, source_bar, modes[i])
        i += covered
    return runs


def _within_warp(edges: np.ndarray, first: int, end: int, source: int, how: str) -> list[tuple[int, int, int, str]]:
    """The copy of bars [first, end) from `source` on, as the runs of its bars whose length is within WARP_RANGE of
    their source bar's (of two bars or more: a shorter one would be little more than its joins)."""
    n = end - first
    ratio = np.diff(edges[first:end + 1]) / np.diff(edges[source:source + n + 1])
    good = np.concatenate([[False], np.abs(ratio - 1.0) <= WARP_RANGE, [False]])
    starts, ends = np.flatnonzero(good[1:] & ~good[:-1]), np.flatnonzero(~good[1:] & good[:-1])
    return [(first + a, first + b, source + a, how) for a, b in zip(starts, ends, strict=True) if b - a >= 2]


def _sample(motion: Motion, frames: np.ndarray) -> Motion:
    """The motion at fractional frames (`placing.sample_frames`), as a Motion; frames before the first carry on its
    first step backwards (a phrase copied from the dance's start still has a lead-in that moves as the dance
    moves), frames after the last hold it."""
    rots, root = sample_frames(motion.rotations, motion.root_positions, np.minimum(frames, motion.num_frames - 1))
    return Motion(rots, root, motion.fps, motion.skeleton)


def _heading(motion: Motion, k: int) -> float:
    """Frame k's heading (yaw about +Y)."""
    return float(heading_frames(motion[k:k + 1])[0])


def _placed(piece: Motion, k: int, at: Motion) -> Motion:
    """`piece` turned about the vertical and moved across the floor so that its frame k stands where `at` (one
    frame) stands and faces where it faces (its height and its pose untouched)."""
    yaw = _heading(at, 0) - _heading(piece, k)
    shift = (at.root_positions[0] - Rotation.from_euler("y", yaw).apply(piece.root_positions[k]))[[0, 2]]
    rots, root = turned(piece.rotations, piece.root_positions, yaw, shift)
    return Motion(rots, root, piece.fps, piece.skeleton)

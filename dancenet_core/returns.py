"""Returns danced again: where the music comes back (the song's form, `music.form`), the dance comes back too.

Any engine's take is rewritten phrase by phrase after it is danced: a phrase whose music repeats an earlier one
takes the frames danced there, bar by bar (each bar's time stretched onto the new bar's, as the tempo may
drift), either as they were ("repeat") or left and right swapped ("mirror"). The copy is laid where the dancer
stands and faces when the phrase begins (the source's heading turned onto the dancer's, its path moved to the
dancer's place), and the dance after it is carried on from where the copy ends (turned and moved rigidly), so
the path and the heading never jump. Both joins are blended as Continue From Here blends (`continuation.splice`:
the offset's value, slope and curvature fade to nothing over `continuation.BLEND_S`).

Phrases are taken in order and copy from the dance as rewritten so far, so a third hearing repeats the first as
it finally stands. A phrase whose source lies before the danced part (a part of the song), or within the frames
kept by a continued dance, is danced anew.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .continuation import DIFFERENCES, splice
from .motion import Motion
from .music.form import SongForm
from .representation import heading_frames

RETURN_MODES = ("repeat", "mirror", "anew")


def dance_returns(motion: Motion, form: SongForm, start_s: float, mode: str, keep_until_s: float = 0.0,
                  section_modes: dict[str, str] | None = None) -> tuple[Motion, np.ndarray]:
    """`motion` (danced from `start_s` seconds into the song) with each returning phrase danced as its first
    hearing, and the source frame of every output frame [T] (its own index where nothing was copied), for
    whatever else follows the frames (the predicted foot contacts). `section_modes` gives some sections (by
    name: A2) a mode of their own."""
    frame_map = np.arange(motion.num_frames, dtype=float)
    edges = form.bar_starts - start_s  # bar boundaries in the dance's time
    fps = motion.fps
    for target, target_end, source, how in _copies(form, mode, section_modes or {}):
        t0, t1 = edges[target] * fps, edges[target_end] * fps
        s0 = edges[source] * fps
        n_bars = target_end - target
        if s0 < 0 or t0 < max(keep_until_s * fps, s0 + DIFFERENCES) or t0 >= motion.num_frames - 1:
            continue
        first, last = int(np.ceil(t0)), min(int(np.ceil(t1)), motion.num_frames)
        if last - first < 2:
            continue
        # Source time of each target frame, bar against bar; the DIFFERENCES frames before the phrase too, so
        # the join can compare the copy's lead-in with the frames the dancer just danced.
        frames = np.arange(first - DIFFERENCES, last, dtype=float)
        src_frames = np.interp(frames, edges[target:target + n_bars + 1] * fps, edges[source:source + n_bars + 1] * fps,
                               left=np.nan)
        lead = np.isnan(src_frames)
        src_frames[lead] = s0 - (first - frames[lead]) * (edges[source + 1] - edges[source]) / (
            edges[target + 1] - edges[target])
        copy = _sample(motion, src_frames)
        if how == "mirror":
            copy = copy.mirrored()
        motion = carry_on(lay_in(motion, copy, first), motion, last)
        frame_map[first:last] = frame_map[np.clip(np.round(src_frames[DIFFERENCES:]).astype(int), 0,
                                                  motion.num_frames - 1)]
    return motion, frame_map


def _copies(form: SongForm, mode: str, section_modes: dict[str, str]) -> list[tuple[int, int, int, str]]:
    """(first bar, end bar, source's first bar, mode) for each run of phrases that repeats consecutive earlier
    bars and is danced again (repeat or mirror) by the mode of the section it lies in."""
    out: list[tuple[int, int, int, str]] = []
    n_bars = len(form.bar_starts) - 1
    for k, phrase in enumerate(form.phrases):
        end = form.phrases[k + 1].first_bar if k + 1 < len(form.phrases) else n_bars
        section = next((s for s in form.sections if s.first_bar <= phrase.first_bar < s.first_bar + s.bars), None)
        how = section_modes.get(section.name, mode) if section is not None else mode
        if phrase.source_bar is None or how == "anew":
            continue
        end = min(end, phrase.first_bar + (phrase.first_bar - phrase.source_bar))  # never reads what it writes
        last = out[-1] if out else None
        if last is not None and last[1] == phrase.first_bar and last[3] == how and \
                last[2] + (last[1] - last[0]) == phrase.source_bar:
            out[-1] = (last[0], end, last[2], how)
        else:
            out.append((phrase.first_bar, end, phrase.source_bar, how))
    return out


def _sample(motion: Motion, frames: np.ndarray) -> Motion:
    """The motion at fractional frames (rotations by normalised quaternion interpolation, which between
    neighbouring frames is slerp to within 1e-4 rad at a quarter the cost; the root linear), as a Motion;
    frames before the first carry on its first step backwards (a phrase copied from the dance's start still
    has a lead-in that moves as the dance moves)."""
    frames = np.minimum(frames, motion.num_frames - 1)
    lo = np.clip(np.floor(frames).astype(int), 0, max(0, motion.num_frames - 2))
    hi = np.minimum(lo + 1, motion.num_frames - 1)
    w = (frames - lo)[:, None]
    first, last = lo.min(), hi.max() + 1
    q = Rotation.from_rotvec(motion.rotations[first:last].reshape(-1, 3)).as_quat().reshape(last - first, -1, 4)
    q0, q1 = q[lo - first], q[hi - first]
    q1 = np.where((q0 * q1).sum(-1, keepdims=True) < 0, -q1, q1)  # the short way round
    mixed = q0 * (1 - w[:, :, None]) + q1 * w[:, :, None]
    rots = Rotation.from_quat(mixed.reshape(-1, 4)).as_rotvec().reshape(len(frames), -1, 3)
    root = motion.root_positions[lo] * (1 - w) + motion.root_positions[hi] * w
    return Motion(rots, root, motion.fps, motion.skeleton)


def _heading(motion: Motion, k: int) -> float:
    """Frame k's heading (yaw about +Y)."""
    return float(heading_frames(motion[k:k + 1])[0])


def _placed(piece: Motion, at: Motion, k: int) -> Motion:
    """`piece` turned about the vertical and moved across the floor so that its frame k stands where `at`'s
    frame k stands and faces where it faces (its height and its pose untouched)."""
    yaw = _heading(at, k) - _heading(piece, k)
    turn = Rotation.from_euler("y", yaw)
    root = piece.root_positions - piece.root_positions[k] * np.array([1.0, 0.0, 1.0])
    root = turn.apply(root) + at.root_positions[k] * np.array([1.0, 0.0, 1.0])
    rots = piece.rotations.copy()
    rots[:, 0] = (turn * Rotation.from_rotvec(rots[:, 0])).as_rotvec()
    return Motion(rots, root, piece.fps, piece.skeleton)


def lay_in(motion: Motion, piece: Motion, first: int) -> Motion:
    """`motion`'s frames before `first`, then `piece` after its first DIFFERENCES frames (which stand for the
    frames before `first`): laid where the dancer stands and faces, the join blended."""
    h = DIFFERENCES
    lead_in = motion[first - h:first]
    piece = _placed(piece, Motion(np.concatenate([lead_in.rotations, piece.rotations[h:]]),
                                  np.concatenate([lead_in.root_positions, piece.root_positions[h:]]),
                                  motion.fps, motion.skeleton), h - 1)
    return splice(motion[:first], piece, first, h)


def carry_on(head: Motion, dance: Motion, last: int) -> Motion:
    """`head` (frames up to `last`), then `dance`'s frames from `last` on, carried on from where `head` ends
    (turned and moved rigidly) and joined; `head` alone when `dance` has nothing after `last`."""
    if last >= dance.num_frames:
        return head
    h = DIFFERENCES
    rest = dance[last - h:]
    rest = _placed(rest, Motion(np.concatenate([head.rotations[last - h:last], rest.rotations[h:]]),
                                np.concatenate([head.root_positions[last - h:last], rest.root_positions[h:]]),
                                dance.fps, dance.skeleton), h - 1)
    return splice(head[:last], rest, last, h)


def figures_as_danced(figures: list[dict], frame_map: np.ndarray, fps: float, start_s: float) -> list[dict]:
    """A plan's figures (`choreography.Report.figures`: clip, clip_s, song_s, ratio) as the take dances them once
    its returns are danced again (`frame_map` from `dance_returns`): each run of frames that plays on through one
    figure of the plan, with where in the song it now plays and where in its clip it starts and ends."""
    if not figures or not len(frame_map):
        return figures
    song0 = np.array([f["song_s"][0] for f in figures])
    planned = start_s + frame_map / fps  # where in the song the plan danced each frame
    row = np.clip(np.searchsorted(song0, planned, side="right") - 1, 0, len(figures) - 1)
    cut = np.flatnonzero((np.diff(row) != 0) | (np.abs(np.diff(frame_map) - 1.0) > 0.5)) + 1
    out = []
    for a, b in zip([0, *cut], [*cut, len(frame_map)], strict=True):
        f = figures[row[a]]
        (s0, s1), (c0, c1) = f["song_s"], f["clip_s"]

        def clip_at(t: float, s0: float = s0, s1: float = s1, c0: float = c0, c1: float = c1) -> float:
            return round(float(c0 + (c1 - c0) * np.clip((t - s0) / max(s1 - s0, 1e-9), 0.0, 1.0)), 3)

        out.append({"clip": f["clip"], "clip_s": [clip_at(planned[a]), clip_at(planned[b - 1] + 1 / fps)],
                    "song_s": [round(start_s + a / fps, 3), round(start_s + b / fps, 3)], "ratio": f["ratio"]})
    return out

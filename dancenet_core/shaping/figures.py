"""The figure list of a library take: one entry per figure danced, the returns included.

The plan's rows (`choreography.Report.figures`: a bar each) are joined where a bar carries on its clip from where
the one before left it (one figure over several bars), and the song's returning sections (`repeats.copies_danced`)
are listed as the figures they copy, each saying which earlier span of the song it repeats and whether mirrored.
The list is read bar by bar: a copy starts and ends on bars, as its joins are planned (they may move up to
`repeats.JOIN_SLACK_S` and crossfade over `repeats.JOIN_BLEND_S`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

# Where a copy's bar and a figure's bar are this close (seconds), they are one boundary: the song's form and the
# plan read their bars from the same downbeats, to a frame or so.
SNAP_S = 0.25


@dataclass(frozen=True)
class _Figure:
    """A figure as danced: its clip, the song seconds `song` [K] at which it plays clip seconds `clip_s` [K]
    (linear between them), and for a copy the song seconds `source` [K] where it was danced before."""

    clip: str
    song: np.ndarray
    clip_s: np.ndarray
    source: np.ndarray | None = None
    mirrored: bool = False

    def cut(self, a: float, b: float) -> _Figure | None:
        """The part of the figure danced within song seconds [a, b] (None: none of it)."""
        a, b = max(a, self.song[0]), min(b, self.song[-1])
        if b - a < 1e-6:
            return None
        song = np.array([a, *self.song[(self.song > a) & (self.song < b)], b])
        source = None if self.source is None else np.interp(song, self.song, self.source)
        return replace(self, song=song, clip_s=np.interp(song, self.song, self.clip_s), source=source)

    def extended(self, t: float) -> _Figure:
        """The figure danced on to song second `t` before its start or after its end, at the pace of its nearest
        stretch."""
        end = 0 if t < self.song[0] else -1
        pace = np.diff(self.clip_s)[end] / max(np.diff(self.song)[end], 1e-9)
        knot = self.clip_s[end] + pace * (t - self.song[end])
        song, clip_s = ([t, *self.song], [knot, *self.clip_s]) if end == 0 else ([*self.song, t], [*self.clip_s, knot])
        return replace(self, song=np.array(song), clip_s=np.array(clip_s))

    def carried_on_by(self, other: _Figure, tolerance: float) -> bool:
        """Whether `other` dances on from where this one ends: the same clip from the same place, right after
        it (and, for copies, from right after its source, mirrored alike)."""
        same = (other.clip == self.clip and abs(other.song[0] - self.song[-1]) < 1e-6
                and abs(other.clip_s[0] - self.clip_s[-1]) <= tolerance)
        if (self.source is None) != (other.source is None):
            return False
        return same and (self.source is None or (other.mirrored == self.mirrored
                                                 and abs(other.source[0] - self.source[-1]) < 1e-6))

    def joined(self, other: _Figure) -> _Figure:
        source = None if self.source is None else np.concatenate([self.source, other.source[1:]])
        return replace(self, song=np.concatenate([self.song, other.song[1:]]),
                       clip_s=np.concatenate([self.clip_s, other.clip_s[1:]]), source=source)

    def to_dict(self) -> dict:
        (s0, s1), (c0, c1) = self.song[[0, -1]], self.clip_s[[0, -1]]
        out = {"clip": self.clip, "clip_s": [round(float(c0), 3), round(float(c1), 3)],
               "song_s": [round(float(s0), 3), round(float(s1), 3)],
               "warp": round(float((c1 - c0) / max(s1 - s0, 1e-9)), 3)}
        if self.source is not None:
            out["repeats"] = {"song_span": [round(float(self.source[0]), 3), round(float(self.source[-1]), 3)],
                              "mirrored": self.mirrored}
        return out


def danced_figures(rows: list[dict], copies: list[tuple[np.ndarray, np.ndarray, bool]], end_s: float,
                   fps: float) -> list[dict]:
    """The figure list (see the module's docstring) from the plan's rows (clip, clip_s, song_s) and the copies
    the take dances in order (target bar starts [n + 1], source bar starts [n + 1], mirrored; song seconds), a
    copy cut at `end_s`, the dance's end. Each entry: clip, clip_s, song_s, warp (clip seconds danced per song
    second: 1 as captured) and, for a copy, repeats (the song span it repeats, mirrored or not)."""
    figures = _joined(_folded([_Figure(r["clip"], np.array(r["song_s"], float), np.array(r["clip_s"], float))
                               for r in rows]), 0.5 / fps)
    for target, source, mirrored in copies:
        bounds = np.array(sorted({f.song[0] for f in figures} | {f.song[-1] for f in figures}))
        target, source = _snapped(target, bounds), _snapped(source, bounds)
        t0, t1 = float(target[0]), min(float(target[-1]), end_s)
        copied = []
        for f in figures:
            part = f.cut(float(source[0]), float(source[-1]))
            if part is not None:
                song = np.interp(part.song, source, target)
                copied.append(_Figure(f.clip, song, part.clip_s, part.song, mirrored).cut(t0, t1))
        figures = ([p for f in figures if (p := f.cut(-np.inf, t0)) is not None] + [c for c in copied if c]
                   + [p for f in figures if (p := f.cut(float(target[-1]), np.inf)) is not None])
    return [f.to_dict() for f in _joined(figures, 0.5 / fps)]


def _snapped(times: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """`times` each moved onto the nearest of `bounds` within SNAP_S."""
    if not len(bounds):
        return times
    near = bounds[np.argmin(np.abs(times[:, None] - bounds[None, :]), axis=1)]
    return np.where(np.abs(near - times) <= SNAP_S, near, times)


def _folded(figures: list[_Figure]) -> list[_Figure]:
    """The plan's figures with one danced for less than SNAP_S (a bar begun before the part's start, or a frame
    the part's end leaves) counted with its neighbour, which is extended at its own pace to cover it."""
    out: list[_Figure] = []
    for f in figures:
        if out and out[-1].song[-1] - out[-1].song[0] < SNAP_S:
            f = f.extended(out.pop().song[0])
        elif out and f.song[-1] - f.song[0] < SNAP_S:
            out[-1] = out[-1].extended(f.song[-1])
            continue
        out.append(f)
    return out


def _joined(figures: list[_Figure], tolerance: float) -> list[_Figure]:
    """Figures with each one that carries on the one before (within `tolerance` clip seconds) joined to it."""
    out: list[_Figure] = []
    for f in figures:
        if out and out[-1].carried_on_by(f, tolerance):
            out[-1] = out[-1].joined(f)
        else:
            out.append(f)
    return out


def spliced(rows: list[dict], new: list[dict], a: float, b: float) -> list[dict]:
    """The plan's rows with song seconds [a, b] danced by the rows `new` (a section danced anew), each row cut
    to what is danced of it."""
    def part(row: dict, lo: float, hi: float) -> dict | None:
        f = _Figure(row["clip"], np.array(row["song_s"], float), np.array(row["clip_s"], float)).cut(lo, hi)
        return None if f is None else row | {"song_s": [round(float(t), 3) for t in f.song[[0, -1]]],
                                             "clip_s": [round(float(t), 3) for t in f.clip_s[[0, -1]]]}

    return ([p for r in rows if (p := part(r, -np.inf, a))] + [p for r in new if (p := part(r, a, b))]
            + [p for r in rows if (p := part(r, b, np.inf))])

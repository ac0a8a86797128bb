"""The song's form from its music: sections that start on downbeats, and which of them return (A1 B1 A2 ...).

What a choreographer hears first is the form: the chorus that comes back is danced again. It is read here from
the features the dance already uses (deep chroma and onsets at 10 fps, beats and downbeats), so it costs
milliseconds once a song is analysed:

1. Bars. Each bar (downbeat to downbeat; the pickup before the first downbeat joins the first bar) is described
   by the chroma at `BAR_POINTS` points through it (the harmony and the order of its changes) and the onset
   strength there (where the accents fall), each column standardised over the song so that what every bar shares
   does not count.
2. Self-similarity. S[i, j] is the cosine of bars i and j. A passage that returns shows as a stripe of high
   similarity parallel to the diagonal; a change of section as a change of block.
3. Phrases. The song is cut into phrases of `PHRASE_BARS` bars on the grid (one of its `PHRASE_BARS` offsets)
   where repeats line up best; a pickup shorter than that joins the first phrase. A phrase repeats the earlier
   phrase heard for the first time that it matches best, bar against bar (the mean of S along their aligned
   diagonal), when that match passes `RETURN_SIMILARITY`.
4. Sections. Runs of phrases heard for the first time, and runs that repeat consecutive earlier music, cut
   wherever a repeat's source begins or ends (so that a return of A B shows as A then B); a repeat takes the
   label of the section it repeats, new music the next label (A ... Z, AA, AB, ...), and music played twice at
   once stays one section. A song too short for two sections, or with too few downbeats, is one section.

Hand-written in numpy rather than through librosa's segmentation: the analysis already has the bars, and the
few matrix operations on a few hundred bars take under 10 ms, with no new dependency for the add-on.
"""

from __future__ import annotations

import string
from dataclasses import dataclass

import numpy as np

from .features import BEAT_COL, DOWNBEAT_COL, MusicAnalysis

BAR_POINTS = 8  # where in the bar the chroma and onsets are read (eighths of a 4/4 bar, near-thirds of a beat in 3/4)
PHRASE_BARS = 4  # a phrase of the grid
MIN_SECTION_BARS = 4
# A phrase repeats an earlier one when its bars match that one's this closely (mean cosine of standardised bar
# features along the aligned diagonal). The same music played again scores 0.74-1.0 on the songs bench/form.py
# arranges from training songs (the beat grid moves a little).
RETURN_SIMILARITY = 0.6


@dataclass(frozen=True)
class Section:
    """A stretch of the song from one downbeat to another, with the label it shares with its returns."""

    label: str  # "A", "B", ... "Z", "AA", ... (`section_label`)
    occurrence: int  # 1 for the first time the label is heard, 2 for its first return, ...
    start_s: float
    end_s: float
    first_bar: int  # index of its first bar in `SongForm.bar_starts`
    bars: int
    match: float  # bar-by-bar similarity to what it repeats (1.0 for music heard for the first time)

    @property
    def name(self) -> str:
        """The marker name users see: A1, B1, A2, ..."""
        return f"{self.label}{self.occurrence}"

    def to_dict(self) -> dict:
        return {"name": self.name, "label": self.label, "start_s": round(self.start_s, 3),
                "end_s": round(self.end_s, 3), "bars": self.bars, "match": round(self.match, 3)}


@dataclass(frozen=True)
class Phrase:
    """A phrase of the grid (its bars run to the next phrase's first bar) and what it repeats."""

    first_bar: int
    source_bar: int | None  # the first bar of the earlier phrase it repeats (None: heard for the first time)
    match: float


@dataclass(frozen=True)
class SongForm:
    """The song's bars (start times, and the song's end after the last), its phrases and its sections in order."""

    bar_starts: np.ndarray  # [B + 1] seconds: each bar's start, then the end of the last bar (the song's end)
    phrases: tuple[Phrase, ...]
    sections: tuple[Section, ...]

    @property
    def labels(self) -> str:
        """The sections' labels in order: "ABACAB", spaced ("A B ... AA B") where some label has two letters."""
        return ("" if all(len(s.label) == 1 for s in self.sections) else " ").join(s.label for s in self.sections)

    def to_dict(self) -> dict:
        return {"labels": self.labels, "sections": [s.to_dict() for s in self.sections]}


def bar_grid(analysis: MusicAnalysis) -> np.ndarray:
    """Bar boundaries [B + 1] in seconds: 0, the downbeats, and the song's end. A pickup before the first
    downbeat shorter than half a bar belongs to the first bar, and so does a last bar that short to the one
    before."""
    down = np.asarray(analysis.downbeat_times, dtype=float)
    inner = down[(down > 0.0) & (down < analysis.duration_s)]
    if len(inner) < 2:
        return np.array([0.0, analysis.duration_s])
    half = 0.5 * np.median(np.diff(inner))
    edges = np.concatenate([[0.0], inner[1:] if inner[0] < half else inner, [analysis.duration_s]])
    if len(edges) > 2 and edges[-1] - edges[-2] < half:
        edges = np.delete(edges, -2)
    return edges


def bar_features(analysis: MusicAnalysis, edges: np.ndarray) -> np.ndarray:
    """[B, BAR_POINTS * 13]: chroma and onset strength at `BAR_POINTS` points through each bar, each column
    standardised over the song."""
    feats = analysis.features
    keep = [c for c in range(feats.shape[1]) if c not in (BEAT_COL, DOWNBEAT_COL)]
    fraction = (np.arange(BAR_POINTS) + 0.5) / BAR_POINTS
    times = edges[:-1, None] + fraction[None, :] * np.diff(edges)[:, None]
    frames = np.clip(np.round(times * analysis.fps).astype(int), 0, len(feats) - 1)
    x = feats[frames][:, :, keep].reshape(len(edges) - 1, -1).astype(float)
    x -= x.mean(axis=0)
    x /= x.std(axis=0) + 1e-6
    return x


def self_similarity(x: np.ndarray) -> np.ndarray:
    """Cosine similarity of every pair of rows."""
    unit = x / (np.linalg.norm(x, axis=1, keepdims=True) + 1e-9)
    return unit @ unit.T


def aligned_match(sim: np.ndarray, a: int, b: int, length: int) -> float:
    """Mean similarity of bar a + k to bar b + k over k < length."""
    k = np.arange(length)
    return float(sim[a + k, b + k].mean())


def phrase_sources(sim: np.ndarray, anchor: int) -> list[tuple[int, int | None, float]]:
    """For each phrase of the grid from `anchor` (the bars before it join the first): (first bar, the first bar of
    the earlier phrase it repeats or None, how well it matches). A phrase repeats the earliest first hearing it
    matches best; phrases that repeat a repeat point to the first hearing."""
    n = len(sim)
    starts = [0, *range(anchor + PHRASE_BARS, n - PHRASE_BARS // 2, PHRASE_BARS)]  # a pickup joins phrase one
    out: list[tuple[int, int | None, float]] = []
    for q, start in enumerate(starts):
        length = (starts[q + 1] if q + 1 < len(starts) else n) - start
        best, best_match = None, RETURN_SIMILARITY
        for p, (p_start, p_source, _m) in enumerate(out):
            p_len = starts[p + 1] - p_start
            if p_source is not None or p_len < PHRASE_BARS:
                continue
            m = aligned_match(sim, p_start, start, min(p_len, length))
            if m > best_match:
                best, best_match = p_start, m
        out.append((start, best, best_match if best is not None else 1.0))
    return out


def song_form(analysis: MusicAnalysis) -> SongForm:
    """The song's sections and which of them return (see the module's docstring)."""
    edges = bar_grid(analysis)
    n_bars = len(edges) - 1
    if n_bars < 2 * MIN_SECTION_BARS:
        return SongForm(edges, (Phrase(0, None, 1.0),), (Section("A", 1, 0.0, float(edges[-1]), 0, n_bars, 1.0),))
    sim = self_similarity(bar_features(analysis, edges))
    # The phrase grid where repeats line up best: the most matching over the phrases.
    phrases = max((phrase_sources(sim, a) for a in range(PHRASE_BARS)),
                  key=lambda ps: sum(m for _s, src, m in ps if src is not None))
    return SongForm(edges, tuple(Phrase(*p) for p in phrases), _sections(phrases, edges))


def section_label(k: int) -> str:
    """The label of the k-th music heard (from 0): A ... Z, then AA, AB, ... as spreadsheet columns go on, so
    no two musics share one however many a song has."""
    label = ""
    k += 1
    while k:
        k, r = divmod(k - 1, 26)
        label = string.ascii_uppercase[r] + label
    return label


def _sections(phrases: list[tuple[int, int | None, float]], edges: np.ndarray) -> tuple[Section, ...]:
    """Sections from the phrases: runs of music heard for the first time and runs that repeat consecutive
    earlier music, cut wherever a repeat's source begins or ends (so that a return of A B shows as A then B),
    each repeat labelled as the section it repeats; music played twice at once stays one section."""
    n_bars = len(edges) - 1
    pieces: list[list] = []  # [first bar, end bar, source bar or None, match]
    for start, source, m in phrases:
        prev = pieces[-1] if pieces else None
        if prev is not None and (source is None) == (prev[2] is None) and (
                source is None or source - prev[2] == start - prev[0]):
            prev[3] = min(prev[3], m)
        else:
            pieces.append([start, None, source, m])
    for k, piece in enumerate(pieces):
        piece[1] = pieces[k + 1][0] if k + 1 < len(pieces) else n_bars
    for _ in range(4):  # cuts carry from a source to its repeats and back; a few passes settle them
        cuts = {p[2] + d for p in pieces if p[2] is not None for d in (0, p[1] - p[0])}
        cuts |= {p[0] for p in pieces}
        split: list[list] = []
        for first, end, source, m in pieces:
            inner = sorted({c if source is None else first + c - source for c in cuts} & set(range(first + 1, end)))
            for a, b in zip([first, *inner], [*inner, end], strict=True):
                split.append([a, b, None if source is None else source + a - first, m])
        if len(split) == len(pieces):
            break
        pieces = split
    sections: list[Section] = []
    for first, end, source, m in pieces:
        if source is None:
            label, match = section_label(len({s.label for s in sections})), 1.0
        else:
            label, match = next(s.label for s in reversed(sections) if s.first_bar <= source), m
        if sections and (sections[-1].label == label or end - first < MIN_SECTION_BARS // 2):
            last = sections.pop()  # the same music again at once (or a stray bar): one section
            first, label, match = last.first_bar, last.label, min(last.match, match)
        occurrence = 1 + sum(s.label == label for s in sections)
        sections.append(Section(label, occurrence, float(edges[first]), float(edges[end]), first, end - first,
                                match))
    return tuple(sections)

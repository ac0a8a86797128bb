"""A song's dance from a motion library: a figure for every bar, time-warped onto the song's beats.

1. The song's beat grid (`song_grid`): its tracked beats, extended at the same tempo to cover the part danced,
   cut into bars at its downbeats (none longer than the meter).
2. The plan (`plan`): dynamic programming over the bars. A state is a figure: a start in the library (a downbeat
   of a clip in the song's meter, or every `meter` beats of a clip in another) and how many clip beats it lays on
   each song beat (1, 2, 1/2, 3/2 or 2/3: `figures.RATIOS`), so that a clip danced at half or twice the song's tempo, or
   whose tempo was read an octave off, still plays at its dancers' speed; a bar of n beats takes the library's
   ratio x n beats from it. Each bar's cost: its energy against the music's (ranks of the mean joint speed and of
   the mean onset strength), the time-warp in real time (how much faster or slower than captured the figure plays,
   at one speed from the bar's first beat to the next bar's: beyond +-15% only when nothing fits, at a steep cost)
   and seeded noise
   (different seeds, different dances); each join's: the distance between the pose, velocity and foot contact
   where one figure ends and the next starts (0 where the next figure is the clip's own continuation), and, at a
   cut, a steep cost where some joint of the new figure, as fast as the warp plays it, steps further in the
   frames the cut blends than `CALM_LIMIT` of that joint's 99th percentile in the library (cuts are made where
   the dancers are calm, so that no joint jumps at a transition; see `CALM_SHARE`), and a cost where the bars
   either side of a cut both move some joint far more than the library's dancers usually do (`stretch_kinetics`),
   so that the loudest bars do not get the library's extremes laid back to back. A clip is only tried at the
   ratios that can play it near its speed (`figures.RATIO_MARGIN`), so there are about as many figures as starts. The
   whole table is [bars, figures] and each step a vectorised min over [figure ends, figure starts]: a 3-minute
   song on a 30-minute library (about 1,000 figures) is about 90 steps of 10^6 numbers.
3. The dance (`transitions.render`): every figure's frames sampled at the warped times, the root path carried
   across cuts, each cut inertialised.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..constants import WARP_RANGE
from ..errors import DanceNetError
from ..motion import Motion
from ..music.features import FPS as MUSIC_FPS
from ..music.features import ONSET_COL, MusicAnalysis
from ..music.form import SongForm, song_form
from .analysis import POSE_DIM, frame_features
from .energy import clips_energy, dance_energy
from .figures import (
    DEFAULT_BPM,
    START_DECIMALS,
    Grid,
    beat_index,
    entry_steps,
    figure_peaks,
    figure_states,
    nearest_beat,
    stretch_kinetics,
    within_clip,
)
from .match import FigureMatch, MatchModel
from .store import MotionLibrary
from .transitions import CUT_BLEND_S, Figure, Rendered, beat_frames, cut_steps, render

# A cut's new figure: its joints' steps over the frames the cut blends (and the one before) at most this share of
# each joint's 99th percentile in the library, as the warp plays them; the rest is left to the fading offset. In a
# library whose dancers are never that calm, the calmest quarter of its figures' openings sets the limit instead,
# so that the plan still cuts (and seeds still differ).
CALM_LIMIT = 0.9
CALM_SHARE = 0.25
# A figure whose fastest joint, as the warp plays it, steps further than this many times that joint's 99.9th
# percentile in the library (a leap beyond anything else the dancers do, or a capture's glitch) is danced only where
# no figure keeps within it: the blends and the foot hold add a little, and a dance should move no joint faster than
# 1.5 times the clips' 99.9th percentile.
PEAK_LIMIT = 1.35
LONG_RUN_BARS = 4  # the copied-run report: frames from runs of one clip longer than this many bars
FALLBACK_METER = 4
PHRASE_TOLERANCE_S = 0.1  # a grid bar and a bar of the song's form that start this close are one bar
# `plan_at_clips_energy`: the dance's mean joint speed within this share of the clips', in at most this many plans,
# the music's energy ranks shifted by this much first (then by the secant), never by more than the last
ENERGY_TOLERANCE = 0.03
ENERGY_ROUNDS = 4
ENERGY_STEP = 0.15
MAX_ENERGY_SHIFT = 0.6


@dataclass(frozen=True)
class Settings:
    """Weights of the plan's costs (a jump between unrelated poses costs about 1)."""

    energy: float = 2.0
    tempo: float = 1.0
    out_of_range: float = 500.0
    noise: float = 0.25
    pose: float = 1.0
    velocity: float = 0.15
    contact: float = 0.3
    cut: float = 0.2  # every cut costs this much more than carrying on with the clip
    calm: float = 50.0  # per unit of a cut's step over the limit (steep: only where no calmer cut fits)
    # With a learned match (a library whose clips name no style): per unit of its cosine below 1 on each bar (off,
    # docs/matching.md), and per unit of the part's probability of a figure's clip's style below its most probable
    # style's.
    match: float = 0.0
    match_style: float = 20.0
    # The song's form (`music.form`): a cut on a bar that begins no phrase costs this much more, and a bar's music
    # energy is this share its section's mean onset strength (the rest its own), so that a section's figures
    # follow the section's loudness.
    off_phrase: float = 0.0
    section_energy: float = 0.0
    # A cut between two stretches that both move some joint far more than the library's dancers usually do (the
    # same joint, the same way: up and down or over the floor) costs this much per unit of the product of how far
    # past one standard deviation each lies (`stretch_kinetics`), so that the plan does not lay the library's
    # extremes back to back where no dancer did.
    pile: float = 0.05
    # The music's energy ranks are shifted by this much (clipped to [0, 1]) before figures are matched to them:
    # with `energy_match`, `plan_at_clips_energy` sets it so that each dance moves as fast as the clips do on
    # average. Off: it also takes each song's own energy away (a quiet rumba danced
    # at the library's mean), and on the Dance with Melody folds it doubled FID_g (docs/experiments.md).
    energy_shift: float = 0.0
    energy_match: bool = False
    # Figures that start between two clip beats (`figures.figure_states`): a clip danced at a ratio that lays a
    # fraction of a beat on a bar carries on across bars instead of being cut every bar.
    between_beats: bool = True


DEFAULT_SETTINGS = Settings()


@dataclass
class Report:
    """What a dance is made of: its figures, its cuts and how much of it is copied in long runs of one clip."""

    figures: list[dict] = field(default_factory=list)
    cuts: list[int] = field(default_factory=list)  # frames where a new clip (or a jump within one) starts
    blends: list[int] = field(default_factory=list)  # frames over which each cut's difference fades
    # each cut's largest joint step past its 99th percentile and past its source clip's own step (1: none past)
    cut_steps: list[float] = field(default_factory=list)
    long_run_share: float = 0.0  # share of frames from runs of one clip longer than LONG_RUN_BARS bars
    longest_run_bars: int = 0
    longest_run_s: float = 0.0
    max_warp: float = 0.0  # largest real-time warp of a beat, as a fraction (0.1: 10% slower or faster than captured)

    def summary(self) -> dict:
        return clip_usage(self.figures) | {
                "figures": len(self.figures), "cuts": len(self.cuts), "long_run_bars": LONG_RUN_BARS,
                "long_run_share": round(self.long_run_share, 4), "longest_run_bars": self.longest_run_bars,
                "longest_run_s": round(self.longest_run_s, 2), "max_warp": round(self.max_warp, 4),
                "max_cut_step": round(max(self.cut_steps, default=0.0), 3)}


def clip_usage(figures: list[dict]) -> dict:
    """How many distinct clips a dance's figures (`Report.figures` rows) use and how evenly: `effective_clips` is
    the exponential of the entropy of the seconds danced per clip (N for N clips danced equally long, near 1 for a
    dance that stays with one clip)."""
    seconds: dict[str, float] = {}
    for f in figures:
        seconds[f["clip"]] = seconds.get(f["clip"], 0.0) + f["song_s"][1] - f["song_s"][0]
    share = np.array(list(seconds.values()))
    share = share[share > 0] / max(share.sum(), 1e-9)
    return {"clips": len(seconds), "effective_clips": round(float(np.exp(-(share * np.log(share)).sum())), 2)}


@dataclass
class LibraryDance:
    motion: Motion
    report: Report


def song_grid(analysis: MusicAnalysis, start_s: float, end_s: float) -> Grid:
    """Beats covering [start_s, end_s] (the tracked ones, extended at the median beat interval before and after)
    and the bars between downbeats (a longer stretch is cut every `meter` beats)."""
    beats, downs = np.asarray(analysis.beat_times, np.float64), np.asarray(analysis.downbeat_times, np.float64)
    if len(beats) < 2:
        beats, downs = np.array([start_s, start_s + 60 / DEFAULT_BPM]), np.array([start_s])
    flags = np.isin(beats, downs)
    known = np.flatnonzero(flags)
    meter = int(np.clip(np.median(np.diff(known)), 2, 6)) if len(known) > 1 else FALLBACK_METER
    ibi = float(np.median(np.diff(beats)))
    before = int(max(0, np.ceil((beats[0] - start_s) / ibi)))
    after = int(max(0, np.ceil((end_s - beats[-1]) / ibi)))
    beats = np.concatenate([beats[0] - ibi * np.arange(before, 0, -1), beats,
                            beats[-1] + ibi * np.arange(1, after + 1)])
    index = np.arange(len(beats))
    first = known[0] + before if len(known) else before
    last = known[-1] + before if len(known) else before
    flags = np.concatenate([np.zeros(before, bool), flags, np.zeros(after, bool)])
    flags |= ((index < first) & ((first - index) % meter == 0)) | ((index > last) & ((index - last) % meter == 0))
    if not flags.any():
        flags[::meter] = True
    # Keep the beats from the last at or before start_s to the first at or after end_s.
    lo, hi = int(np.searchsorted(beats, start_s, "right")) - 1, int(np.searchsorted(beats, end_s, "left"))
    beats, flags = beats[lo : hi + 1], flags[lo : hi + 1]
    edges = sorted({0, len(beats) - 1, *np.flatnonzero(flags).tolist()})
    bars = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        while b - a > meter:
            bars.append((a, meter))
            a += meter
        bars.append((a, b - a))
    return Grid(beats, bars, meter)


def _ranks(x: np.ndarray, among: np.ndarray | None = None) -> np.ndarray:
    """Each value's rank as a fraction in [0, 1] among `among` (default: `x` itself; ties share their mean rank:
    all equal, all 0.5)."""
    among = x if among is None else among
    if len(among) < 2:
        return np.full(len(x), 0.5)
    s = np.sort(among)
    return np.clip((np.searchsorted(s, x, "left") + np.searchsorted(s, x, "right") - 1) / (2.0 * (len(s) - 1)),
                   0.0, 1.0)


def _weights(settings: Settings, dim: int) -> np.ndarray:
    w = np.empty(dim, np.float32)
    w[:POSE_DIM], w[POSE_DIM : 2 * POSE_DIM], w[2 * POSE_DIM :] = settings.pose, settings.velocity, settings.contact
    return w


def _speed_limit_excess(log_speed: np.ndarray) -> np.ndarray:
    """How far (log) a real-time speed lies outside [1 - WARP_RANGE, 1 + WARP_RANGE]."""
    return np.maximum(np.maximum(log_speed - np.log1p(WARP_RANGE), np.log1p(-WARP_RANGE) - log_speed), 0.0)


class _Bars:
    """What the plan's path through the bars weighs: every figure that may be danced (`figure_states`), its
    energy and entry steps, the library's boundary features (weighted), and each bar's music, with the costs of
    a figure on a bar (`unary`) and of a cut between figures (`joins`)."""

    def __init__(self, library: MotionLibrary, grid: Grid, onset: np.ndarray, rng: np.random.Generator,
                 style: str | None, settings: Settings, match: FigureMatch | None,
                 form: SongForm | None = None, kinetics: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        self.library, self.grid, self.rng, self.settings, self.match = library, grid, rng, settings, match
        starts, ratios = self.starts, self.ratios = figure_states(library, grid, style, settings.between_beats)
        self.nb = nb = len(library.beats)
        self.too_short = DanceNetError(f"the motion library has no clip with {grid.meter + 1} beats or more to cut "
                                       "a figure from; add longer clips (a few bars each)")
        if len(starts) == 0:
            raise self.too_short
        self.clip = library.beat_clip[beat_index(starts)]
        csum = np.concatenate([[0.0], np.cumsum(library.energy, dtype=np.float64)])
        span = np.maximum(np.round(ratios * grid.meter), 1.0)  # the whole beats from its start
        beat = np.arange(nb + 1)
        energy = (np.interp(np.minimum(starts + span, nb), beat, csum) - np.interp(starts, beat, csum)) / span
        self.fig_energy_raw = energy  # mean joint speed per clip beat (m/s)
        # ranked among the figures that start on a clip's beat (those between two beats carry on from them)
        self.fig_energy = _ranks(energy, energy[starts == np.round(starts)])
        self.weights = _weights(settings, library.features.shape[1])
        self.feats = library.features * np.sqrt(self.weights)
        self.sq = (self.feats**2).sum(1)
        self.ustarts, self.start_of = np.unique(starts, return_inverse=True)
        self.ufeat = nearest_beat(self.ustarts)  # the beat whose features stand for each distinct start
        bar_times = [(grid.beats[a], grid.beats[a + n]) for a, n in grid.bars]
        frames = [(min(max(0, int(t0 * MUSIC_FPS)), len(onset) - 1), int(t1 * MUSIC_FPS)) for t0, t1 in bar_times]
        loud = np.array([onset[a : max(a + 1, b)].mean() for a, b in frames])
        bar_starts = np.array([t0 for t0, _t1 in bar_times])
        phrase, section = _form_bars(form, bar_starts)
        if settings.section_energy:
            means = np.array([loud[section == k].mean() for k in section])
            loud = (1 - settings.section_energy) * loud + settings.section_energy * means
        self.music_rank = np.clip(_ranks(loud) + settings.energy_shift, 0.0, 1.0)
        self.off_phrase = np.where(phrase, 0.0, settings.off_phrase)
        if kinetics is None and settings.pile:
            kinetics = stretch_kinetics(library, grid.meter)
        self.kinetics = kinetics if settings.pile else None
        self.entry = entry_steps(library, starts)
        self.peak = figure_peaks(library, starts, ratios * grid.meter)
        self.limit = max(CALM_LIMIT, float(np.quantile(self.entry, CALM_SHARE)))
        self.cache: dict[int, tuple] = {}
        self.scale: float | None = None

    def joins(self, n_prev: int) -> tuple:
        """For figures n_prev song beats long: where each ends (an index into the distinct ends), the cost [U, E]
        of a cut to each distinct start from each distinct end (float32, a row per start: the min over ends runs
        along memory), and per figure the end it carries on from (its clip's own continuation, -1: none)."""
        if n_prev not in self.cache:
            starts, feats, sq, ustarts = self.starts, self.feats, self.sq, self.ufeat
            ends = np.round(starts + self.ratios * n_prev, START_DECIMALS)
            uend, end_of = np.unique(ends, return_inverse=True)
            at = np.minimum(nearest_beat(uend), self.nb - 1)
            d = np.maximum(sq[at][:, None] + sq[ustarts][None, :] - 2.0 * feats[at] @ feats[ustarts].T, 0.0)
            if self.scale is None:
                self.scale = float(np.median(d)) or 1.0
            k = np.minimum(np.searchsorted(uend, starts), len(uend) - 1)
            d = d / self.scale + self.settings.cut
            if self.kinetics is not None:
                after, before = self.kinetics
                d = d + self.settings.pile * (before[at] @ after[ustarts].T)
            cut = np.ascontiguousarray(d.T, dtype=np.float32)
            self.cache[n_prev] = (end_of, cut, np.where(uend[k] == starts, k, -1))
        return self.cache[n_prev]

    def unary(self, b: int) -> tuple[np.ndarray, np.ndarray]:
        """[F] each figure's cost on bar b, and how much faster than captured it plays (one speed over the bar)."""
        library, starts, ratios, settings, match = self.library, self.starts, self.ratios, self.settings, self.match
        a, n = self.grid.bars[b]
        song_s = self.grid.beats[a + n] - self.grid.beats[a]
        end = starts + ratios * n
        fits = within_clip(library, self.clip, end)
        clip_s = (beat_frames(library, end) - beat_frames(library, starts)) / library.fps
        with np.errstate(divide="ignore", invalid="ignore"):
            log_speed = np.log(clip_s / song_s)
        fits &= np.isfinite(log_speed)
        excess = _speed_limit_excess(log_speed)
        cost = (settings.energy * (self.music_rank[b] - self.fig_energy) ** 2 + settings.tempo * log_speed**2
                + settings.out_of_range * excess + self.rng.normal(0.0, settings.noise, len(starts)))
        if (fits & (excess == 0.0)).any():  # the speed limit holds wherever some figure keeps it
            fits &= excess == 0.0
        fast = self.peak * np.exp(np.nan_to_num(log_speed, nan=0.0)) > PEAK_LIMIT
        if (fits & ~fast).any():  # and no joint moves faster than the library's dancers do, where a figure keeps it
            fits &= ~fast
        if match is not None:
            cost = cost + settings.match_style * match.style_away(starts, ratios, n)
            if settings.match:
                cost = cost + settings.match * (1.0 - match.fit(b, starts, ratios, n))
        return np.where(fits, cost, np.inf), np.exp(np.nan_to_num(log_speed, nan=0.0, posinf=0.0, neginf=0.0))

    def calm(self, speed: np.ndarray) -> np.ndarray:
        """[F]: the cost of entering each figure by a cut, for its steps at the cut as fast as it plays them."""
        return self.settings.calm * np.maximum(self.entry * speed - self.limit, 0.0)

    def first(self, previous: np.ndarray | None) -> np.ndarray:
        """[F] each figure's cost on the first bar, joined to `previous` (a continued dance's last pose) as a
        figure's end is."""
        cost, speed = self.unary(0)
        if previous is not None:
            self.joins(self.grid.bars[0][1])  # sets the scale of a join's cost
            p = previous.astype(np.float32) * np.sqrt(self.weights)
            at = nearest_beat(self.starts)
            join = np.maximum(p @ p + self.sq[at] - 2.0 * self.feats[at] @ p, 0.0)
            cost = cost + join / self.scale + self.settings.cut + self.calm(speed)
        return cost


def _form_bars(form: SongForm | None, bar_starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per bar of the grid (by its start time): whether a phrase of the song's form begins on it, and the index
    of the section it lies in (all bars phrase starts of one section without a form)."""
    if form is None:
        return np.ones(len(bar_starts), bool), np.zeros(len(bar_starts), np.int64)
    phrase_s = form.bar_starts[[p.first_bar for p in form.phrases]]
    near = np.abs(bar_starts[:, None] - phrase_s[None, :]).min(axis=1) < PHRASE_TOLERANCE_S
    section_s = np.array([s.start_s for s in form.sections])
    return near, np.maximum(np.searchsorted(section_s, bar_starts + PHRASE_TOLERANCE_S, side="right") - 1, 0)


def plan(library: MotionLibrary, grid: Grid, onset: np.ndarray, rng: np.random.Generator,
         style: str | None = None, settings: Settings = DEFAULT_SETTINGS,
         previous: np.ndarray | None = None, match: FigureMatch | None = None,
         form: SongForm | None = None, kinetics: tuple[np.ndarray, np.ndarray] | None = None
         ) -> list[tuple[int, float]]:
    """The figure (its start, a beat of the library, maybe between two, and its clip beats per song beat) for every
    bar of `grid`:
    the cheapest path through the bars (see the module's docstring); `onset` [T] is the song's onset strength at
    MUSIC_FPS. `previous` [FEATURE_DIM]: the boundary features of the pose the first figure follows (a continued
    dance's last frame), joined to as a figure's end is. `kinetics`: `stretch_kinetics(library, grid.meter)`,
    computed here when not given (the same for every take of a song)."""
    bars = _Bars(library, grid, onset, rng, style, settings, match, form, kinetics)
    cost = bars.first(previous)
    if not np.isfinite(cost).any():
        raise bars.too_short
    back = np.zeros((len(grid.bars), len(bars.starts)), np.int64)
    for b in range(1, len(grid.bars)):
        end_of, cut_cost, carries = bars.joins(grid.bars[b - 1][1])
        # the cheapest figure ending at each distinct end
        order = np.lexsort((cost, end_of))
        best = order[np.searchsorted(end_of[order], np.arange(cut_cost.shape[1]))]
        ending = cost[best]
        total = cut_cost + ending.astype(np.float32)[None, :]
        came = np.argmin(total, axis=1)
        u, speed = bars.unary(b)
        by_cut = total[np.arange(len(bars.ustarts)), came][bars.start_of] + bars.calm(speed) + bars.off_phrase[b]
        by_carry = np.where(carries >= 0, ending[np.maximum(carries, 0)], np.inf)
        carry = by_carry <= by_cut
        back[b] = np.where(carry, best[np.maximum(carries, 0)], best[came[bars.start_of]])
        cost = u + np.where(carry, by_carry, by_cut)
        if not np.isfinite(cost).any():
            raise bars.too_short
    path = [int(np.argmin(cost))]
    for b in range(len(grid.bars) - 1, 0, -1):
        path.append(int(back[b, path[-1]]))
    return [(float(bars.starts[k]), float(bars.ratios[k])) for k in path[::-1]]


def plan_at_clips_energy(library: MotionLibrary, grid: Grid, onset: np.ndarray, rng: np.random.Generator,
                         style: str | None, settings: Settings, previous: np.ndarray | None,
                         match: FigureMatch | None, form: SongForm | None,
                         kinetics: tuple[np.ndarray, np.ndarray] | None) -> list[tuple[float, float]]:
    """`plan`, its music's energy ranks shifted (`Settings.energy_shift`, the same noise each time) until the dance
    moves within `ENERGY_TOLERANCE` of the clips' mean speed (`ENERGY_ROUNDS` plans at most, the nearest kept).

    Why: the plan's joins favour calm figures (a cut between calm poses is cheaper, a cut into a calm figure is
    calm), so a library that mixes calm clips with lively ones was danced at 0.8-0.9 of its clips' speed; matching
    ranks alone cannot tell how far the choice of figures drifted. A library of one kind of dancing needs no shift."""
    if not settings.energy_match:
        return plan(library, grid, onset, rng, style, settings, previous, match, form, kinetics)
    state = rng.bit_generator.state
    target = clips_energy(library)
    tried: list[tuple[float, float, list]] = []  # (how far off, log; the shift; the plan)
    shift = settings.energy_shift
    for _ in range(ENERGY_ROUNDS):
        rng.bit_generator.state = state
        bars = plan(library, grid, onset, rng, style, replace(settings, energy_shift=shift), previous, match, form,
                    kinetics)
        danced = dance_energy(library, grid.beats, grid.bars, bars)
        tried.append((float(np.log(max(danced, 1e-9) / max(target, 1e-9))), shift, bars))
        off = tried[-1][0]
        if abs(off) <= np.log1p(ENERGY_TOLERANCE):
            break
        slope = 0.0
        if len(tried) > 1 and tried[-1][1] != tried[-2][1]:  # the secant through the last two plans
            slope = (off - tried[-2][0]) / (tried[-1][1] - tried[-2][1])
        shift = float(np.clip(shift - off / slope if slope > 0 else shift - np.sign(off) * ENERGY_STEP,
                              -MAX_ENERGY_SHIFT, MAX_ENERGY_SHIFT))
    return min(tried, key=lambda t: abs(t[0]))[2]


def choreograph(library: MotionLibrary, analysis: MusicAnalysis, seed: int = 0, start_s: float = 0.0,
                end_s: float | None = None, takes: int = 1, style: str | None = None,
                settings: Settings = DEFAULT_SETTINGS, kept: Motion | None = None,
                match: MatchModel | None = None) -> list[LibraryDance]:
    """`takes` dances to the song's part from `start_s` to `end_s` (default: its end), cut from `library`; the same
    seed gives the same dances. With `kept` (a dance at the library's frame rate and skeleton, two frames or more,
    that ends at `start_s`) each dance goes on from its last pose: chosen and blended as after a cut."""
    end = analysis.duration_s if end_s is None else min(end_s, analysis.duration_s)
    grid = song_grid(analysis, start_s, end)
    rng = np.random.default_rng(seed)
    onset = analysis.features[:, ONSET_COL]
    bar_beats = [grid.beats[a : a + n + 1] for a, n in grid.bars]
    fit = None if match is None else FigureMatch(match, library, analysis.features, bar_beats)
    previous = None if kept is None else frame_features(kept[-8:])[0][-1]  # its last frame, its speed and feet
    form = song_form(analysis) if settings.off_phrase or settings.section_energy else None
    kinetics = stretch_kinetics(library, grid.meter) if settings.pile else None
    dances = []
    for _ in range(takes):
        bars = plan_at_clips_energy(library, grid, onset, rng, style, settings, previous, fit, form, kinetics)
        figures = _carried_to_the_end(library, [Figure(s, n, grid.beats[a : a + n + 1], r)
                                                for (s, r), (a, n) in zip(bars, grid.bars, strict=True)], end)
        rendered = render(library, figures, start_s, end, kept)
        dances.append(LibraryDance(rendered.motion, report(library, figures, rendered, grid, start_s, end)))
    return dances


def _carried_to_the_end(library: MotionLibrary, figures: list[Figure], end_s: float) -> list[Figure]:
    """The figures, the last two one figure where the last would be a cut within `CUT_BLEND_S` of the part's end (too
    late for its blend: the dance would jump in its last frames): the figure before carried on at one speed over
    both bars, where its clip goes on that far and the speed keeps within its limit."""
    if len(figures) < 2 or figures[-2].carries_on(figures[-1]) or end_s - figures[-1].times[0] >= CUT_BLEND_S:
        return figures
    prev, last = figures[-2:]
    merged = Figure(prev.start, prev.beats + last.beats, np.concatenate([prev.times, last.times[1:]]), prev.ratio)
    if not within_clip(library, library.beat_clip[beat_index(prev.start)], np.array(merged.end)):
        return figures
    clip_s = float(np.diff(beat_frames(library, np.array([merged.start, merged.end])))[0]) / library.fps
    if _speed_limit_excess(np.log(clip_s / (merged.times[-1] - merged.times[0]))) > 0:
        return figures
    return [*figures[:-2], merged]


def report(library: MotionLibrary, figures: list[Figure], rendered: Rendered, grid: Grid, start_s: float,
           end_s: float) -> Report:
    """The figures (clip, where in it, where in the song, clip beats per song beat), the runs of one clip, the
    largest time-warp (real time: how much faster or slower than captured a frame plays) and each cut's largest
    step (`transitions.cut_steps`)."""
    rows, runs, warp = [], [], 0.0
    for k, f in enumerate(figures):
        clip = int(library.beat_clip[beat_index(f.start)])
        lib = f.frames(library)
        t0 = library.clip_starts[clip]
        song = np.clip(f.times, start_s, end_s)
        warp = max(warp, float(np.abs(np.diff(lib) / library.fps / np.diff(f.times) - 1.0).max()))
        rows.append({"clip": library.names[clip], "clip_s": [round(float((lib[0] - t0) / library.fps), 3),
                                                              round(float((lib[-1] - t0) / library.fps), 3)],
                     "song_s": [round(float(song[0]), 3), round(float(song[-1]), 3)], "ratio": round(f.ratio, 3)})
        continues = k > 0 and figures[k - 1].carries_on(f)
        if continues:
            runs[-1] = (runs[-1][0] + 1, runs[-1][1] + song[-1] - song[0])
        else:
            runs.append((1, song[-1] - song[0]))
    total = max(end_s - start_s, 1e-9)
    longest = max(runs, key=lambda r: r[1])
    return Report(rows, rendered.cuts, rendered.blends, cut_steps(rendered),
                  float(sum(s for b, s in runs if b > LONG_RUN_BARS) / total), int(longest[0]), float(longest[1]),
                  warp)

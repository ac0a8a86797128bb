"""Music features of the paper (section 4.1): onset, beat, downbeat and deep chroma at 10 fps, plus beats,
downbeats, tempo and a log-mel spectrum for the ablation; cached on disk by audio content.

Column layout follows the authors' code (`get_music_onset_chroma_feature`): chroma 0-11, beat 12,
downbeat 13, onset 14. As there, the 100-fps onset and beat/downbeat activations are linearly stretched onto
the deep-chroma frame count (`linspace(0, n100 - 1, n_chroma)`). Frame j is centred at j / 10 s and
T = floor(10 * duration + 0.5): madmom's ceil(N / 4410) chroma frames, less a last frame whose centre lies in
the song's final 50 ms.

madmom's networks hold whole spectrograms and the DBN scores ~15k states per frame, so every song
is processed in blocks (60 s, plus 5 s of real audio as context each side) and the DBN in 40-s windows
(plus 10 s each side): peak memory stays under ~0.5 GB per worker process whatever the song's length.
Chroma and mel are identical to a one-shot run; the bidirectional beat network remembers far back, so its
activations differ from a one-shot run by 0.003 on average (0.09 at most) on a 3.5-min waltz, whose
beats and downbeats came out identical. The mel spectrum is log(1 + 80-band mel magnitude), 4096-sample
frames at 10 fps on the chroma frame grid.
"""

from __future__ import annotations

import ctypes
import hashlib
import json
import multiprocessing as mp
import os
import sys
from collections.abc import Callable
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import jit
from ..atomic import atomic_open
from ..environment import cache_root, default_workers, end_with_parent, one_blas_thread, stop_pool
from ..errors import DanceNetError, first_line
from ..progress import Progress
from ..series import interp_frames, stretch_frames
from . import madmom_dbn, madmom_nets
from .audio import MADMOM_SAMPLE_RATE, Audio, load_audio
from .madmom_nets import OnsetAndBeat

FEATURE_VERSION = "music-features-1"  # change whenever any computation below changes
FPS = 10
FEATURE_NAMES = tuple(
    [f"chroma_{p}" for p in ("C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B")]
    + ["beat", "downbeat", "onset"]
)
N_FEATURES = len(FEATURE_NAMES)
CHROMA_COLS = slice(0, 12)
BEAT_COL, DOWNBEAT_COL, ONSET_COL = (FEATURE_NAMES.index(c) for c in ("beat", "downbeat", "onset"))
MEL_BANDS = 80
BEATS_PER_BAR = (3, 4)

ACT_FPS = 100  # madmom's onset and downbeat networks
_HOP_ACT = MADMOM_SAMPLE_RATE // ACT_FPS
_HOP_10 = MADMOM_SAMPLE_RATE // FPS
BLOCK_S = 60  # seconds of audio kept from one network pass
CONTEXT_S = 5  # seconds of audio either side of a block, seen by the bidirectional networks, then dropped
DBN_BLOCK_S = 40  # madmom's Viterbi pass stored 4 bytes per frame and state (~15k states): ~360 MB here;
# the compiled decode (madmom_dbn) keeps 1/60 of that, but the windows stay: they shape the beats
DBN_CONTEXT_S = 10


@dataclass(frozen=True)
class FeatureSpec:
    """The music features a network hears, written into its weights when they are saved, so that generation can
    tell weights trained on other features (another extractor, version or column order) from its own."""

    version: str
    fps: int
    columns: tuple[str, ...]

    @property
    def dim(self) -> int:
        return len(self.columns)

    def to_dict(self) -> dict:
        return {"version": self.version, "fps": self.fps, "dim": self.dim, "columns": list(self.columns)}

    @classmethod
    def from_dict(cls, d: dict | None) -> FeatureSpec:
        """The spec weights record; weights saved before specs were recorded (None) were trained on FEATURE_SPEC."""
        if d is None:
            return FEATURE_SPEC
        try:
            return cls(str(d["version"]), int(d["fps"]), tuple(str(c) for c in d["columns"]))
        except (KeyError, TypeError, ValueError) as e:
            raise DanceNetError(f"the weights' music feature spec is unreadable ({first_line(e)}); "
                                "re-export them with `dancenet weights export`") from e

    def describe(self, columns: bool = False) -> str:
        text = f"{self.version} ({self.dim} columns at {self.fps} fps"
        return text + (f": {', '.join(self.columns)})" if columns else ")")

    def check_trained(self, trained: FeatureSpec, what: str) -> None:
        """A one-line DanceNetError unless the weights `what` were trained on the features this spec computes."""
        if trained != self:
            cols = (trained.version, trained.dim, trained.fps) == (self.version, self.dim, self.fps)
            raise DanceNetError(f"these {what} were trained on music features {trained.describe(cols)}; this version "
                                f"computes {self.describe(cols)}: use weights trained on this version's features, "
                                "or the version of DanceNet they were trained with")


FEATURE_SPEC = FeatureSpec(FEATURE_VERSION, FPS, FEATURE_NAMES)
MEL_SPEC = FeatureSpec(FEATURE_VERSION, FPS, tuple(f"mel_{i}" for i in range(MEL_BANDS)))  # the ablation's input
MUSIC_SPECS = {"onset_beat_chroma": FEATURE_SPEC, "mel": MEL_SPEC}  # by a network config's `music_features`


@dataclass
class MusicAnalysis:
    """Everything the dance model and the UI need to know about a song."""

    features: np.ndarray  # [T, N_FEATURES] float32 at `fps`, columns as FEATURE_NAMES
    beat_times: np.ndarray  # seconds
    downbeat_times: np.ndarray  # seconds
    tempo_bpm: float  # 60 / median beat interval; 0 when fewer than two beats were found
    duration_s: float
    fps: int = FPS
    mel: np.ndarray | None = None  # [T, MEL_BANDS] log-mel at `fps`, when asked for

    @property
    def num_frames(self) -> int:
        return int(self.features.shape[0])

    def check(self) -> None:
        """ValueError unless every field fits the others, as `analyze_audio` makes them: what the cache may hold
        (an entry that passed a shape check but not this failed every run, or asked for all the memory)."""
        f, mel, beats, downbeats = self.features, self.mel, self.beat_times, self.downbeat_times
        arrays = (f, beats, downbeats, *(() if mel is None else (mel,)))
        if not all(isinstance(a, np.ndarray) and a.dtype.kind == "f" for a in arrays):
            raise ValueError("the analysis holds arrays that are not of real numbers")
        if f.ndim != 2 or f.shape[1] != N_FEATURES or (mel is not None and mel.shape != (len(f), MEL_BANDS)):
            raise ValueError(f"features of shape {f.shape}, expected [T, {N_FEATURES}] (mel [T, {MEL_BANDS}])")
        if not all(np.isfinite(a).all() for a in arrays) or not np.isfinite([self.tempo_bpm, self.duration_s]).all():
            raise ValueError("the analysis holds values that are not finite")
        if self.fps != FPS or not (self.duration_s > 0 and abs(len(f) - self.duration_s * FPS) <= 1):
            raise ValueError(f"{len(f)} frames do not make {self.duration_s:g} s at {self.fps} fps")
        end = self.duration_s + 1 / FPS  # give or take a frame: the beat tracker's last frame may end after the audio
        for what, times in (("beat", beats), ("downbeat", downbeats)):
            if times.ndim != 1 or (np.diff(times) < 0).any() or (len(times) and not 0 <= times[0] <= times[-1] <= end):
                raise ValueError(f"{what} times are not sorted times within the song")
        if not np.isin(downbeats, beats).all():
            raise ValueError("downbeats that are not beats")
        ibi = np.diff(beats)
        if not np.isclose(self.tempo_bpm, 60.0 / np.median(ibi) if len(ibi) else 0.0, rtol=1e-9, atol=0.0):
            raise ValueError(f"a tempo of {self.tempo_bpm:g} BPM that is not the beats'")

    def save(self, path: str | Path, version: str = FEATURE_VERSION) -> None:
        """Write an .npz (no pickles), atomically so a killed run never leaves half a cache entry, and two
        processes writing the same entry leave one whole copy; refuses a result that is not finite. `version`
        names the computation (another analysis, `weightfree`, writes its own)."""
        self.check()
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {
            "features": self.features,
            "beat_times": self.beat_times,
            "downbeat_times": self.downbeat_times,
            "meta": np.array(
                json.dumps(
                    {
                        "version": version,
                        "tempo_bpm": self.tempo_bpm,
                        "duration_s": self.duration_s,
                        "fps": self.fps,
                    }
                )
            ),
        }
        if self.mel is not None:
            arrays["mel"] = self.mel
        with atomic_open(path, "wb") as f:
            np.savez(f, **arrays)

    @classmethod
    def load(cls, path: str | Path, version: str = FEATURE_VERSION) -> MusicAnalysis:
        """Read an entry written by `save` with `version`; ValueError for anything else (truncated, empty, stale,
        damaged, another analysis')."""
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                if meta.get("version") != version:
                    raise ValueError(f"features of version {meta.get('version')}")
                result = cls(
                    features=z["features"],
                    beat_times=z["beat_times"],
                    downbeat_times=z["downbeat_times"],
                    tempo_bpm=float(meta["tempo_bpm"]),
                    duration_s=float(meta["duration_s"]),
                    fps=int(meta["fps"]),
                    mel=z["mel"] if "mel" in z.files else None,
                )
            result.check()
        except Exception as e:  # any way a file fails to be an entry (damaged zip, nested JSON, an overflow...)
            raise ValueError(first_line(e)) from e
        return result


def default_cache_dir() -> Path:
    """The feature cache: `features/` in the one cache folder (`$DANCENET_CACHE` or ~/.cache/dancenet)."""
    return cache_root() / "features"


def cache_key(path: str | Path) -> str:
    """Hash of the file's bytes and of every setting that changes the result, so edits invalidate it."""
    import madmom  # madmom takes ~0.9 s to load: only an analysis that misses the cache loads it

    return song_key(
        path,
        [
            FEATURE_VERSION,
            madmom.__version__,
            MADMOM_SAMPLE_RATE,
            BLOCK_S,
            CONTEXT_S,
            DBN_BLOCK_S,
            DBN_CONTEXT_S,
            list(BEATS_PER_BAR),
            MEL_BANDS,
            "blas-threads-1",  # the networks' sums in one order (`one_blas_thread`); before, in as many as threads
        ],
    )


def song_key(path: str | Path, settings: list) -> str:
    """Hash of a song file's bytes and of the `settings` that change its analysis (a cache entry's name)."""
    with open(path, "rb") as f:
        h = hashlib.file_digest(f, "sha256")
    h.update(json.dumps(settings).encode())
    return h.hexdigest()[:40]


def cached_analysis(entry: Path | None, compute: Callable[[], MusicAnalysis], version: str = FEATURE_VERSION,
                    report: Progress | None = None) -> MusicAnalysis:
    """The analysis cached at `entry` with `version`, else `compute()`d and cached there (None: no cache). A
    damaged, stale or unreadable entry is computed again; one that cannot be written costs only the cache."""
    if entry is not None:
        try:
            if entry.is_file():
                if report is not None:
                    report(1.0)
                return MusicAnalysis.load(entry, version)
        except (ValueError, OSError) as e:
            print(f"dancenet: the cached analysis {entry.name} cannot be used ({first_line(e, 120)}); "
                  "analysing the song again", file=sys.stderr)
    result = compute()
    if entry is not None:
        try:
            result.save(entry, version)
        except (DanceNetError, ValueError, OSError) as e:  # a full disk, a cache folder that cannot be (a file,
            # read-only) or a damaged result lose the cache entry only
            print(f"dancenet: the music analysis is not cached ({first_line(e, 160)}); carrying on without "
                  "the cache (set DANCENET_CACHE to a folder you can write to)", file=sys.stderr)
    return result


def analyze_music(
    path: str | Path,
    *,
    cache_dir: str | Path | None = None,
    use_cache: bool = True,
    with_mel: bool = False,
    workers: int | None = None,
    progress: Progress | None = None,
) -> MusicAnalysis:
    """Analyse a song file, reusing the on-disk cache when the same bytes were analysed before."""
    report = progress or (lambda _f: None)
    entry = None
    if use_cache:
        entry = Path(cache_dir).expanduser() if cache_dir else default_cache_dir()
        entry = entry / f"{cache_key(_existing(path))}.npz"

    def compute() -> MusicAnalysis:
        audio = load_audio(path)
        report(0.02)
        return analyze_audio(audio, workers=workers, progress=lambda f: report(0.02 + 0.98 * f))

    result = cached_analysis(entry, compute, report=report)
    return result if with_mel else _without_mel(result)


def analyze_audio(audio: Audio, *, workers: int | None = None, progress: Progress | None = None) -> MusicAnalysis:
    """Run the networks block by block, stitch the activations, track beats; mel is always included."""
    report = progress or (lambda _f: None)
    if audio.sample_rate != MADMOM_SAMPLE_RATE:
        raise ValueError(f"analyze_audio needs {MADMOM_SAMPLE_RATE} Hz audio")
    x, n = audio.samples, len(audio.samples)
    blocks = _blocks(n, BLOCK_S * MADMOM_SAMPLE_RATE, CONTEXT_S * MADMOM_SAMPLE_RATE)
    if jit.may_compile():  # else the kernels not yet compiled run their numpy twins (dancenet_core/jit.py)
        madmom_nets.load_compiled()  # before the workers fork, so they inherit them
        madmom_dbn.load_compiled()
    with _executor(workers, len(blocks)) as ex:
        jobs = [(x[s0:s1], c0 - s0, c1 - s0, c1 == n) for s0, c0, c1, s1 in blocks]
        parts = _run_all(ex, _network_block, jobs, lambda f: report(0.9 * f))
        onset, act, chroma, mel = (np.concatenate([p[k] for p in parts]) for k in range(4))
        windows = _blocks(len(act), DBN_BLOCK_S * ACT_FPS, DBN_CONTEXT_S * ACT_FPS)
        jobs = [(act[s0:s1], c0 - s0, c1 - s0, s0 / ACT_FPS) for s0, c0, c1, s1 in windows]
        beat_times, downbeat_times = _merge_beats(_run_all(ex, _dbn_window, jobs, lambda f: report(0.9 + 0.09 * f)))
    t = int(np.floor(n / _HOP_10 + 0.5))
    features = np.empty((t, N_FEATURES), np.float32)
    features[:, CHROMA_COLS] = chroma[:t]
    features[:, BEAT_COL : DOWNBEAT_COL + 1] = stretch_frames(act, len(chroma)).astype(np.float32)[:t]
    features[:, ONSET_COL] = stretch_frames(onset[:, None], len(chroma)).astype(np.float32)[:t, 0]
    ibi = np.diff(beat_times)
    tempo = float(60.0 / np.median(ibi)) if len(ibi) else 0.0
    report(1.0)
    return MusicAnalysis(features, beat_times, downbeat_times, tempo, audio.duration_s, FPS, mel[:t])


def _run_all(ex: Executor, fn: Callable, jobs: list[tuple], report: Progress) -> list:
    """Results in job order, reporting the fraction done; pending jobs are dropped if one fails."""
    futures = [ex.submit(fn, *job) for job in jobs]
    out = []
    try:
        for i, fut in enumerate(futures):
            out.append(fut.result())
            report((i + 1) / len(futures))
    except BaseException:
        stop_pool(ex)
        raise
    return out


def _existing(path: str | Path) -> Path:
    """Hashing needs the bytes; let load_audio phrase the error for anything unreadable."""
    p = Path(path)
    if not p.is_file() or p.stat().st_size == 0:
        load_audio(p)  # raises the user-facing DanceNetError
    return p


def _without_mel(a: MusicAnalysis) -> MusicAnalysis:
    return MusicAnalysis(a.features, a.beat_times, a.downbeat_times, a.tempo_bpm, a.duration_s, a.fps, None)


def _blocks(n: int, core: int, ctx: int) -> list[tuple[int, int, int, int]]:
    """(start, core start, core end, end) for cores of `core` items with up to `ctx` items of context."""
    return [(max(0, c0 - ctx), c0, min(n, c0 + core), min(n, c0 + core + ctx)) for c0 in range(0, n, core)]


def _executor(workers: int | None, jobs: int) -> Executor:
    """Worker processes (forked, so nothing is re-imported) where the platform allows, else in-process."""
    if workers is None:
        workers = default_workers()
    workers = min(workers, jobs)
    if workers > 1 and "fork" in mp.get_all_start_methods():
        return ProcessPoolExecutor(workers, mp_context=mp.get_context("fork"), initializer=_start_worker,
                                   initargs=(os.getpid(),))
    return _InlineExecutor()


def _start_worker(parent: int) -> None:
    """Worker start-up: end with the analysing process, however it ends, and keep freed memory."""
    end_with_parent(parent)
    _keep_freed_memory()


def _keep_freed_memory() -> None:
    """glibc's malloc maps each large array on its own and gives it back to the kernel
    when freed, so every block's arrays were fresh pages to fault in and zero (~15 % of the cold
    analysis' CPU, more on a virtual machine that hands freed memory back to its host); a worker lives
    for one analysis, so it keeps what it frees for the next block: no separate mappings, no trimming."""
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # not glibc: its allocator as it is
        return
    mallopt(-4, 0)  # M_MMAP_MAX: every allocation from the heap, which glibc reuses
    mallopt(-1, 2**31 - 1)  # M_TRIM_THRESHOLD: never hand the heap's free top back


class _InlineExecutor(Executor):
    """Runs submitted calls at once in this process (the Blender-safe path)."""

    def submit(self, fn, /, *args, **kwargs):  # type: ignore[override]
        fut: Future = Future()
        try:
            fut.set_result(fn(*args, **kwargs))
        except BaseException as e:  # handed to the caller through the future, as a pool would
            fut.set_exception(e)
        return fut


def _processors() -> tuple:
    """Fresh per block (building them takes ~20 ms): madmom's spectrogram-difference step keeps the last
    input, and with it the whole complex STFT, alive inside the processor. The onset and beat processors
    are madmom's, sharing their STFTs, with their networks run by a compiled time loop (madmom_nets)."""
    # madmom takes ~0.9 s to load: only an analysis that misses the cache loads it
    from madmom.audio.chroma import DeepChromaProcessor
    from madmom.audio.filters import MelFilterbank
    from madmom.audio.signal import FramedSignalProcessor
    from madmom.audio.spectrogram import FilteredSpectrogramProcessor, LogarithmicSpectrogramProcessor
    from madmom.audio.stft import ShortTimeFourierTransformProcessor
    from madmom.processors import SequentialProcessor


    mel = SequentialProcessor(
        (
            FramedSignalProcessor(frame_size=4096, fps=FPS),
            ShortTimeFourierTransformProcessor(),
            FilteredSpectrogramProcessor(
                filterbank=MelFilterbank,
                num_bands=MEL_BANDS,
                fmin=30,
                fmax=11000,
                norm_filters=True,
                unique_filters=False,
            ),
            LogarithmicSpectrogramProcessor(mul=1, add=1),
        )
    )
    return OnsetAndBeat(), DeepChromaProcessor(), mel


@one_blas_thread
def _network_block(
    x: np.ndarray, c0: int, c1: int, last: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Onset and beat/downbeat activations (100 fps), chroma and mel (10 fps) for samples [c0, c1) of x,
    whose start is on the 10-fps grid; the last block keeps every frame to the end of the signal."""
    # madmom takes ~0.9 s to load: only an analysis that misses the cache loads it
    from madmom.audio.signal import Signal

    onset_beat_p, chroma_p, mel_p = _processors()
    sig = Signal(x, sample_rate=MADMOM_SAMPLE_RATE, num_channels=1)
    onset, beat = onset_beat_p(sig)

    def core(a: np.ndarray, hop: int) -> np.ndarray:
        return a[c0 // hop :] if last else a[c0 // hop : c1 // hop]

    return (
        core(np.asarray(onset, np.float32), _HOP_ACT),
        core(np.asarray(beat, np.float32), _HOP_ACT),
        core(np.asarray(chroma_p(sig), np.float32), _HOP_10),
        core(np.asarray(mel_p(sig), np.float32), _HOP_10),
    )


def _tracker():
    """madmom's downbeat DBN for 3 and 4 beats to the bar, its Viterbi decode compiled (madmom_dbn)."""
    # madmom takes ~0.9 s to load: only an analysis that misses the cache loads it
    from madmom.features.downbeats import DBNDownBeatTrackingProcessor

    return madmom_dbn.compiled_dbn(DBNDownBeatTrackingProcessor(beats_per_bar=list(BEATS_PER_BAR), fps=ACT_FPS))


def _dbn_window(act: np.ndarray, c0: int, c1: int, t0: float) -> np.ndarray:
    """Beats [time s, position in bar] found in the core [c0, c1) of one window of activations."""
    beats = np.asarray(_tracker()(act), np.float64).reshape(-1, 2)
    keep = (beats[:, 0] >= c0 / ACT_FPS) & (beats[:, 0] < c1 / ACT_FPS)
    beats = beats[keep]
    beats[:, 0] += t0
    return beats


def _merge_beats(windows: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Join windows' beats; a beat found by both windows at a seam is kept once."""
    beats = np.concatenate(windows) if windows else np.zeros((0, 2))
    if len(beats) > 2:
        min_gap = 0.5 * float(np.median(np.diff(beats[:, 0])))
        keep = np.ones(len(beats), bool)
        last = beats[0, 0]
        for i in range(1, len(beats)):
            keep[i] = beats[i, 0] - last >= min_gap
            if keep[i]:
                last = beats[i, 0]
        beats = beats[keep]
    return beats[:, 0].copy(), beats[beats[:, 1] == 1, 0].copy()


def music_at_frames(features: np.ndarray, feature_fps: float, times: np.ndarray) -> np.ndarray:
    """Music features [T_music, F] (frame j centred at j / feature_fps) sampled at `times` (seconds)."""
    return interp_frames(features, times * feature_fps).astype(np.float32)

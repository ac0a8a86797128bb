"""The music analysis without trained weights, for dances a studio may use (`--commercial`): onsets, tempo, beats,
meter, downbeats and chroma from signal processing alone, in the layout `features.MusicAnalysis` has (15 columns
at 10 fps), so that the library engine and the song's form read it as they read the default analysis.

The default analysis runs madmom's networks (CC BY-NC-SA 4.0 model files); nothing here opens a model file or
imports madmom (0.9 s to import alone). The steps, each a few numpy/scipy calls on a 3-minute song:

1. Spectra. A 2048-sample STFT at 100 fps (`ONSET_FPS`) summed into log-spaced bands (12 an octave, 30 Hz -
   16 kHz), and an 8192-sample one at 10 fps folded into pitch classes (55 Hz - 2 kHz; 5.4 Hz bins keep the
   bass notes' pitch classes apart), each computed a block of frames at a time.
2. Onsets. Spectral flux of the log-compressed band magnitudes, averaged over the bands (every octave weighs
   the same: a hi-hat's many bins do not drown a bass note) less its moving mean; the compression is linear
   below -40 dB of the loudest band, so the click that ends a note in silent high bands is no onset. Beside
   it, the bass flux: the rise of the magnitude below 120 Hz (a kick, a bass note).
3. Tempo. The onset envelope's autocorrelation read through a comb (the lag and its multiples) for every beat
   period from 60 to 200 BPM, times a wide log-normal preference around 110 BPM. Its octave is then settled by
   the accents (onset and bass flux) between the beats: half-beats at least 0.7 as strong as the beats are
   beats (the tempo doubled); every other beat under 0.3 of the rest is an off-beat (halved).
4. Beats. Dynamic programming over the onset envelope (Ellis 2007): each frame's best chain of beats whose
   intervals keep near the period, scored by the onsets they land on, a block of half a period at a time (a
   frame looks back at least that far); the chain ending best near the song's end is followed back.
5. Meter and downbeats. The chroma averaged over each beat; for bars of 3 and of 4 beats, how much the harmony
   of the bar's worth of beats from each beat differs from that of the bar's worth before it (chords change
   with the bar); the meter, and the beat of the bar, on which that change stands out most over the others.

The beat and downbeat columns hold a bump (0.05 s wide) on each tracked beat and downbeat, as the networks'
activations peak there; the onset column the flux scaled to [0, 1]; the chroma each frame's energy per pitch
class over its loudest. Measured against songs with known beats and the default analysis by
bench/weightfree_beats.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import fft
from scipy.ndimage import maximum_filter1d
from scipy.signal import correlate
from scipy.sparse import csr_array

from ..progress import Progress
from .audio import MADMOM_SAMPLE_RATE, Audio, load_audio
from .features import (
    BEAT_COL,
    CHROMA_COLS,
    DOWNBEAT_COL,
    FEATURE_NAMES,
    FPS,
    N_FEATURES,
    ONSET_COL,
    FeatureSpec,
    MusicAnalysis,
    cached_analysis,
    default_cache_dir,
    song_key,
)

WEIGHTFREE_VERSION = "music-features-weightfree-1"  # change whenever any computation below changes
WEIGHTFREE_SPEC = FeatureSpec(WEIGHTFREE_VERSION, FPS, FEATURE_NAMES)  # the same columns, another computation

SR = MADMOM_SAMPLE_RATE
ONSET_FPS = 100
ONSET_FRAME = 2048
CHROMA_FRAME = 8192
MIN_BPM, MAX_BPM = 60.0, 200.0
PREFERRED_BPM, PREFERENCE_OCTAVES = 110.0, 1.0  # the log-normal tempo preference: centre and width (octaves)
BASS_HZ = 120.0
BANDS_PER_OCTAVE = 12
TIGHTNESS = 100.0  # how strongly the beat chain keeps to the period (Ellis' alpha)
HALVE_BELOW = 0.3  # every other beat this much weaker than the rest: they are off-beats
DOUBLE_ABOVE = 0.7  # half-beats this strong against the beats: they are beats
BUMP_S = 0.05
BLOCK_FRAMES = 512  # STFT frames transformed at a time
FLOOR = 0.01  # the onsets' log compression is linear below this share of the song's loudest band (-40 dB): the
# click that ends a note in silent high bands is no onset


def cache_key(path: str | Path) -> str:
    """Hash of the file's bytes and of this analysis' version."""
    return "wf-" + song_key(path, [WEIGHTFREE_VERSION, SR, ONSET_FRAME, CHROMA_FRAME])


def analyze_music_weightfree(path: str | Path, *, cache_dir: str | Path | None = None, use_cache: bool = True,
                             progress: Progress | None = None) -> MusicAnalysis:
    """`features.analyze_music` without trained weights: the same cache folder, entries of their own."""
    report = progress or (lambda _f: None)
    entry = None
    if use_cache and Path(path).is_file() and Path(path).stat().st_size:
        entry = (Path(cache_dir).expanduser() if cache_dir else default_cache_dir()) / f"{cache_key(path)}.npz"
    result = cached_analysis(entry, lambda: analyze_audio_weightfree(load_audio(path)), WEIGHTFREE_VERSION)
    report(1.0)
    return result


def analyze_audio_weightfree(audio: Audio) -> MusicAnalysis:
    """The analysis of a decoded song (44.1 kHz mono)."""
    if audio.sample_rate != SR:
        raise ValueError(f"the analysis needs {SR} Hz audio")
    x = np.asarray(audio.samples, np.float32)
    onset, bass = onset_envelopes(x)
    energy = pitch_class_energy(x)
    chroma = chroma_features(energy)
    period = beat_period(onset, bass)
    beats = track_beats(onset, period) / ONSET_FPS
    meter, phase = meter_and_phase(beats, np.sqrt(energy))
    downbeats = beats[phase::meter] if len(beats) else beats
    t = int(np.floor(len(x) / (SR // FPS) + 0.5))
    features = np.zeros((t, N_FEATURES), np.float32)
    features[:, CHROMA_COLS] = chroma[:t] if len(chroma) >= t else np.pad(chroma, ((0, t - len(chroma)), (0, 0)))
    features[:, BEAT_COL] = _bumps(beats, t)
    features[:, DOWNBEAT_COL] = _bumps(downbeats, t)
    peaks = maximum_filter1d(np.maximum(onset, 0.0), ONSET_FPS // FPS)  # an onset between two frames kept
    scale = max(float(np.percentile(peaks, 99.5)), 1e-9)
    features[:, ONSET_COL] = np.clip(np.interp(np.arange(t) * (ONSET_FPS / FPS), np.arange(len(peaks)), peaks)
                                     / scale, 0.0, 1.0)
    ibi = np.diff(beats)
    tempo = float(60.0 / np.median(ibi)) if len(ibi) else 0.0
    return MusicAnalysis(features, beats, downbeats.copy(), tempo, audio.duration_s, FPS, None)


def _filtered_spectrogram(x: np.ndarray, frame: int, hop: int, matrix: csr_array, power: float) -> np.ndarray:
    """|STFT| ** power of x, frame j centred at sample j * hop (zero-padded at the ends), times `matrix`
    [frame // 2 + 1, K]: [frames, K]. In blocks of frames, so that no [frames, frame] array is ever held (a
    3-minute song's would be 150 MB, and the time went to memory, not to the FFT)."""
    padded = np.pad(x, (frame // 2, frame // 2))
    n = 1 + (len(x) - 1) // hop
    frames = np.lib.stride_tricks.as_strided(padded, (n, frame), (padded.strides[0] * hop, padded.strides[0]),
                                             writeable=False)
    window = np.hanning(frame).astype(np.float32)
    out = np.empty((n, matrix.shape[1]), np.float32)
    for start in range(0, n, BLOCK_FRAMES):
        mag = np.abs(fft.rfft(frames[start : start + BLOCK_FRAMES] * window, axis=1, workers=-1))
        out[start : start + BLOCK_FRAMES] = (matrix.T @ (mag if power == 1 else mag**power).T).T
    return out


def _log_bands(freqs: np.ndarray, low: float, high: float) -> csr_array:
    """[bins, bands] a sum over log-spaced bands (`BANDS_PER_OCTAVE`), each band's bins averaged."""
    edges = low * 2.0 ** (np.arange(0, np.log2(high / low) * BANDS_PER_OCTAVE + 1) / BANDS_PER_OCTAVE)
    band = np.searchsorted(edges, freqs) - 1
    used = (band >= 0) & (band < len(edges) - 1)
    m = np.zeros((len(freqs), len(edges) - 1), np.float32)
    m[np.flatnonzero(used), band[used]] = 1.0
    m = m[:, m.sum(axis=0) > 0]
    return csr_array(m / m.sum(axis=0))


def onset_envelopes(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(onset flux over all bands less its moving mean, bass flux below `BASS_HZ` over its largest), each [frames]
    at `ONSET_FPS`. The bass flux is of the bands' magnitude, not its log: a kick or a bass note, not the low end
    of a snare's noise."""
    bands = _filtered_spectrogram(x, ONSET_FRAME, SR // ONSET_FPS,
                                  _log_bands(np.fft.rfftfreq(ONSET_FRAME, 1 / SR), 30.0, 16000.0), 1)
    level = np.log1p(bands / (FLOOR * max(float(np.percentile(bands, 99.9)), 1e-12)))
    rise = np.maximum(np.diff(level, axis=0, prepend=level[:1]), 0.0)
    onset = rise.mean(axis=1)
    low = bands[:, : int(np.log2(BASS_HZ / 30.0) * BANDS_PER_OCTAVE)].sum(axis=1)
    bass = np.maximum(np.diff(low, prepend=low[:1]), 0.0)
    return onset - _local_mean(onset), bass / max(float(bass.max()), 1e-12)


def _local_mean(a: np.ndarray, width: int = 25) -> np.ndarray:
    """The moving mean over `width` frames (what the flux rests on between onsets)."""
    return np.convolve(a, np.ones(width) / width, mode="same")


def pitch_class_energy(x: np.ndarray) -> np.ndarray:
    """[frames, 12] spectral energy per pitch class (C first) at 10 fps, 55 Hz - 2 kHz."""
    freqs = np.fft.rfftfreq(CHROMA_FRAME, 1 / SR)
    use = np.flatnonzero((freqs >= 55.0) & (freqs <= 2000.0))
    pitch = np.round(12 * np.log2(freqs[use] / 440.0)).astype(int) + 9  # A = 9 with C = 0
    fold = np.zeros((len(freqs), 12), np.float32)
    fold[use, pitch % 12] = 1.0
    return _filtered_spectrogram(x, CHROMA_FRAME, SR // FPS, csr_array(fold), 2)


def chroma_features(energy: np.ndarray) -> np.ndarray:
    """The chroma columns: log-compressed pitch-class energy over each frame's loudest class."""
    chroma = np.log1p(energy / (FLOOR * max(float(np.percentile(energy, 99.9)), 1e-12)))
    return (chroma / np.maximum(chroma.max(axis=1, keepdims=True), 1e-9)).astype(np.float32)


def beat_period(onset: np.ndarray, bass: np.ndarray) -> float:
    """The beat period in onset frames (see the module's docstring, step 3)."""
    env = np.maximum(onset, 0.0)
    env = env - env.mean()
    ac = correlate(env, env, mode="full", method="fft")[len(env) - 1 :]
    ac = ac / max(ac[0], 1e-12)
    lags = np.arange(int(60 * ONSET_FPS / MAX_BPM), int(60 * ONSET_FPS / MIN_BPM) + 1, dtype=float)
    comb = sum(w * _at(ac, k * lags) for k, w in ((1, 1.0), (2, 0.5), (3, 0.33), (4, 0.25)))
    bpm = 60 * ONSET_FPS / lags
    prior = np.exp(-0.5 * (np.log2(bpm / PREFERRED_BPM) / PREFERENCE_OCTAVES) ** 2)
    period = _refine(ac, float(lags[int(np.argmax(comb * prior))]))
    accents = _standard(np.maximum(onset, 0.0)) + _standard(bass)
    fastest, slowest = 60 * ONSET_FPS / (MAX_BPM * 1.05), 60 * ONSET_FPS / (MIN_BPM * 0.95)
    if period / 2 >= fastest and _offbeat_ratio(accents, period / 2) > DOUBLE_ABOVE:
        return _refine(ac, period / 2)
    if 2 * period <= slowest and _offbeat_ratio(accents, period) < HALVE_BELOW:
        return _refine(ac, 2 * period)
    return period


def _at(a: np.ndarray, positions: np.ndarray) -> np.ndarray:
    return np.interp(positions, np.arange(len(a)), a, right=0.0)


def _refine(ac: np.ndarray, period: float) -> float:
    """The period at the autocorrelation's peak within 6 % of `period`, to a tenth of a frame."""
    fine = np.arange(period * 0.94, period * 1.06, 0.1)
    return float(fine[int(np.argmax(sum(_at(ac, k * fine) / k for k in (1, 2, 3, 4))))])


def _offbeat_ratio(env: np.ndarray, period: float) -> float:
    """The onsets on the weaker half of a double-length grid over those on the stronger half: about 1 when every
    beat of `period` is alike, small when every other one is an off-beat."""
    env = env - env.min()
    phases = np.arange(0, 2 * period, 1.0)
    on = np.array([_at(env, np.arange(p, len(env) - 1, 2 * period)).mean() for p in phases])
    p = phases[int(np.argmax(on))]
    off = _at(env, np.arange(p + period, len(env) - 1, 2 * period)).mean()
    floor = float(np.median(env))
    return float((off - floor) / max(on.max() - floor, 1e-12))


def track_beats(onset: np.ndarray, period: float) -> np.ndarray:
    """Beat frames [B] (float) by dynamic programming (module docstring, step 4)."""
    env = np.maximum(onset, 0.0)
    env = env / max(float(env.std()), 1e-12)
    n = len(env)
    if n < 2 * period:
        return np.zeros(0)
    lo, hi = int(round(period / 2)), int(round(2 * period))
    offsets = np.arange(lo, hi + 1)
    penalty = -TIGHTNESS * np.log(offsets / period) ** 2
    score = env.copy()
    back = np.full(n, -1)
    for start in range(lo, n, lo):  # a block of `lo` frames looks back only to frames before it: one step each
        t = np.arange(start, min(start + lo, n))
        source = t[:, None] - offsets[None, :]
        window = np.where(source >= 0, score[np.maximum(source, 0)] + penalty, -np.inf)
        k = np.argmax(window, axis=1)
        best = window[np.arange(len(t)), k]
        chained = best > 0
        score[t[chained]] += best[chained]
        back[t[chained]] = source[chained, k[chained]]
    tail = np.arange(max(0, n - int(round(period))), n)
    t = int(tail[np.argmax(score[tail])])
    path = [t]
    while back[path[-1]] >= 0:
        path.append(int(back[path[-1]]))
    beats = np.array(path[::-1], float)
    return beats[(beats >= 0) & (beats < n)]


def meter_and_phase(beats: np.ndarray, chroma: np.ndarray) -> tuple[int, int]:
    """(beats to the bar, index of the first downbeat among the first beats) from a chroma [frames, 12] at 10 fps
    (module docstring, step 5)."""
    if len(beats) < 16:
        return 4, 0
    edges = np.clip(np.round(beats * FPS).astype(int), 0, len(chroma) - 1)
    ends = np.append(edges[1:], len(chroma))
    sync = np.stack([chroma[a : max(b, a + 1)].mean(axis=0) for a, b in zip(edges, ends, strict=True)])
    best = (-np.inf, 4, 0)
    for meter in (3, 4):
        change = _standard(_bar_change(sync, meter))
        by_phase = np.array([change[p::meter].mean() for p in range(meter)])
        phase = int(np.argmax(by_phase))
        best = max(best, (by_phase[phase] - np.delete(by_phase, phase).mean(), meter, phase))
    return best[1], best[2]


def _bar_change(sync: np.ndarray, meter: int) -> np.ndarray:
    """[B] how much the harmony of the `meter` beats from each beat on differs from that of the `meter` beats
    before it (1 - cosine): high where bars of `meter` beats start, when chords change with the bar."""
    c = np.cumsum(np.vstack([np.zeros(12), sync]), axis=0)
    k = np.arange(len(sync))
    before = c[k] - c[np.maximum(k - meter, 0)]
    after = c[np.minimum(k + meter, len(sync))] - c[k]
    cos = np.sum(before * after, axis=1) / np.maximum(np.linalg.norm(before, axis=1) * np.linalg.norm(after, axis=1),
                                                      1e-9)
    out = 1.0 - cos
    out[(k < meter) | (k > len(sync) - meter)] = np.median(out)  # a window cut by the song's ends
    return out


def _standard(a: np.ndarray) -> np.ndarray:
    return (a - a.mean()) / max(float(a.std()), 1e-9)


def _bumps(times: np.ndarray, t: int) -> np.ndarray:
    """[t] at 10 fps: a bump of width `BUMP_S` and height 1 on each of `times`."""
    grid = np.arange(t) / FPS
    if not len(times):
        return np.zeros(t, np.float32)
    after = np.clip(np.searchsorted(times, grid), 0, len(times) - 1)
    nearest = np.minimum(np.abs(grid - times[after]), np.abs(grid - times[np.maximum(after - 1, 0)]))
    return np.exp(-0.5 * (nearest / BUMP_S) ** 2).astype(np.float32)

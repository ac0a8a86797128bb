"""`dancenet analyze SONG`: tempo, style, beats and downbeats of a song, optionally as JSON."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import soundfile as sf
from tqdm import tqdm

from ..atomic import write_text
from ..engines.styles import DANCE_TEMPI, load_style_model, meter_of, style_by_tempo
from ..errors import DanceNetError
from ..licence import analysis_part, licence_block
from ..music.audio import load_audio
from ..music.features import analyze_music
from ..music.form import song_form
from ..music.weightfree import analyze_music_weightfree

# Songs longer than this get a progress bar; shorter ones finish before a bar would be worth reading.
PROGRESS_BAR_MIN_S = 60.0


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("song", help="audio file: wav, flac, ogg, mp3 or opus")
    p.add_argument("--json", metavar="PATH", help="also write beats, downbeats and per-window styles as JSON")
    p.add_argument("--style-model", metavar="PATH",
                   help="style classifier .npz, or a training checkpoint .pt (needs torch); default: the shipped one")
    p.add_argument("--cache-dir", metavar="DIR",
                   help="feature cache (default: features/ in $DANCENET_CACHE or ~/.cache/dancenet)")
    p.add_argument("--no-cache", action="store_true", help="recompute the features even if cached")
    p.add_argument("--commercial", action="store_true",
                   help="only parts whose terms allow commercial use: the weight-free analysis, the style from the "
                        "dance-sport tempo ranges (no classifier; docs/licence.md)")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    t0 = time.time()
    song = Path(args.song)
    duration = _duration_hint(song)
    if duration is None:
        load_audio(song)  # not readable as audio: raises the one-line error
    if args.commercial and args.style_model:
        raise DanceNetError("commercial use: a style classifier is trained weights, which the commercial mode does "
                            "not load; leave --style-model out (the style is read from the tempo and meter)")
    model = None if args.commercial else load_style_model(args.style_model)
    bar = None
    if duration is not None and duration >= PROGRESS_BAR_MIN_S:
        bar = tqdm(total=100, desc="analysing", unit="%", leave=False, bar_format="{l_bar}{bar}| {elapsed}")
    try:
        analysis = (analyze_music_weightfree if args.commercial else analyze_music)(
            song,
            cache_dir=args.cache_dir,
            use_cache=not args.no_cache,
            progress=(lambda f: bar.update(round(100 * f) - bar.n)) if bar else None,
        )
    finally:
        if bar is not None:
            bar.close()
    if model is None:
        tempo_style = style_by_tempo(analysis.tempo_bpm, meter_of(analysis), list(DANCE_TEMPI))
        style_text = f"{tempo_style or 'none'} (by tempo and meter, {meter_of(analysis)}/4)"
        style_json = {"style": tempo_style or None, "by": "tempo and meter", "meter": meter_of(analysis)}
    else:
        style = model.classify(analysis)
        style_text = f"{style.style} (" + ", ".join(
            f"{s} {p:.2f}" for s, p in sorted(zip(style.styles, style.probabilities, strict=True),
                                               key=lambda sp: -sp[1])) + ")"
        style_json = style.to_dict()
    form = song_form(analysis)
    elapsed = time.time() - t0
    print(f"song:      {song.name} ({analysis.duration_s:.1f} s)")
    print(f"tempo:     {analysis.tempo_bpm:.1f} BPM")
    print(f"style:     {style_text}")
    print(f"beats:     {len(analysis.beat_times)}")
    print(f"downbeats: {len(analysis.downbeat_times)}")
    print(f"form:      {' '.join(f'{s.name} {s.start_s:.1f}s' for s in form.sections)}")
    print(f"time:      {elapsed:.1f} s")
    if args.json:
        out = {
            "song": str(song),
            "duration_s": round(analysis.duration_s, 3),
            "tempo_bpm": round(analysis.tempo_bpm, 2),
            "style": style_json,
            "beat_times": [round(float(t), 3) for t in analysis.beat_times],
            "downbeat_times": [round(float(t), 3) for t in analysis.downbeat_times],
            "form": form.to_dict(),
            "features": {"shape": list(analysis.features.shape), "fps": analysis.fps},
            "seconds": round(elapsed, 2),
            "licence": licence_block([analysis_part(args.commercial),
                                      "style_by_tempo" if model is None else "style_classifier"], args.commercial),
        }
        try:
            write_text(args.json, json.dumps(out, indent=1, allow_nan=False) + "\n")
        except OSError as e:
            raise DanceNetError(f"cannot write {args.json}: {e.strerror}; choose a writable path") from e
    return 0


def _duration_hint(path: Path) -> float | None:
    """Duration from the file header, to decide on a progress bar before decoding; None if unreadable."""
    try:
        info = sf.info(str(path))
    except (sf.LibsndfileError, RuntimeError, TypeError, OSError):
        return None
    return info.frames / info.samplerate if info.samplerate else None

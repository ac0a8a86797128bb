"""`dancenet generate SONG -o DIR`: BVH + .npz per take and a JSON summary, with a progress bar."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..atomic import remove_leftovers, write_text
from ..bvh import write_bvh
from ..continuation import keep_original
from ..errors import DanceNetError
from ..generate import DEFAULT_TEMPERATURE, GenerationResult, generate_dance
from ..model.runtime import DEFAULT_RUNTIME, META
from ..motion import FRAME_RATES, Motion
from ..outputs import check_folder_writable, claimed_outputs, refuse_overwrite, safe_stem
from ..render import render_motion
from ..rootmotion import ROOT_MODES, apply_mode, read_dance_bvh, write_root_bone_bvh


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("song", type=Path, help="audio file: wav, flac, ogg, mp3 or opus")
    p.add_argument("-o", "--out", type=Path, required=True, help="output folder (created if missing)")
    p.add_argument("--style", default="auto",
                   help=f"auto (the music's style) or a style the model knows; the shipped one: {_shipped_styles()}")
    p.add_argument("--seed", type=int, default=0, help="same seed, same dance")
    p.add_argument("--temperature", type=float, default=DEFAULT_TEMPERATURE,
                   help=f"variety of the dance, 0 = most likely (default {DEFAULT_TEMPERATURE})")
    p.add_argument("--takes", type=int, default=1, help="number of different dances to generate")
    p.add_argument("--fps", type=int, choices=FRAME_RATES, default=None,
                   help="frame rate of the files (slerp-resampled; default: the model's own 25)")
    p.add_argument("--root-motion", choices=ROOT_MODES, default="travel",
                   help="travel (as danced), in-place (no horizontal path, heading kept) or root-bone (a 'root' "
                        "joint on the floor carries path and heading; the .npz keeps the dance as danced)")
    p.add_argument("--start", type=float, default=0.0, metavar="SECONDS",
                   help="dance from this many seconds into the song (default: its beginning)")
    p.add_argument("--end", type=float, default=None, metavar="SECONDS",
                   help="dance up to this many seconds into the song (default: its end)")
    p.add_argument("--continue", dest="continue_from", type=Path, default=None, metavar="BVH",
                   help="keep this dance (a BVH from `dancenet generate` for the same song and --start) up to "
                        "--at and dance the rest anew after it")
    p.add_argument("--at", type=float, default=None, metavar="SECONDS",
                   help="with --continue: seconds into the kept dance where the new dancing starts")
    p.add_argument("--no-footfix", action="store_true", help="skip the foot-sliding clean-up")
    p.add_argument("--weights", type=Path, default=None, help="a DanceNet weights file (default: shipped)")
    p.add_argument("--render", action="store_true", help="also render a preview video with the music")
    p.add_argument("--overwrite", action="store_true", help="replace outputs already in the folder")
    p.set_defaults(handler=run)


def _shipped_styles() -> str:
    """The shipped model's styles, for --help: read from its metadata alone, so asking for help loads no weights
    (a damaged file is reported, in one line, when a dance loads it)."""
    try:
        with np.load(DEFAULT_RUNTIME) as f:
            return ", ".join(json.loads(str(f[META]))["config"]["styles"])
    except (OSError, ValueError, KeyError):
        return "unreadable (reinstall the package)"


def _names(stem: str, takes: int) -> list[str]:
    return [stem] if takes == 1 else [f"{stem}_take{k}" for k in range(1, takes + 1)]


def _outputs(args: argparse.Namespace, stem: str) -> list[Path]:
    """Every file this run will write, so none is replaced unless the user asked."""
    suffixes = (".bvh", ".npz", ".mp4") if args.render else (".bvh", ".npz")
    return [args.out / f"{n}{s}" for n in _names(stem, args.takes) for s in suffixes] + [args.out / f"{stem}.json"]


def _kept_dance(args: argparse.Namespace) -> Motion | None:
    """The dance to continue, read and checked against --at before any music is analysed."""
    if args.continue_from is None:
        if args.at is not None:
            raise DanceNetError("--at goes with --continue BVH (the dance to continue)")
        return None
    if args.at is None:
        raise DanceNetError("--continue needs --at SECONDS: where in the kept dance the new dancing starts")
    kept = read_dance_bvh(args.continue_from)
    if not 0 < args.at <= kept.duration:
        raise DanceNetError(f"--at must be within the kept dance (0 to {kept.duration:.2f} s), got {args.at}")
    return kept


def run(args: argparse.Namespace) -> int:
    stem = safe_stem(args.song)
    kept = _kept_dance(args)
    check_folder_writable(args.out)
    remove_leftovers(args.out)
    outputs = _outputs(args, stem)
    if not args.overwrite:
        refuse_overwrite(outputs)
    # A bar drawn keeps its last state on a line of its own (leave=True ends it with a newline), so the summary
    # below starts its own line, also where stderr and stdout share a log; a run under `delay` draws none.
    bar = tqdm(total=100, unit="%", bar_format="{desc:<18} {bar} {percentage:3.0f}% {elapsed}", delay=0.5,
               leave=True)
    state = {"stage": ""}

    def progress(stage: str, fraction: float) -> None:
        if stage != state["stage"]:
            state["stage"] = stage
            bar.set_description_str(stage, refresh=False)
        bar.update(int(100 * fraction) - bar.n)  # through update, so tqdm knows what it drew and ends that line

    t0 = time.perf_counter()
    try:
        result = generate_dance(args.song, style=args.style, seed=args.seed, temperature=args.temperature,
                                takes=args.takes, footfix=not args.no_footfix, progress=progress,
                                weights=str(args.weights) if args.weights else None, start_s=args.start,
                                end_s=args.end, continue_from=kept, at_s=args.at or 0.0)
    finally:
        bar.close()
    if kept is not None:  # the kept frames as they were, at the kept dance's rate (or --fps)
        join = round(args.at * result.motions[0].fps) / result.motions[0].fps
        kept = kept.resampled(args.fps or kept.fps)
        result.motions = [keep_original(kept, m, join) for m in result.motions]
    elif args.fps is not None:
        result.motions = [m.resampled(args.fps) for m in result.motions]
    result.motions = [apply_mode(m, args.root_motion) for m in result.motions]
    with claimed_outputs(outputs, args.overwrite) as temp:  # this run's files appear together, or none
        summary = _write(args, stem, result, temp, t0)
    print(f"{result.style} dance, {summary['frames']} frames at {summary['fps']:g} fps "
          f"({result.tempo_bpm:.0f} BPM) in {result.timings['total_s']:.1f} s -> {args.out}")
    return 0


def _write(args: argparse.Namespace, stem: str, result: GenerationResult, temp: dict[Path, Path],
           t0: float) -> dict:
    """Write every output to its temporary path in `temp` (keyed by its final path); returns the summary."""
    write_dance_bvh = write_root_bone_bvh if args.root_motion == "root-bone" else write_bvh
    files = []
    t = time.perf_counter()
    for name, motion in zip(_names(stem, len(result.motions)), result.motions, strict=True):
        write_dance_bvh(temp[args.out / f"{name}.bvh"], motion)
        motion.save(temp[args.out / f"{name}.npz"])
        files += [f"{name}.bvh", f"{name}.npz"]
    result.timings["writing_s"] = time.perf_counter() - t
    if args.render:
        t = time.perf_counter()
        for name, motion in zip(_names(stem, len(result.motions)), result.motions, strict=True):
            render_motion(motion, temp[args.out / f"{name}.mp4"], audio=args.song, audio_start=result.start_s)
            files.append(f"{name}.mp4")
        result.timings["render_s"] = time.perf_counter() - t
    result.timings["total_s"] = time.perf_counter() - t0
    summary = {
        "song": str(args.song),
        "style": result.style,
        "style_probabilities": result.style_probabilities,
        "tempo_bpm": round(result.tempo_bpm, 2),
        "start_s": round(result.start_s, 3) + 0.0,  # never -0.0 (`--start -0.0`)
        "duration_s": round(result.duration_s, 3),
        "fps": result.motions[0].fps,
        "frames": result.motions[0].num_frames,
        "takes": len(result.motions),
        "seed": args.seed,
        "temperature": args.temperature,
        "footfix": not args.no_footfix,
        "root_motion": args.root_motion,
        "continued_from": str(args.continue_from) if args.continue_from else None,
        "at_s": args.at,
        "beats": len(result.beat_times),
        "downbeats": len(result.downbeat_times),
        "timings_s": {k: round(v, 3) for k, v in result.timings.items()},
        "files": files,
    }
    write_text(temp[args.out / f"{stem}.json"], json.dumps(summary, indent=2, allow_nan=False) + "\n")
    return summary

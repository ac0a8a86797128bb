"""`dancenet generate SONG -o DIR`: BVH + .npz per take and a JSON summary, with a progress bar."""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..atomic import remove_leftovers, write_text
from ..bvh import write_bvh
from ..errors import DanceNetError
from ..generate import GenerationResult, analyze, generate_dance
from ..outputs import check_folder_writable, claimed_outputs, refuse_overwrite, safe_stem
from ..progress import StageProgress
from ..render import render_motion
from ..request import DanceRequest, add_options, options_from
from ..runtime.weights import DEFAULT_RUNTIME, META
from ..shaping.rootmotion import read_dance_bvh, write_root_bone_bvh
from ..shaping.takes import shape_takes


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("song", type=Path, help="audio file: wav, flac, ogg, mp3 or opus")
    p.add_argument("-o", "--out", type=Path, required=True, help="output folder (created if missing)")
    p.formatter_class = _StylesInHelp
    add_options(p, {"style": f"auto (the music's style) or a style the model knows; the shipped one: "
                             f"{_StylesInHelp.SHIPPED}"})
    p.add_argument("--continue", dest="continue_from", type=Path, default=None, metavar="BVH",
                   help="keep this dance (a BVH from `dancenet generate` for the same song and --start) up to "
                        "--at and dance the rest anew after it")
    p.add_argument("--at", type=float, default=None, metavar="SECONDS",
                   help="with --continue: seconds into the kept dance where the new dancing starts")
    p.add_argument("--render", action="store_true", help="also render a preview video with the music")
    p.add_argument("--form-plot", action="store_true",
                   help="also draw the song's form beside the dance's (<song>_form.png: bar against bar, music and "
                        "dance, the sections marked)")
    p.add_argument("--overwrite", action="store_true", help="replace outputs already in the folder")
    p.set_defaults(handler=run)


class _StylesInHelp(argparse.HelpFormatter):
    """Names the shipped model's styles in --help when the help is printed, not whenever the parser is built: a
    commercial run opens no trained weights, not even to list their styles."""

    SHIPPED = "<shipped styles>"

    def _get_help_string(self, action: argparse.Action) -> str:
        text = super()._get_help_string(action) or ""
        return text.replace(self.SHIPPED, _shipped_styles()) if self.SHIPPED in text else text


def _shipped_styles() -> str:
    """The shipped model's styles, for --help: read from its metadata alone, so asking for help loads no weights
    (a damaged file is reported, in one line, when a dance loads it)."""
    try:
        with np.load(DEFAULT_RUNTIME) as f:
            return ", ".join(json.loads(str(f[META]))["config"]["styles"])
    except (OSError, ValueError, KeyError):
        return "unreadable (reinstall the package)"


def names(stem: str, takes: int) -> list[str]:
    """Each take's file stem: the song's, or `<song>_take<k>` for several takes."""
    return [stem] if takes == 1 else [f"{stem}_take{k}" for k in range(1, takes + 1)]


def outputs(args: argparse.Namespace, stem: str) -> list[Path]:
    """Every file this run will write, so none is replaced unless the user asked."""
    suffixes = (".bvh", ".npz", ".mp4") if args.render else (".bvh", ".npz")
    plot = [args.out / f"{stem}_form.png"] if getattr(args, "form_plot", False) else []
    return [args.out / f"{n}{s}" for n in names(stem, args.takes) for s in suffixes] + plot + [
        args.out / f"{stem}.json"]


def _request(args: argparse.Namespace) -> DanceRequest:
    """The request the options make, with the dance to continue read, checked before the output folder is made
    (generate_dance checks it again, with its engine, before any music is analysed)."""
    kept = None
    if args.continue_from is None:
        if args.at is not None:
            raise DanceNetError("--at goes with --continue BVH (the dance to continue)")
    elif args.at is None:
        raise DanceNetError("--continue needs --at SECONDS: where in the kept dance the new dancing starts")
    else:
        kept = read_dance_bvh(args.continue_from)
    request = DanceRequest(args.song, **options_from(args), continue_from=kept, at_s=args.at or 0.0)
    request.check()
    return request


def run(args: argparse.Namespace) -> int:
    stem = safe_stem(args.song)
    request = _request(args)
    check_folder_writable(args.out)
    remove_leftovers(args.out)
    if not args.overwrite:
        refuse_overwrite(outputs(args, stem))
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

    try:
        result, summary = dance_into(args, request, stem, progress)
    finally:
        bar.close()
    print(f"{result.style} dance, {summary['frames']} frames at {summary['fps']:g} fps "
          f"({result.tempo_bpm:.0f} BPM) in {result.timings['total_s']:.1f} s -> {args.out}")
    for name, details in zip(names(stem, len(result.details)), result.details, strict=True):
        if "long_run_share" in details:
            print(f"{name}: {_copied(details)}")
    return 0


# Files a caller writes beside generate's own, in the same set (`dance_into`): their paths, and what writes
# them, given the result as danced (before `shape_takes`, as the add-on keys it) and each path's temporary name.
Extra = tuple[list[Path], Callable[[GenerationResult, dict[Path, Path]], None]]


def dance_into(args: argparse.Namespace, request: DanceRequest, stem: str, progress: StageProgress | None = None,
               extra: Extra | None = None) -> tuple[GenerationResult, dict]:
    """Dance `request` and write generate's files for it into `args.out`, with `extra`'s, all appearing together
    (replacing what is there only with `args.overwrite`); returns the shaped result and the summary. The one
    path from a request to files, for `generate` and each song of `batch`."""
    t0 = time.perf_counter()
    result = generate_dance(request, progress=progress)
    danced = replace(result, motions=list(result.motions))
    result.motions = shape_takes(result.motions, request)
    paths, write_extra = extra or ([], None)
    with claimed_outputs(outputs(args, stem) + paths, args.overwrite) as temp:  # together, or none
        summary = _write(args, request, stem, result, temp, t0)
        if write_extra is not None:
            write_extra(danced, temp)
    return result, summary


def _form_plot(path: Path, request: DanceRequest, result: GenerationResult) -> None:
    """The song's form beside the first take's (`evaluation.form.form_figure`)."""
    from ..evaluation.form import form_figure  # matplotlib: only for this figure
    from ..representation import heading_frames

    motion = result.motions[0]
    labels = " ".join(s.name for s in result.form.sections)
    form_figure(path, analyze(request.song, request.commercial), motion.positions(), heading_frames(motion), motion.fps,
                result.form, result.start_s, f"{Path(request.song).name}: {labels} (returns: {request.returns})")


def _copied(details: dict) -> str:
    """A library take's copied-run figures (`choreography.Report.summary`), so a user knows how much of the dance
    is one clip played straight through."""
    return (f"{100 * details['long_run_share']:.0f}% of frames from runs of one clip longer than "
            f"{details['long_run_bars']} bars; longest run {details['longest_run_bars']} bars "
            f"({details['longest_run_s']:.1f} s); played within {100 * details['max_warp']:.0f}% of its captured speed")


def _write(args: argparse.Namespace, request: DanceRequest, stem: str, result: GenerationResult,
           temp: dict[Path, Path], t0: float) -> dict:
    """Write every output to its temporary path in `temp` (keyed by its final path); returns the summary, which
    names the song as `args.song` gives it (batch on a cluster reads a copy, `request.song`)."""
    write_dance_bvh = write_root_bone_bvh if args.root_motion == "root-bone" else write_bvh
    files = []
    t = time.perf_counter()
    for name, motion in zip(names(stem, len(result.motions)), result.motions, strict=True):
        write_dance_bvh(temp[args.out / f"{name}.bvh"], motion)
        motion.save(temp[args.out / f"{name}.npz"])
        files += [f"{name}.bvh", f"{name}.npz"]
    result.timings["writing_s"] = time.perf_counter() - t
    if args.render:
        t = time.perf_counter()
        for name, motion in zip(names(stem, len(result.motions)), result.motions, strict=True):
            render_motion(motion, temp[args.out / f"{name}.mp4"], audio=request.song, audio_start=result.start_s)
            files.append(f"{name}.mp4")
        result.timings["render_s"] = time.perf_counter() - t
    if getattr(args, "form_plot", False):
        _form_plot(temp[args.out / f"{stem}_form.png"], request, result)
        files.append(f"{stem}_form.png")
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
        "energy": args.energy,
        "footfix": args.footfix,
        "beat_lock": args.beat_lock,
        "root_motion": args.root_motion,
        "returns": args.returns,
        "sections": [str(o) for o in request.sections],
        "form": result.form.to_dict() if result.form is not None else None,  # the song's sections, song seconds
        "continued_from": str(args.continue_from) if args.continue_from else None,
        "at_s": args.at,
        "beats": len(result.beat_times),
        "downbeats": len(result.downbeat_times),
        "timings_s": {k: round(v, 3) for k, v in result.timings.items()},
        "takes_details": result.details,  # per take, the engine's report (the library engine: the copied runs)
        "files": files,
        "licence": result.licence,  # the parts that made the dance and their terms: may a studio use it?
    }
    write_text(temp[args.out / f"{stem}.json"], json.dumps(summary, indent=2, allow_nan=False) + "\n")
    return summary

"""`dancenet data build|pack|show|alignment`: build the paired dataset (skeleton fits, music features, the CMU
clips retargeted), pack its training songs for another machine, draw a fit beside its source, and score the real
dances' timing by data folder."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..data.build import (
    MODEL_FPS,
    PairedSequence,
    build_dataset,
    dataset_cache_dir,
    fit_report,
    fitted_clip,
    fitted_motion,
    mean_skeleton,
)
from ..data.cmu_dance import read_cmu_manifest
from ..data.dance_with_melody import load_positions, read_manifest
from ..data.pack import save_pack
from ..data.show import draw_fit
from ..data.split import load_split
from ..environment import default_data_dir
from ..evaluation.alignment import alignment_table, report
from ..evaluation.metrics import floor_reach
from ..evaluation.test_split import split_with_beats
from ..representation import decode
from ..shaping.floor import toe_ends
from ..skeleton import Skeleton


def add_arguments(p: argparse.ArgumentParser) -> None:
    dsub = p.add_subparsers(dest="data_command", required=True)
    b = dsub.add_parser("build", help="fit skeletons, pair motion with music, cache on disk")
    b.add_argument("--data", type=Path, default=None, help="the shared data folder (default: ../shared/data)")
    b.add_argument("--out", type=Path, default=None, help="cache folder (default: ~/.cache/dancenet)")
    b.set_defaults(handler=_cmd_build)
    s = dsub.add_parser("show", help="draw a source frame and our fitted skeleton side by side")
    s.add_argument("seq", help="sequence id, e.g. DANCE_W_1, or CMU clip, e.g. 60_01")
    s.add_argument("--frame", type=int, default=None, help="frame index (default: the middle)")
    s.add_argument("--data", type=Path, default=None)
    s.add_argument("--out", type=Path, default=Path("frame.png"))
    s.set_defaults(handler=_cmd_show)
    k = dsub.add_parser("pack", help="the training and validation songs' features in one file, for a machine "
                                     "without the data folder or madmom (`train dancenet --pack`)")
    k.add_argument("out", type=Path, help="pack file to write (.npz)")
    k.add_argument("--data", type=Path, default=None, help="the shared data folder (default: ../shared/data)")
    k.set_defaults(handler=_cmd_pack)
    a = dsub.add_parser("alignment", help="Beat Align Score of the real dances against their songs, by folder")
    a.add_argument("--data", type=Path, default=None, help="the shared data folder (default: ../shared/data)")
    a.set_defaults(handler=_cmd_alignment)


def _cmd_pack(args: argparse.Namespace) -> int:
    split, by_seq, beats = split_with_beats(args.data or default_data_dir(), part="validation")
    keep = set(split["train"]) | set(split.get("validation", []))  # never the test songs
    save_pack([p for p in by_seq.values() if p.seq in keep], args.out, beats)
    pairs = [p for p in by_seq.values() if p.seq in keep]
    mb = args.out.stat().st_size / 2**20
    minutes = sum(len(p.motion) for p in pairs) / MODEL_FPS / 60
    print(f"{args.out}: {len(pairs)} sequences, {minutes:.1f} min, {mb:.1f} MiB")
    return 0


def _cmd_build(args: argparse.Namespace) -> int:
    pairs = build_dataset(args.data or default_data_dir(), args.out)
    split = load_split()
    for name in ("train", "test"):
        mins: dict[str, float] = {}
        for p in pairs:
            if p.seq in split[name]:
                mins[p.style] = mins.get(p.style, 0.0) + len(p.motion) / MODEL_FPS / 60
        print(f"{name}: " + ", ".join(f"{k} {v:.1f} min" for k, v in sorted(mins.items())))
    train = [p for p in pairs if p.seq in split["train"]]
    reach = floor_reach_by_style(train, mean_skeleton(train))
    print("floor reach of the training dances decoded on their average skeleton (share of 2-s windows whose lowest "
          "toe end comes within 1.5 cm of the floor): " + ", ".join(f"{k} {v:.2f}" for k, v in reach.items()))
    data_dir = args.data or default_data_dir()
    out_dir = args.out or dataset_cache_dir()
    rows = []
    for seq in read_manifest(data_dir):
        motion, _ = fitted_motion(seq, out_dir)
        err, stretch = fit_report(motion, load_positions(seq))
        rows.append([err.mean(), np.percentile(err, 95), stretch.mean()])
    f = np.array(rows) * 100
    print(f"fit error on the matched joints over {len(f)} sequences: mean {f[:, 0].mean():.2f} cm "
          f"(worst {f[:, 0].max():.2f}), p95 {f[:, 1].mean():.2f} cm (worst {f[:, 1].max():.2f}); the markers' "
          f"own-bone stretch is {f[:, 2].mean():.2f} cm, {100 * f[:, 2].mean() / f[:, 0].mean():.0f}% of it")
    _build_cmu(data_dir, out_dir)
    return 0


def floor_reach_by_style(pairs: list[PairedSequence], skeleton: Skeleton) -> dict[str, float]:
    """Mean floor reach (`metrics.floor_reach`) of the dances of each style, decoded on `skeleton` as training and
    evaluation decode them: whether the dataset's dances stand on the floor."""
    by: dict[str, list[float]] = {}
    for p in pairs:
        low = toe_ends(decode(p.motion, MODEL_FPS, skeleton))[:, :, 1].min(axis=1)
        by.setdefault(p.style, []).append(floor_reach(low, MODEL_FPS))
    return {s: float(np.mean(v)) for s, v in sorted(by.items())}


def _build_cmu(data_dir: Path, out_dir: Path) -> None:
    """Retarget every CMU clip once (cached) and print the fit error per clip and over all frames."""
    clips = read_cmu_manifest(data_dir)
    if not clips:
        print(f"no CMU clips under {data_dir} (cmu_dance/manifest.csv): skipped")
        return
    out_dir.mkdir(parents=True, exist_ok=True)
    errs, seconds, start = [], 0.0, time.perf_counter()
    for clip in tqdm(clips, desc="CMU retarget", unit="clip"):
        motion, err, _ = fitted_clip(clip, out_dir)
        errs.append(err)
        seconds += motion.duration
        tqdm.write(f"  CMU {clip.clip} ({clip.description}): mean {err.mean() * 100:.2f} cm, "
                   f"p95 {np.percentile(err, 95) * 100:.2f} cm, {motion.duration:.0f} s")
    every = np.concatenate(errs) * 100
    worst = int(np.argmax([np.percentile(e, 95) for e in errs]))
    print(f"CMU retarget error on the mapped joints over {len(clips)} clips ({seconds / 60:.1f} min): "
          f"mean {every.mean():.2f} cm, p95 {np.percentile(every, 95):.2f} cm; worst clip {clips[worst].clip} "
          f"(p95 {np.percentile(errs[worst], 95) * 100:.2f} cm); {time.perf_counter() - start:.0f} s")


def _cmd_alignment(args: argparse.Namespace) -> int:
    print(report(alignment_table(args.data or default_data_dir())))
    return 0


def _cmd_show(args: argparse.Namespace) -> int:
    draw_fit(args.data or default_data_dir(), args.seq, args.frame, args.out)
    print(f"wrote {args.out}")
    return 0

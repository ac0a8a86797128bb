"""The library engine as its users dance it: the shipped CMU library and a folder of clips without labels, on
made-up songs of 60-200 BPM (`synth_songs.py`: 3/4 and 4/4, straight and swung), at the defaults
(`dancenet generate SONG --engine library [--library FOLDER]`). Prints JSON per library and song, and per library
over all its dances, the figures issue 45's "done when" asks for:

- `speed`: the dance's hands (wrists), feet and pelvis mean speed over the library clips' own (the same joints,
  every frame of every clip), both in body heights per second: 0.85-1.2 wanted;
- `floor`: the share of 2-s windows in which the body's lowest point (`floor.lowest_point`) comes within 5 cm
  of the floor (y = 0): 0.9 or more;
- `fastest`: the largest joint speed of the dance over that joint's 99.9th percentile in the clips: 1.5 at most;
- `bars_per_figure`: how long the dance stays with one clip between cuts, in the song's bars: 1 or more;
- `bas_own_over_other`: the dances' Beat Align Score against their own songs' beats over that against the other
  songs': 1.15 or more;
- `clips`, `effective_clips`: how many distinct clips a dance uses and how evenly (the exponential of the entropy
  of the seconds danced per clip: N for N clips danced equally long), and `clips_in_library`.

    OMP_NUM_THREADS=1 .venv/bin/python scripts/library_users_check.py [--folder FOLDER] [--takes 2]
        [--seconds 60] [--songs DIR] [--no-default] [--no-folder] [--returns anew] [--set NAME=VALUE ...] [--commercial]
        [--shipped FILE]

`--folder` is a folder of clips (built first as `dancenet library build` builds it); without it, the CMU BVH clips
of the data folder (`$DANCENET_DATA/cmu_dance`) laid flat in a temporary folder, so that no clip names a style:
a user's folder of downloads. `--set` changes a plan setting (`library.choreography.Settings`) for choosing them on
songs that are not the evaluation's. `--commercial` dances in the commercial mode (`DanceRequest.commercial`: the
weight-free music analysis, no learned match), on the folder only. `--shipped` dances another file in the shipped
library's place (a built library's .npz, given to the engine as `--library FILE`): the library a rebuild replaces,
measured in the same session as the rebuilt one.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
from pathlib import Path
from unittest import mock

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))

from synth_songs import DEFAULT_SPECS, SongSpec, write_song  # noqa: E402

from dancenet_core.environment import default_data_dir  # noqa: E402
from dancenet_core.evaluation.metrics import own_song_bas_ratio  # noqa: E402
from dancenet_core.kinematics import fk_numpy  # noqa: E402
from dancenet_core.library.choreography import clip_usage  # noqa: E402
from dancenet_core.motion import Motion  # noqa: E402
from dancenet_core.shaping.floor import lowest_point  # noqa: E402
from dancenet_core.skeleton import BODY_JOINTS, JOINT_INDEX  # noqa: E402

PARTS = {"hands": ["left_wrist", "right_wrist"], "feet": ["left_foot", "right_foot"], "pelvis": ["pelvis"]}
FLOOR_WINDOW_S, FLOOR_NEAR_M = 2.0, 0.05


def body_height(motion: Motion) -> float:
    """The rest pose's height (m), end sites included: the unit of the speeds."""
    skel = motion.skeleton
    rest = fk_numpy(skel, np.zeros((1, skel.num_joints, 3)), np.zeros((1, 3)), with_end_sites=True)
    return float(np.ptp(np.concatenate([rest[0][0], rest[2][0]])[:, 1]))


def part_speeds(motion: Motion) -> dict[str, np.ndarray]:
    """Per part, the speed of each of its joints at each frame step [T - 1, k] (body heights per second)."""
    pos = motion.positions()
    h = body_height(motion)
    return {p: np.linalg.norm(np.diff(pos[:, [JOINT_INDEX[n] for n in names]], axis=0), axis=-1) * motion.fps / h
            for p, names in PARTS.items()}


def clip_stats(library) -> dict:
    """The library clips' own mean part speeds and each body joint's 99.9th percentile speed (m/s)."""
    speeds: dict[str, list] = {p: [] for p in PARTS}
    joints = []
    for c in range(library.num_clips):
        clip = library.clip(c)
        for p, v in part_speeds(clip).items():
            speeds[p].append(v)
        joints.append(np.linalg.norm(np.diff(clip.positions()[:, :BODY_JOINTS], axis=0), axis=-1) * clip.fps)
    return {"mean": {p: float(np.concatenate(v).mean()) for p, v in speeds.items()},
            "p999": np.percentile(np.concatenate(joints), 99.9, axis=0)}


def floor_share(motion: Motion) -> float:
    """Share of 2-s windows whose lowest body point (`floor.lowest_point`) comes within 5 cm of y = 0."""
    low = lowest_point(motion)
    n = int(round(FLOOR_WINDOW_S * motion.fps))
    k = max(1, len(low) // n)
    windows = low[: k * n].reshape(k, -1) if len(low) >= n else low[None]
    return float(np.mean(np.abs(windows.min(axis=1)) <= FLOOR_NEAR_M))


def measure(result, stats: dict) -> list[dict]:
    """Each take of a `generate_dance` result, measured."""
    rows = []
    ibi = float(np.median(np.diff(result.beat_times)))
    downs = np.flatnonzero(np.isin(result.beat_times, result.downbeat_times))
    meter = int(np.median(np.diff(downs))) if len(downs) > 1 else 4
    for motion, detail in zip(result.motions, result.details, strict=True):
        speeds = part_speeds(motion)
        joint = np.linalg.norm(np.diff(motion.positions()[:, :BODY_JOINTS], axis=0), axis=-1) * motion.fps
        usage = clip_usage(detail["danced_figures"])
        rows.append({"speed": {p: round(float(v.mean()) / stats["mean"][p], 3) for p, v in speeds.items()},
                     "floor": round(floor_share(motion), 3),
                     "fastest": round(float((joint.max(axis=0) / stats["p999"]).max()), 3),
                     "bars_per_figure": round(motion.duration / (detail["cuts"] + 1) / (meter * ibi), 2),
                     "clips": usage["clips"], "effective_clips": usage["effective_clips"],
                     "max_warp": detail["max_warp"]})
    return rows


def songs(folder: Path | None, seconds: float, tmp: Path) -> list[Path]:
    if folder is not None:
        return sorted(p for p in folder.iterdir() if p.suffix.lower() in (".ogg", ".wav", ".mp3", ".flac"))
    out = []
    for spec in DEFAULT_SPECS:
        spec = SongSpec(spec.bpm, spec.meter, spec.swing, seconds, spec.seed)
        write_song(spec, tmp / f"{spec.name}.ogg")
        out.append(tmp / f"{spec.name}.ogg")
    return out


def users_folder(tmp: Path) -> Path:
    """The CMU BVH clips of the data folder, flat (no style folders): a user's folder of downloads."""
    folder = tmp / "clips"
    folder.mkdir()
    for f in sorted((default_data_dir() / "cmu_dance").rglob("*.bvh")):
        (folder / f.name).symlink_to(f)
    return folder


def check(name: str, library, folder: Path | None, song_files: list[Path], takes: int, seconds: float,
          settings, returns: str, commercial: bool = False) -> dict:
    from dancenet_core.generate import generate_dance
    from dancenet_core.library import engine
    from dancenet_core.request import DanceRequest

    stats = clip_stats(library)
    per_song, positions, beats = [], [], []
    choreograph = engine.choreograph
    with mock.patch.object(engine, "choreograph", lambda *a, **k: choreograph(*a, settings=settings, **k)):
        for song in song_files:
            result = generate_dance(DanceRequest(song=song, engine="library", library=folder, end_s=seconds,
                                                 takes=takes, returns=returns, commercial=commercial))
            rows = measure(result, stats)
            positions += [m.positions()[:, :BODY_JOINTS] for m in result.motions]
            beats += [result.beat_times] * len(result.motions)
            per_song.append({"song": song.name, "tempo_bpm": round(result.tempo_bpm, 1), "takes": rows})
            print(json.dumps({"library": name} | per_song[-1]), flush=True)
    rows = [r for s in per_song for r in s["takes"]]
    return {"library": name, "clips_in_library": library.num_clips,
            "speed_range": {p: [min(r["speed"][p] for r in rows), max(r["speed"][p] for r in rows)] for p in PARTS},
            "speed_mean": {p: round(float(np.mean([r["speed"][p] for r in rows])), 3) for p in PARTS},
            "floor_min": min(r["floor"] for r in rows), "fastest_max": max(r["fastest"] for r in rows),
            "bars_per_figure_mean": round(float(np.mean([r["bars_per_figure"] for r in rows])), 2),
            "bars_per_figure_min": min(r["bars_per_figure"] for r in rows),
            "clips_mean": round(float(np.mean([r["clips"] for r in rows])), 1),
            "effective_clips_mean": round(float(np.mean([r["effective_clips"] for r in rows])), 1),
            "effective_clips_min": min(r["effective_clips"] for r in rows),
            "bas_own_over_other": round(own_song_bas_ratio(positions, 25.0, beats), 3),
            "max_warp": max(r["max_warp"] for r in rows)}


def main() -> int:
    from dancenet_core.library.build import build_library
    from dancenet_core.library.choreography import DEFAULT_SETTINGS
    from dancenet_core.library.store import MotionLibrary, load_default

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folder", type=Path, default=None, help="a folder of clips (default: CMU's, flat)")
    parser.add_argument("--songs", type=Path, default=None, help="a folder of songs (default: made up)")
    parser.add_argument("--takes", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--no-default", action="store_true", help="leave out the shipped CMU library")
    parser.add_argument("--no-folder", action="store_true", help="leave out the folder of clips")
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE")
    parser.add_argument("--returns", default="repeat", help="returning sections: repeat (the default), mirror, anew")
    parser.add_argument("--commercial", action="store_true",
                        help="the commercial mode (weight-free analysis, no learned match; the folder only)")
    parser.add_argument("--shipped", type=Path, default=None,
                        help="a built library's .npz danced in the shipped library's place (default: the shipped one)")
    args = parser.parse_args()
    changed = {k: float(v) for k, v in (item.split("=", 1) for item in args.set)}
    settings = dataclasses.replace(DEFAULT_SETTINGS, **changed)
    summaries = []
    with tempfile.TemporaryDirectory() as t:
        tmp = Path(t)
        song_files = songs(args.songs, args.seconds, tmp)
        if not args.no_default and not args.commercial:  # the shipped library is not the commercial mode's
            shipped = load_default() if args.shipped is None else MotionLibrary.load(args.shipped)
            summaries.append(check(str(args.shipped or "shipped CMU"), shipped, args.shipped, song_files, args.takes,
                                   args.seconds, settings, args.returns))
        if not args.no_folder:
            folder = args.folder or users_folder(tmp)
            library, _ = build_library(folder, report=lambda _line: None)
            summaries.append(check(str(args.folder or "CMU clips, flat"), library, folder, song_files, args.takes,
                                   args.seconds, settings, args.returns, args.commercial))
    print(json.dumps({"settings": changed, "returns": args.returns, "commercial": args.commercial, "all": summaries},
                     indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

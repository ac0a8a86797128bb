"""`dancenet render MOTION [--audio SONG] -o preview.mp4`: a preview video, PNG stills or a contact sheet."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from tqdm import tqdm

from ..bvh import read_bvh
from ..errors import DanceNetError
from ..motion import Motion
from ..render import contact_sheet, render_motion, write_frames


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("motion", type=Path, help="a BVH file or a DanceNet motion .npz")
    p.add_argument("-o", "--out", type=Path, help="the MP4 video to write")
    p.add_argument("--audio", type=Path,
                   help="music to mux in (cut, or padded with silence, to the dance's length)")
    p.add_argument("--frames", type=Path, metavar="DIR", help="write every frame as a PNG into DIR")
    p.add_argument("--sheet", type=Path, metavar="PNG",
                   help="write a 4x3 contact sheet of evenly spaced, time-stamped frames (cells half size)")
    p.add_argument("--width", type=int, default=640, help="video width in pixels (default 640)")
    p.add_argument("--height", type=int, default=360, help="video height in pixels (default 360)")
    p.add_argument("--fps", type=float, default=None, help="frame rate (default: the motion's)")
    p.set_defaults(handler=run)


def load_motion(path: Path) -> Motion:
    """A motion from a BVH file or a `Motion.save` .npz; anything else is a one-line `DanceNetError`."""
    if not path.is_file():
        raise DanceNetError(f"motion file not found: {path}")
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        return read_bvh(path).to_motion()
    if suffix == ".npz":
        try:
            return Motion.load(path)
        except ValueError as e:
            raise DanceNetError(str(e).splitlines()[0]) from e
    raise DanceNetError(f"{path} is not a motion file: give a .bvh or a DanceNet .npz")


def run(args: argparse.Namespace) -> int:
    if args.out is None and args.frames is None and args.sheet is None:
        raise DanceNetError("nothing to write: give -o VIDEO.mp4, --frames DIR or --sheet SHEET.png")
    if args.audio is not None and args.out is None:
        raise DanceNetError("--audio goes into a video: add -o VIDEO.mp4")
    motion = load_motion(args.motion)
    if args.fps is not None:
        if not args.fps > 0:
            raise DanceNetError(f"--fps must be positive, got {args.fps:g}")
        motion = motion.resampled(args.fps)

    t0 = time.perf_counter()
    written = []
    if args.out is not None or args.frames is not None:
        bar = tqdm(total=motion.num_frames, unit="frame", desc="rendering", leave=False, delay=0.5)

        def progress(fraction: float) -> None:
            bar.update(round(fraction * motion.num_frames) - bar.n)

        try:
            if args.out is not None:
                written.append(render_motion(motion, args.out, audio=args.audio, width=args.width,
                                             height=args.height, progress=progress, frames_dir=args.frames))
            else:
                write_frames(motion, args.frames, args.width, args.height, progress=progress)
        finally:
            bar.close()
        if args.frames is not None:
            written.append(args.frames)
    if args.sheet is not None:
        written.append(contact_sheet(motion, args.sheet, width=max(args.width // 2, 16),
                                     height=max(args.height // 2, 16)))
    print(f"{motion.num_frames} frames at {motion.fps:g} fps in {time.perf_counter() - t0:.1f} s -> "
          + ", ".join(str(w) for w in written))
    return 0

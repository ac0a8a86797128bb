"""Still pictures of a dance: every frame as a PNG, or a contact sheet of evenly spaced frames."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from ..errors import DanceNetError
from ..motion import Motion
from ..progress import Progress
from .frames import iter_frames


def _save_png(image: np.ndarray, path: Path) -> None:
    from PIL import Image  # Pillow comes with the render extra

    with atomic_path(path) as tmp:  # a killed run never leaves half a PNG
        Image.fromarray(image).save(tmp, compress_level=1)


def _make_dir(folder: Path) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise DanceNetError(f"cannot create the folder {folder}: {e.strerror}") from e


def write_frames(
    motion: Motion, folder: str | Path, width: int = 640, height: int = 360, progress: Progress | None = None
) -> list[Path]:
    """Every frame as `frame_00000.png`, ... in `folder` (created if missing)."""
    folder = Path(folder)
    _make_dir(folder)
    paths = []
    for i, image in enumerate(iter_frames(motion, None, width, height)):
        paths.append(folder / f"frame_{i:05d}.png")
        _save_png(image, paths[-1])
        if progress:
            progress((i + 1) / motion.num_frames)
    return paths


def contact_sheet(
    motion: Motion | Sequence[tuple[str, Motion]], out: str | Path, cols: int = 4, rows: int = 3,
    width: int = 320, height: int = 180,
) -> Path:
    """A PNG grid of `cols` x `rows` evenly spaced frames, each `width` x `height`, with its time stamp.

    Given (caption, motion) pairs instead, each motion gets its own block of `rows` rows, one under the other,
    with its caption on every cell: the same moments of a real and a generated dance, compared by eye.
    """
    from PIL import Image, ImageDraw, ImageFont  # Pillow comes with the render extra

    if cols < 1 or rows < 1:
        raise DanceNetError(f"a contact sheet needs at least 1x1 cells, got {cols}x{rows}")
    out = Path(out)
    blocks = [("", motion)] if isinstance(motion, Motion) else list(motion)
    sheet = Image.new("RGB", (cols * width, len(blocks) * rows * height))
    draw = ImageDraw.Draw(sheet)
    font = ImageFont.load_default(size=max(10, height // 12))
    for b, (caption, m) in enumerate(blocks):
        frames = np.linspace(0, m.num_frames - 1, cols * rows).round().astype(int)
        for k, (f, image) in enumerate(zip(frames, iter_frames(m, frames, width, height), strict=True)):
            x, y = (k % cols) * width, (b * rows + k // cols) * height
            sheet.paste(Image.fromarray(image), (x, y))
            t = f / m.fps
            label = f"{caption}  {int(t // 60)}:{t % 60:05.2f}".strip() if caption else \
                f"{int(t // 60)}:{t % 60:05.2f}  #{f}"
            box = draw.textbbox((x + 6, y + 4), label, font=font)
            draw.rectangle((box[0] - 4, box[1] - 3, box[2] + 4, box[3] + 3), fill=(20, 20, 24))
            draw.text((x + 6, y + 4), label, fill=(255, 255, 255), font=font)
            draw.rectangle((x, y, x + width - 1, y + height - 1), outline=(60, 60, 66))
    if out.parent != Path():
        _make_dir(out.parent)
    try:
        with atomic_path(out) as tmp:
            sheet.save(tmp)
    except ValueError as e:
        raise DanceNetError(f"cannot write the contact sheet {out}: {e}") from e
    return out

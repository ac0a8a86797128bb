"""Reading the CMU dance clips: BVH files (motion only, no music) listed in the data folder's manifest."""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Clip:
    """One row of the CMU manifest; `clip` is the file name without `_poses.bvh` (e.g. 60_01)."""

    clip: str
    subject: str
    description: str
    bvh: Path


def cmu_dir(root: str | Path) -> Path | None:
    """The CMU folder under the data folder, or None when this copy of the data has none."""
    d = Path(root) / "cmu_dance"
    return d if (d / "manifest.csv").is_file() else None


def read_cmu_manifest(root: str | Path) -> list[Clip]:
    d = cmu_dir(root)
    if d is None:
        return []
    with open(d / "manifest.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return [Clip(Path(r["file"]).name.removesuffix("_poses.bvh").removesuffix(".bvh"), r["subject"],
                 r["description"], d / r["file"]) for r in rows]

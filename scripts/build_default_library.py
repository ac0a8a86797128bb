"""Build the motion library that ships (dancenet_core/weights/cmu_dance_library.npz, the `library` engine's default)
from the CMU dance clips in $DANCENET_DATA/cmu_dance: python scripts/build_default_library.py

Run by hand when the clips or what a library build computes (store.LIBRARY_VERSION) change; never at run time.
Only the built arrays ship (float16 rotations, compressed), not the BVH files. Each clip's style is what CMU's index
says its subject dances; 05_01 is a walk and is left out. The clips are linked, not copied, into a temporary
folder named by style, which is what `dancenet library build` reads styles from.
"""

from __future__ import annotations

import csv
import sys
import tempfile
import time
from pathlib import Path

from dancenet_core.environment import default_data_dir
from dancenet_core.library.build import build_library
from dancenet_core.library.store import DEFAULT_LIBRARY

# CMU subject -> the dance its trials hold (the CMU index; data/README.md's cmu_dance table).
SUBJECT_STYLES = {"05": "modern", "55": "latin", "60": "salsa", "61": "salsa", "93": "swing", "94": "indian"}
LEFT_OUT = {"05/05_01_poses.bvh"}  # a walk


def main() -> int:
    source = default_data_dir() / "cmu_dance"
    with open(source / "manifest.csv", newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["file"] not in LEFT_OUT]
    t = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for row in rows:
            link = Path(tmp) / SUBJECT_STYLES[row["subject"]] / Path(row["file"]).name
            link.parent.mkdir(exist_ok=True)
            link.symlink_to(source / row["file"])
        library, _cached = build_library(tmp, force=True)
    library.names = [n.split("/", 1)[-1] for n in library.names]  # the CMU file names, without the style folder
    library.save(DEFAULT_LIBRARY, compact=True)
    print(f"{library.num_clips} clips, {library.duration_s / 60:.1f} min, {len(library.notes)} left out "
          f"({'; '.join(library.notes) or 'none'}), {time.perf_counter() - t:.0f} s -> {DEFAULT_LIBRARY} "
          f"({DEFAULT_LIBRARY.stat().st_size / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

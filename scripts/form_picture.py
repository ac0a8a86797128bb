"""The README's picture of a song's form and the dance's: a song arranged A B A C A B from 8-bar sections of
three training waltzes (`evaluation.form.arranged_song`), danced by `dancenet generate --form-plot` at its
defaults (returns repeated), the figure copied to docs/form.png.

    python scripts/form_picture.py [--data ../shared/data] [--engine dancenet|library]
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from dancenet_core.evaluation.form import arranged_song  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    parser.add_argument("--engine", default="dancenet")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "form.png")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        song = arranged_song(args.data, Path(tmp) / "abacab.wav")
        if song is None:
            print(f"the Dance with Melody songs are not in {args.data}: give --data", file=sys.stderr)
            return 1
        subprocess.run([sys.executable, "-m", "dancenet_core.cli", "generate", str(song), "-o", f"{tmp}/out",
                        "--engine", args.engine, "--seed", "1", "--form-plot"], check=True, cwd=ROOT)
        shutil.copyfile(f"{tmp}/out/abacab_form.png", args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

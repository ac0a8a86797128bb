"""The time to dance a 3-minute song once analysed, at another revision and at this checkout, in the same run:
`generate_dance` at its defaults with each engine (DanceNet and the motion library with its bundled library), the
song's analysis cached, each revision in a process of its own (a `git worktree` of REV), the two run in turn
`--rounds` times. Prints JSON: per engine the best seconds of each revision (best of 3 dances per round, seeds 0-2,
after one dance that fills the caches), and this checkout's over REV's.

    .venv/bin/python bench/revision.py REV [--rounds 2]

The song is bench/end_to_end.py's (the first 180 s of DANCE_W_1, else a synthetic song). Only `DanceRequest` and
`generate_dance` are asked of REV.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
ENGINES = ("dancenet", "library")


@contextmanager
def worktree(rev: str) -> Iterator[tuple[str, Path]]:
    """(REV's commit, a detached `git worktree` of it in a temporary folder), removed afterwards whatever happens; a
    revision this repository lacks is a one-line error."""
    commit = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--verify", "--quiet", f"{rev}^{{commit}}"],
                            capture_output=True, text=True).stdout.strip()
    if not commit:
        raise SystemExit(f"no revision {rev!r} in {REPO}; give a commit, tag or branch of this repository")
    with tempfile.TemporaryDirectory(prefix="dancenet-revision-") as tmp:
        tree = Path(tmp) / "rev"
        subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", "--quiet", str(tree), commit],
                       check=True)
        try:
            yield commit, tree
        finally:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(tree)], check=True)


def timed(song: Path) -> dict[str, float]:
    """The timing side, run with PYTHONPATH at a revision: each engine's best of 3 dances, after a first one."""
    from dancenet_core.generate import generate_dance
    from dancenet_core.request import DanceRequest

    best = {}
    for engine in ENGINES:
        generate_dance(DanceRequest(song, engine=engine))
        seconds = []
        for seed in range(3):
            t = time.perf_counter()
            generate_dance(DanceRequest(song, engine=engine, seed=seed))
            seconds.append(time.perf_counter() - t)
        best[engine] = min(seconds)
    return best


def main() -> int:
    sys.path.insert(0, str(REPO / "bench"))
    from end_to_end import three_minute_song

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("rev", help="the revision to time beside this checkout")
    p.add_argument("--rounds", type=int, default=2)
    args = p.parse_args()
    with worktree(args.rev) as (commit, tree), tempfile.TemporaryDirectory(prefix="dancenet-revision-") as tmp:
        d = Path(tmp)
        song, kind = three_minute_song(d)
        runs: dict[str, list[dict[str, float]]] = {"rev": [], "this": []}
        for _ in range(args.rounds):
            for name, root in (("rev", tree), ("this", REPO)):
                env = os.environ | {"PYTHONPATH": str(root), "DANCENET_CACHE": str(d / f"cache_{name}")}
                out = subprocess.run([sys.executable, __file__, "--time", str(song)], env=env, cwd=root,
                                     check=True, capture_output=True, text=True).stdout
                runs[name].append(json.loads(out.splitlines()[-1]))
    result: dict = {"rev": args.rev, "commit": commit, "song": kind}
    for engine in ENGINES:
        rev, this = (min(r[engine] for r in runs[name]) for name in ("rev", "this"))
        result[engine] = {"rev_s": round(rev, 3), "this_s": round(this, 3), "this_over_rev": round(this / rev, 2)}
    result["load_average"] = [round(x, 2) for x in os.getloadavg()]
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    if sys.argv[1:2] == ["--time"]:
        print(json.dumps(timed(Path(sys.argv[2]))))
    else:
        sys.exit(main())

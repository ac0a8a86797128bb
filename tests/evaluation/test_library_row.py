"""`dancenet evaluate --library` on the users' path: the training dances written as BVH files without music and built
as `dancenet library build` builds a user's folder, danced to a test song within the real-time warp limit, and the
clip analysis scored against the songs' beats (on the real capture; skipped without it)."""

from __future__ import annotations

from pathlib import Path

import pytest

from dancenet_core.data.build import build_dataset
from dancenet_core.data.split import load_split
from dancenet_core.evaluation.library_row import clip_analysis, library_note, library_row, users_library
from dancenet_core.library.choreography import WARP_RANGE
from dancenet_core.skeleton import DEFAULT_SKELETON


@pytest.mark.data  # builds the whole training dataset: every capture sequence fitted
def test_the_users_path_row(shared_data: Path) -> None:
    split = load_split()
    pairs = {p.seq: p for p in build_dataset(shared_data, progress=False)}
    train = [pairs[s] for s in split["train"] if pairs[s].style == "waltz"][:2]
    test = [pairs[s] for s in split["test"] if pairs[s].style == "waltz"][:1]
    library = users_library(train, DEFAULT_SKELETON, 25.0)
    assert library.names == [f"waltz/{p.seq}.bvh" for p in train]
    assert library.meter.tolist() == [3, 3] and set(library.source) == {"tempo: motion, meter: style (waltz)"}
    dances, styles, beats, info = library_row(library, test, shared_data, 25.0, 1)
    assert len(dances) == 1 and styles == ["waltz"] and len(beats[0]) > 10
    assert abs(dances[0].duration - len(test[0].motion) / 25.0) < 0.1
    assert info["max_warp"] <= WARP_RANGE + 1e-6 and info["cuts"] >= 1
    analysis = clip_analysis(train + test, shared_data, DEFAULT_SKELETON, 25.0, {test[0].seq})
    assert analysis["clips"] == 3 and analysis["test_clips"] == 1
    assert all(r["song_meter"] == 3 and r["with_style"]["meter_right"] for r in analysis["per_clip"])
    note = library_note({"library": info | {"clip_analysis": analysis}})
    assert "users' path" in note and "with the style's meter: meter 100%" in note

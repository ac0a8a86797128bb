"""The figure list of a library take (shaping/figures.py) on made-up plans: one entry per figure danced, a
returning section's copy listed as the figures it repeats."""

from __future__ import annotations

import numpy as np
import pytest

from dancenet_core.shaping.figures import danced_figures, spliced
from tests.form.test_form import assert_whole_figures


def plan(bars: list[tuple[str, float]], bar_s: float = 2.0, start_s: float = 0.0) -> list[dict]:
    """Rows of a plan (a bar each) from (clip, clip second) pairs: a bar whose clip second is None carries on
    the bar before."""
    rows, clip_at = [], 0.0
    for k, (clip, at) in enumerate(bars):
        clip_at = clip_at if at is None else at
        rows.append({"clip": clip, "clip_s": [clip_at, clip_at + bar_s], "song_s": [start_s + k * bar_s,
                     start_s + (k + 1) * bar_s], "ratio": 1.0})
        clip_at += bar_s
    return rows


def test_runs_of_one_clip_are_one_figure_and_a_copy_names_the_span_it_repeats():
    # A (bars 0-3) B (4-5) A (6-9), the second A a mirrored copy of the first.
    rows = plan([("a", 0.0), ("a", None), ("b", 5.0), ("b", None), ("c", 1.0), ("c", None), ("d", 0.0), ("d", None),
                 ("e", 3.0), ("e", None)])
    edges = np.arange(11) * 2.0
    figures = danced_figures(rows, [(edges[6:11] + 0.02, edges[0:5] - 0.01, True)], 20.0, 30.0)
    assert [(f["clip"], f["song_s"], f.get("repeats")) for f in figures] == [
        ("a", [0.0, 4.0], None), ("b", [4.0, 8.0], None), ("c", [8.0, 12.0], None),
        ("a", [12.0, 16.0], {"song_span": [0.0, 4.0], "mirrored": True}),
        ("b", [16.0, 20.0], {"song_span": [4.0, 8.0], "mirrored": True})]
    assert figures[3]["clip_s"] == [0.0, 4.0] and figures[4]["clip_s"] == [5.0, 9.0]
    assert_whole_figures(figures, 0.5)


def test_a_copy_of_a_copy_points_at_the_copy_and_the_dances_end_cuts_the_last():
    rows = plan([("a", 0.0), ("b", 7.0), ("c", 0.0), ("d", 0.0), ("e", 0.0), ("f", 0.0)], start_s=1.0)
    edges = 1.0 + np.arange(7) * 2.0
    copies = [(edges[2:5], edges[0:3], False), (edges[4:7], edges[2:5], False)]
    figures = danced_figures(rows, copies, 12.0, 30.0)  # the copy of bars 2-3 runs past the dance's end
    assert [(f["clip"], f["song_s"], f.get("repeats", {}).get("song_span")) for f in figures] == [
        ("a", [1.0, 3.0], None), ("b", [3.0, 5.0], None), ("a", [5.0, 7.0], [1.0, 3.0]),
        ("b", [7.0, 9.0], [3.0, 5.0]), ("a", [9.0, 11.0], [5.0, 7.0]), ("b", [11.0, 12.0], [7.0, 8.0])]
    assert figures[-1]["clip_s"] == [7.0, 8.0]
    assert_whole_figures(figures, 0.5)


def test_a_bar_begun_before_the_part_counts_with_the_next_and_a_section_danced_anew_replaces_its_rows():
    rows = [{"clip": "x", "clip_s": [3.0, 5.0], "song_s": [0.0, 0.04], "ratio": 1.0}, *plan([("a", 0.0)], start_s=0.04)]
    assert [(f["clip"], f["song_s"]) for f in danced_figures(rows, [], 2.04, 30.0)] == [("a", [0.0, 2.04])]
    new = plan([("n", 10.0), ("n", None)], start_s=1.0)
    out = spliced(plan([("a", 0.0), ("b", 0.0), ("c", 0.0)]), new, 1.0, 4.0)
    assert [(r["clip"], r["song_s"], r["clip_s"]) for r in out] == [
        ("a", [0.0, 1.0], [0.0, 1.0]), ("n", [1.0, 3.0], [10.0, 12.0]), ("n", [3.0, 4.0], [12.0, 13.0]),
        ("c", [4.0, 6.0], [0.0, 2.0])]
    with pytest.raises(AssertionError):  # the check catches a copy pointing where nothing was danced
        assert_whole_figures([{"clip": "a", "clip_s": [0, 2], "song_s": [0, 2], "warp": 1.0},
                              {"clip": "a", "clip_s": [0, 2], "song_s": [2, 4], "warp": 1.0,
                               "repeats": {"song_span": [5, 7], "mirrored": False}}], 0.5)

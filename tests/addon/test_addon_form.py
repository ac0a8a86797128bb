"""The song's sections on the timeline: A1, B1, A2, ... named on their first bars (the generator a stand-in that
reports a form, as generate_dance does)."""

from __future__ import annotations

import numpy as np
from doubles import make_fake_generator
from scene_helpers import generate

from dancenet_core.music.form import Phrase, Section, SongForm

FORM = SongForm(np.array([0.0, 0.5, 1.0, 1.5, 2.0]), (Phrase(0, None, 1.0), Phrase(2, 0, 0.9)),
                (Section("A", 1, 0.0, 1.0, 0, 2, 1.0), Section("A", 2, 1.0, 2.0, 2, 2, 0.9)))


def test_sections_are_named_on_the_timeline_and_replaced_by_the_next_generate(scene, addon, song, monkeypatch):
    fake = make_fake_generator()

    def with_form(request, progress=None, should_cancel=None):
        result = fake(request, progress, should_cancel)
        result.form = FORM
        return result

    monkeypatch.setattr(addon.pipeline, "load_generator", lambda: with_form)
    scene.timeline_markers.new("A2", frame=40)  # the user's, named like ours
    assert generate(scene, song, seed=1) == {"FINISHED"}
    assert generate(scene, song, seed=2) == {"FINISHED"}
    # The first section on bar 1 (named for it), the return at 1.0 s (frame 25 at 24 fps, between downbeats).
    assert sorted((m.name, m.frame) for m in scene.timeline_markers) == sorted(
        [("A1", 1), ("·", 13), ("·", 25), ("A2", 25), ("·", 37), ("A2", 40)])

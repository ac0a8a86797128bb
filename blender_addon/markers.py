"""The section, bar and beat markers a generation puts on the timeline; only those the add-on made are ever
replaced. A section of the song's form (A1, B1, A2, ...: `music.form`) is named on its first bar instead of the
bar's number, so the sections that return can be seen at a glance."""

from __future__ import annotations

import json
from typing import Any

import bpy

from .takes import stored_json

# Markers this add-on owns (replaced on each generation); anything else on the timeline is left alone.
BEAT_MARKER = "·"
# The (name, frame) pairs of the timeline markers the add-on made, as JSON on the scene: only those are
# replaced by the next Generate, never a user's marker that happens to be called "bar 2".
MARKERS_PROP = "dancenet_markers"


def set_markers(scene: bpy.types.Scene, result: Any, frame_start: int, fps: float) -> None:
    stored = stored_json(scene.get(MARKERS_PROP, "[]"), list) or []
    ours = {(m[0], m[1]) for m in stored if isinstance(m, list) and len(m) == 2 and isinstance(m[0], str)
            and isinstance(m[1], int)}
    for marker in [m for m in scene.timeline_markers if (m.name, m.frame) in ours]:
        scene.timeline_markers.remove(marker)
    downbeats = {round(float(t) * fps) for t in result.downbeat_times}
    form = getattr(result, "form", None)
    sections = {} if form is None else {
        round((s.start_s - result.start_s) * fps): s.name for s in form.sections
        if 0 <= s.start_s - result.start_s < result.duration_s}
    made = [(sections.pop(t, f"bar {i}"), frame_start + t) for i, t in enumerate(sorted(downbeats), start=1)]
    made += [(name, frame_start + t) for t, name in sorted(sections.items())]  # a section off the downbeats
    beats = {round(float(t) * fps) for t in result.beat_times} - downbeats
    made += [(BEAT_MARKER, frame_start + t) for t in sorted(beats)]
    for name, frame in made:
        scene.timeline_markers.new(name, frame=frame)
    scene[MARKERS_PROP] = json.dumps(made)

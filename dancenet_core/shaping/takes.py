"""The takes as danced turned into the dance that is written or keyed: the song's returning sections danced
again (`repeats.py`) with the foot contacts and the figure list following, then the frame rate, a continued dance's
kept frames and the root motion (`shape_takes`, the one output path of the command line and the add-on)."""

from __future__ import annotations

import numpy as np

from ..motion import Motion
from ..music.form import SongForm
from ..request import DanceRequest
from .continuation import keep_original
from .figures import danced_figures
from .repeats import copies_danced, dance_returns
from .rootmotion import apply_mode


def with_repeats(motion: Motion, contacts: np.ndarray | None, figures: list[dict] | None, form: SongForm,
                 start_s: float, request: DanceRequest) -> tuple[Motion, np.ndarray | None, list[dict] | None]:
    """A take (danced from `start_s` seconds into the song) with the song's returning sections danced as
    `request.returns` says, or as a section's own settings say (`repeats.dance_returns`; a section danced with a
    style or energy of its own is left as it is), its foot contacts [T, 2] following the frames and a library
    take's figures (the plan's rows) listed as danced (`figures.danced_figures`); None stays None."""
    keep = request.at_s if request.continue_from is not None else 0.0
    modes = {o.section: "anew" if o.redances else o.returns for o in request.sections if o.redances or o.returns}
    out, frame_map = dance_returns(motion, form, start_s, request.returns, keep, modes)
    if figures is not None:
        bars = form.bar_starts
        copies = [(bars[a:b + 1], bars[s:s + b - a + 1], how == "mirror")
                  for a, b, s, how in copies_danced(form, start_s, motion.fps, motion.num_frames, request.returns,
                                                    keep, modes)]
        figures = danced_figures(figures, copies, start_s + motion.duration, motion.fps)
    if contacts is not None:
        contacts = contacts[np.round(frame_map).astype(int)]
    return out, contacts, figures


def shape_takes(motions: list[Motion], request: DanceRequest) -> list[Motion]:
    """The takes as they are written or keyed: at `request.fps` (slerp-resampled; None keeps the engine's
    rate, or a continued dance's own), a continued dance's kept frames exactly as they were (at its rate, not
    resampled ones), and the root motion applied (in place; a root bone is a layout of the dance as danced,
    made by the BVH writer or the add-on)."""
    kept = request.continue_from
    if kept is None:
        return [shape_take(m, request.fps, request.root_motion) for m in motions]
    join = round(request.at_s * motions[0].fps) / motions[0].fps  # on the engine's frame grid
    kept = kept.resampled(request.fps or kept.fps)
    return [shape_take(keep_original(kept, m, join), None, request.root_motion) for m in motions]


def shape_take(motion: Motion, fps: float | None, root_motion: str) -> Motion:
    """One take at `fps` (None: at its own rate) with its root motion applied (see `shape_takes`)."""
    return apply_mode(motion if fps is None else motion.resampled(fps), root_motion)

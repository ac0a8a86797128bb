"""The request's settings as the panel holds them: read from the panel's properties or from a take's record.
Below both the pipeline and the library fold (each reads them), so neither imports the other for them."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import bpy

from dancenet_core.request import panel_options

from .preferences import commercial_only

AS_DANCE = "same"  # a section setting that follows the dance's


def panel_settings(source: Any) -> dict[str, Any]:
    """The request's panel settings (`request.panel_options`) read from the panel's properties, or from a take's
    record (a dict): what a new setting needs to reach a dance, the record and a continued take. Commercial Use,
    whatever they say, where the add-on's preference asks for it (`preferences.commercial_only`): Generate Dance,
    Continue From Here and Dance Section Anew read their settings here (batch mode has its own, `batch.py`)."""
    read = source.get if isinstance(source, dict) else lambda name, default: getattr(source, name, default)
    values = {name: read(name, default) for name, default, _o in panel_options()}
    for name, _default, o in panel_options():  # a folder setting: "" is none, "//" is beside the .blend
        if o.kind is Path:
            values[name] = Path(bpy.path.abspath(str(values[name]))) if values[name] else None
    values["commercial"] = bool(values["commercial"]) or commercial_only()
    return values

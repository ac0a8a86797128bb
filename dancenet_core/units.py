"""Which unit makes a skeleton a dancer's size: the units a dance's or a rig's lengths may come in, and the guess
among them by the skeleton's size against a dancer's. A dance's BVH (`shaping/rootmotion.py`), a rig's rest pose
(`jointmap.rest_unit`: BVH clips and rigs sampled in Blender) and an FBX rig as Blender imports it
(`library/fbx.py`) each guess here among the units that can happen to them, and refuse a size in their own words.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

# Metres per unit of the units a file is written in (ours and Blender's exporter write metres; other tools
# centimetres, millimetres or inches): all a BVH can be in, as it carries no scale of its own.
FILE_UNITS: dict[str, float] = {"metres": 1.0, "centimetres": 0.01, "millimetres": 0.001, "inches": 0.0254}
FILE_UNIT_NAMES = ", ".join(FILE_UNITS)  # for the lines that refuse a size
# A rig's rest pose: a file's unit, or a centimetre FBX rig whose 0.01 scale was applied twice (applied not at all,
# it reads as centimetres).
RIG_UNITS: tuple[float, ...] = (*FILE_UNITS.values(), 100.0)
# An FBX rig as Blender imports it, the file's unit and its nodes' scales applied over one another: any power of
# ten from 1e-4 to 1e4, or the inch.
SAMPLED_UNITS: tuple[float, ...] = (*(10.0**k for k in range(-4, 5)), FILE_UNITS["inches"])
DANCER_M = (0.5, 2.5)  # how tall a dancer's rest pose is, in metres
DANCER_HEIGHT_M = 1.7  # the height a rig in no known unit is read nearest to


def dancer_unit(size: float, dancer: float, units: Iterable[float]) -> float:
    """The metres per unit, of `units`, that makes a skeleton `size` units big nearest a dancer `dancer` metres big
    (both measured alike), so that a file in any of them reads as a dancer; the first of `units` for a skeleton of
    no size. Whether the size it gives is a dancer's is each caller's to say, in its own words."""
    if not size > 0:
        return next(iter(units))
    return min(units, key=lambda m: abs(np.log(size * m / dancer)))

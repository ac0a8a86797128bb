"""The add-on's preferences (Preferences > Add-ons > DanceNet): Commercial Use only, for a studio that wants no
part with a non-commercial licence opened in its Blender at all (docs/licence.md).

The scene's Commercial Use switch makes a Generate Dance open none of those parts, but the warm-up that runs when
the add-on is enabled loads DanceNet's weights and madmom's networks whatever a scene says. With this preference
on, the warm-up leaves them out (`dancenet_core.warmup.warm_up`, commercial), and every dance the add-on makes,
Generate Dance, Continue From Here, a section danced anew and batch mode's, is made in Commercial Use.
"""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty


class DanceNetPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    commercial_only: BoolProperty(
        name="Commercial Use only", default=False,
        description="Open no part whose licence is non-commercial or unknown (DanceNet's weights, the style "
                    "classifier, madmom's networks, the shipped library): every dance is made in Commercial Use, "
                    "and the warm-up at start-up loads none of them")

    def draw(self, _context: bpy.types.Context) -> None:
        col = self.layout.column()
        col.prop(self, "commercial_only")
        col.label(text="Every dance then uses the Motion Library engine on clips of your own", icon="INFO")
        col.label(text="Turned on while Blender runs: restart Blender, as the warm-up at start-up may have loaded "
                       "those parts already")


def addon_preferences() -> DanceNetPreferences | None:
    """This add-on's preferences, or None where it has no entry in the preferences (a script registered it: tests,
    bpy as a module). Batch mode loads the add-on's package under its folder's name (`dancenet` for the extension,
    which Blender enabled as `bl_ext.<repository>.dancenet`): the enabled extension's entry is this package's then.
    Main thread only: it reads bpy."""
    addons = bpy.context.preferences.addons
    entry = addons.get(__package__)
    if entry is None:
        entry = next((a for a in addons if a.module.rpartition(".")[2] == __package__), None)
    return entry.preferences if entry is not None else None


def commercial_only() -> bool:
    """Whether Commercial Use only is on (off where the add-on has no preferences)."""
    return bool(getattr(addon_preferences(), "commercial_only", False))


def commercial(props: bpy.types.PropertyGroup) -> bool:
    """Whether a scene's dances are made in Commercial Use: its switch, or the preference for every scene."""
    return bool(props.commercial) or commercial_only()


CLASSES = (DanceNetPreferences,)

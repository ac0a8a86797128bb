"""Add-on preferences: the dependency status and the Install Dependencies button."""

from __future__ import annotations

import bpy

from . import deps


class DanceNetPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__  # "bl_ext.<repo>.dancenet" as an extension, the module name as a legacy add-on

    def draw(self, context: bpy.types.Context) -> None:
        layout = self.layout
        missing = deps.missing()
        if missing:
            layout.label(text=f"Missing Python packages: {', '.join(missing)}", icon="ERROR")
            layout.label(text="About 300 MB (torch CPU build and friends), pinned versions, from PyPI:")
            layout.operator("dancenet.install_dependencies", icon="IMPORT")
            if context.window_manager.dancenet.installing:
                layout.label(text="Installing… see the status bar", icon="SORTTIME")
        else:
            layout.label(text="All dependencies are installed", icon="CHECKMARK")
        layout.label(text=f"Install folder: {deps.site_dir()}")


CLASSES = (DanceNetPreferences,)

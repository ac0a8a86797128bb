"""DanceNet for Blender: pick a song, click Generate Dance, a character dances to it.

Works as a Blender 4.2+ extension (blender_manifest.toml; the core bundled under vendor/) and as a
legacy add-on module on sys.path next to an installed `dancenet_core` (the source checkout, tests).
The add-on is thin: generation, skeleton and kinematics live in `dancenet_core`, which never imports bpy.
"""

from . import deps

deps.activate()  # before the modules below import dancenet_core

import bpy  # noqa: E402

from . import menus, operators, panels, preferences, properties  # noqa: E402

bl_info = {  # read by Blender only when installed as a legacy add-on
    "name": "DanceNet",
    "author": "DanceNet contributors",
    "version": (0, 1, 0),
    "blender": (4, 2, 0),
    "location": "3D Viewport and Sequencer > Sidebar > DanceNet",
    "description": "Music-driven dance generation for any armature",
    "category": "Animation",
}

_CLASSES = (*properties.CLASSES, *preferences.CLASSES, *operators.CLASSES, *panels.CLASSES, *menus.CLASSES)


def register() -> None:
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    properties.register()
    menus.register()


def unregister() -> None:
    menus.unregister()
    properties.unregister()
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)

"""DanceNet for Blender: pick a song, click Generate Dance, a character dances to it.

Works as a Blender 4.2+ extension (blender_manifest.toml; build_addon.py bundles the core and its dependencies
as wheels, which Blender installs with the extension) and as a legacy add-on module next to an installed
`dancenet_core` (the source checkout, tests). The add-on is thin: generation, skeleton and kinematics live in
`dancenet_core`, which never imports bpy.
"""

import atexit
import os

import bpy


def _use_extension_cache() -> None:
    """Keep the music cache and numba's compiled code in the extension's user folder, which Blender keeps across
    updates and removes with the extension (a user's own $DANCENET_CACHE wins). Before the core is imported:
    it derives numba's cache folder from this one at import."""
    if (__package__ or "").startswith("bl_ext."):
        os.environ.setdefault("DANCENET_CACHE", bpy.utils.extension_path_user(__package__, path="cache", create=True))


_use_extension_cache()

from . import menus, operators, panels, preferences, properties, warming  # noqa: E402

bl_info = {  # read by Blender only when installed as a legacy add-on
    "name": "DanceNet",
    "author": "DanceNet contributors",
    "version": (0, 1, 0),
    "blender": (4, 2, 0),
    "location": "3D Viewport and Sequencer > Sidebar > DanceNet",
    "description": "Music-driven dance generation for any armature",
    "category": "Animation",
}

_CLASSES = (*preferences.CLASSES, *properties.CLASSES, *operators.CLASSES, *panels.CLASSES, *menus.CLASSES)


def _unregister_at_exit() -> None:
    """Blender disables the add-ons its preferences list when it quits, not one a script registered itself, and
    bpy 4.5 as a Python module never ends a process that exits with an operator or a panel class registered."""
    if __package__ not in bpy.context.preferences.addons:
        unregister()


def register() -> None:
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    properties.register()
    menus.register()
    warming.start(commercial=preferences.commercial_only())  # read here: the warm-up's thread never touches bpy
    atexit.register(_unregister_at_exit)  # runs before bpy's own exit, registered when bpy was imported


def unregister() -> None:
    atexit.unregister(_unregister_at_exit)
    warming.stop()
    menus.unregister()
    properties.unregister()
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)

"""DanceNet for Blender: pick a song, click Generate Dance, a character dances to it.

Works as a Blender 4.2+ extension (blender_manifest.toml; build_addon.py bundles the core and its dependencies
as wheels, which Blender installs with the extension) and as a legacy add-on module next to an installed
`dancenet_core` (the source checkout, tests). The add-on is thin: generation, skeleton and kinematics live in
`dancenet_core`, which never imports bpy.
"""

import os
import threading

import bpy


def _use_extension_cache() -> None:
    """Keep the music cache and numba's compiled code in the extension's user folder, which Blender keeps across
    updates and removes with the extension (a user's own $DANCENET_CACHE wins). Before the core is imported:
    it derives numba's cache folder from this one at import."""
    if (__package__ or "").startswith("bl_ext."):
        os.environ.setdefault("DANCENET_CACHE", bpy.utils.extension_path_user(__package__, path="cache", create=True))


_use_extension_cache()

from . import menus, operators, panels, properties  # noqa: E402

bl_info = {  # read by Blender only when installed as a legacy add-on
    "name": "DanceNet",
    "author": "DanceNet contributors",
    "version": (0, 1, 0),
    "blender": (4, 2, 0),
    "location": "3D Viewport and Sequencer > Sidebar > DanceNet",
    "description": "Music-driven dance generation for any armature",
    "category": "Animation",
}

_CLASSES = (*properties.CLASSES, *operators.CLASSES, *panels.CLASSES, *menus.CLASSES)
_warm_up_stop = threading.Event()  # this registration's; unregister sets it, register makes a new one


def _warm_up(stop: threading.Event) -> None:
    """The first Generate Dance's imports and numba compiles, done now rather than on the first click (17-30 s
    from cold, issue 27). It never touches bpy, so disabling the add-on meanwhile only stops it early. Not a
    daemon thread: one frozen mid-import or mid-compile when Python shuts down can hang the shutdown, so Python
    waits for it instead; Blender disables its add-ons when it quits, so that wait is one step at most."""
    try:
        from dancenet_core.warmup import warm_up

        warm_up(stop.is_set)
    except Exception as e:  # a failed warm-up costs only speed; a Generate Dance reports the fault itself
        print(f"DanceNet: warm-up stopped: {e}")


def register() -> None:
    global _warm_up_stop
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    properties.register()
    menus.register()
    _warm_up_stop = threading.Event()
    threading.Thread(target=_warm_up, args=(_warm_up_stop,), name="dancenet-warm-up").start()


def unregister() -> None:
    _warm_up_stop.set()
    menus.unregister()
    properties.unregister()
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)

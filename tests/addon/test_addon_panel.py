"""Issue 27 item 6: a panel that reads like Blender's (fake generator): sub-panels in both sidebars."""

from __future__ import annotations

import pytest
from scene_helpers import bpy, generate, panel_screenshot

FOLDS = ["Music", "Dance", "Rig", "Takes", "Export"]


def sub_panels(root) -> dict:
    """The recorded sub-panels of a recorded panel, by title."""
    return {child.title: child for child in root.children if getattr(child, "kind", "") == "panel"}


@pytest.mark.parametrize("sidebar", [0, 1], ids=["view3d", "sequencer"])
def test_sub_panels_register_under_the_main_panel_and_draw(scene, addon, song, sidebar):
    shot = panel_screenshot()
    main = addon.panels.MAIN_PANELS[sidebar]
    subs = addon.panels.SUB_PANELS[main.bl_idname]
    assert [s.bl_label for s in subs] == FOLDS
    for sub in subs:
        assert getattr(bpy.types, sub.bl_idname) is sub  # registered
        assert (sub.bl_parent_id, sub.bl_space_type) == (main.bl_idname, main.bl_space_type)
    assert "DEFAULT_CLOSED" in subs[FOLDS.index("Export")].bl_options

    before = sub_panels(shot.record_panel(bpy.context, main))
    assert list(before) == ["Music", "Dance", "Rig"]  # no take and nothing to export yet: those stay hidden
    assert generate(scene, song) == {"FINISHED"}
    root = shot.record_panel(bpy.context, main)
    folds = sub_panels(root)
    assert list(folds) == FOLDS
    assert [f.closed for f in folds.values()] == [False, False, False, False, True]
    own = [child for child in root.children if getattr(child, "kind", "") != "panel"]
    assert "Generate Dance" in {w.text for child in own for w in shot.walk(child)}  # the main panel's, on top
    assert "Seed" in {w.text for w in shot.walk(folds["Dance"])}
    assert "Existing Armature" in {w.text for w in shot.walk(folds["Rig"])}
    assert {"Export FBX", "Export BVH"} <= {w.text for w in shot.walk(folds["Export"])}
    image = shot.paint(root)
    assert image.height > 10 * shot.UNIT

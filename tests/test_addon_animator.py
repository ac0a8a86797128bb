"""Issue 18 in the add-on (fake generator for the wiring; the shipped model in the marked tests): frame
rates, a part of the song, root motion, continue from here, takes on the NLA, menus and presets."""

from __future__ import annotations

import pytest
from test_addon import addon, bpy, scene, song  # noqa: F401 (fixtures)
from test_addon_doubles import make_fake_generator, write_song


def test_batch_fps_resamples_onto_the_scene_rate(addon, tmp_path, capsys):  # noqa: F811
    from blender_addon import batch

    song_path = write_song(tmp_path / "beat.wav", 1.5)
    code = batch.main([str(song_path), "--out", str(tmp_path / "out"), "--fps", "60"], generator=make_fake_generator())
    assert code == 0, capsys.readouterr().out
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "out" / "beat" / "beat.blend"))
    opened = bpy.context.scene
    action = bpy.data.objects["DanceNet Dancer"].animation_data.action
    assert opened.render.fps == 60 and round(action.frame_range[1] - action.frame_range[0]) + 1 == 90
    with pytest.raises(SystemExit):
        batch.parse_args([str(song_path), "--out", str(tmp_path), "--fps", "23"])

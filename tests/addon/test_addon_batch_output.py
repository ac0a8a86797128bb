"""Batch mode's output is its summary lines (no temporary file names from Blender's
exporters), and a folder given as a song is called a folder."""

from __future__ import annotations

from doubles import make_fake_generator, write_song


def test_batch_prints_no_temporary_names_and_calls_a_folder_a_folder(addon, tmp_path, capfd):
    from blender_addon import batch

    song = write_song(tmp_path / "short.wav", 0.5)
    (tmp_path / "x.ogg").mkdir()
    code = batch.main([str(song), str(tmp_path / "x.ogg"), "--out", str(tmp_path / "out"), "--bvh", "--fbx",
                       "--render", "--resolution", "96x64"], generator=make_fake_generator())
    out = capfd.readouterr().out
    assert code == 1, out
    assert ".tmp" not in out, out
    lines = out.splitlines()
    assert lines[0].startswith("OK      short.wav"), out
    assert lines[1].startswith("FAILED  x.ogg: ") and "is a folder, not an audio file" in lines[1], out
    assert lines[2:] == ["1 of 2 songs done"], out
    assert {p.name for p in (tmp_path / "out" / "short").iterdir()} == {"short.blend", "short.bvh", "short.fbx",
                                                                      "short.mp4"}

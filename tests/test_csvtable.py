"""A user's CSV as a spreadsheet saves it (Excel's "CSV UTF-8" starts with a byte-order mark, a trailing comma
leaves an empty header): the library manifest and the song catalog read it the same way, no hint lost."""

from __future__ import annotations

from pathlib import Path

from dancenet_core.catalog import read_catalog
from dancenet_core.library.build import ClipHints, clip_hints

EXCEL = "utf-8-sig"  # what Excel's "CSV UTF-8" writes: a byte-order mark, then UTF-8


def test_a_manifest_with_a_byte_order_mark_keeps_its_hints(tmp_path: Path) -> None:
    (tmp_path / "manifest.csv").write_text("file,Style,bpm,meter,\r\na.bvh,rumba,100,3,\r\n", encoding=EXCEL)
    a = tmp_path / "a.bvh"
    assert clip_hints(tmp_path, [a]) == {a: ClipHints("rumba", 100.0, 3)}


def test_a_catalog_with_a_byte_order_mark_and_a_trailing_comma(tmp_path: Path) -> None:
    (tmp_path / "list.csv").write_text("Song,style,\r\nx.wav,waltz,\r\n", encoding=EXCEL)
    (song,) = read_catalog([tmp_path / "list.csv"])
    assert (song.path, song.settings) == (tmp_path / "x.wav", {"style": "waltz"})

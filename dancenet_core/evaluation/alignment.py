"""How well each real dance keeps time with its song: the Beat Align Score of the captured motion against
the music's tracked beats, at the manifest's offset and with the music moved by half a beat (a control:
what a wrong offset scores). The extra folder's timing was rebuilt from an older export (its README), so
its scores are compared with the main folder's, whose offsets are the authors'.

    dancenet data alignment [--data ../shared/data]
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..data.build import MODEL_FPS, build_dataset
from ..data.dance_with_melody import read_manifest
from ..music.features import analyze_music
from .metrics import beat_align_score


def alignment_table(data_dir: Path) -> list[dict]:
    """Per sequence: style, alignment kind, BAS at the manifest offset and with the beats moved half a beat."""
    pairs = {p.seq: p for p in build_dataset(data_dir, progress=False)}
    rows = []
    for seq in read_manifest(data_dir):
        pair = pairs[seq.seq]
        beats = analyze_music(seq.audio).beat_times - seq.music_offset_s
        half = 0.5 * float(np.median(np.diff(beats)))
        rows.append({
            "seq": seq.seq, "style": seq.style, "alignment": seq.alignment,
            "bas": beat_align_score(pair.positions, MODEL_FPS, beats),
            "bas_half_beat_off": beat_align_score(pair.positions, MODEL_FPS, beats + half),
        })  # fmt: skip
    return rows


def report(rows: list[dict]) -> str:
    """Mean scores by folder (alignment kind) and style, as a markdown table."""
    lines = ["| alignment | style | sequences | BAS at the offset | BAS half a beat off |", "|---|---|---|---|---|"]
    for kind in sorted({r["alignment"] for r in rows}):
        for style in sorted({r["style"] for r in rows if r["alignment"] == kind}):
            sel = [r for r in rows if r["alignment"] == kind and r["style"] == style]
            lines.append(f"| {kind} | {style} | {len(sel)} | {np.mean([r['bas'] for r in sel]):.3f} | "
                         f"{np.mean([r['bas_half_beat_off'] for r in sel]):.3f} |")
    return "\n".join(lines)

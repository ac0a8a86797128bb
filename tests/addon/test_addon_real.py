"""The add-on's batch mode with the real shipped model, end to end, in a fresh pip-bpy process."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from made_up import click_song

ROOT = Path(__file__).resolve().parents[2]


def test_batch_mode_dances_two_songs_with_the_shipped_model(tmp_path: Path) -> None:
    pytest.importorskip("bpy")
    songs = [click_song(tmp_path / "slow waltz.wav", 6.0, 90), click_song(tmp_path / "quick.wav", 5.0, 128)]
    user = tmp_path / "blender-user"
    env = os.environ | {
        "HOME": str(tmp_path / "home"),
        "BLENDER_USER_RESOURCES": str(user / "resources"),
        "BLENDER_USER_CONFIG": str(user / "config"),
        "BLENDER_USER_SCRIPTS": str(user / "scripts"),
        "BLENDER_USER_EXTENSIONS": str(user / "extensions"),
        "DANCENET_CACHE": str(tmp_path / "cache"),
    }
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, str(ROOT / "blender_addon" / "batch.py"), *map(str, songs), "--out", str(out), "--bvh",
         "--fbx", "--seed", "3", "--fps", "30"],
        capture_output=True, text=True, env=env, timeout=600, cwd=ROOT,
    )
    summary = [line for line in proc.stdout.splitlines() if line.startswith(("OK ", "FAILED ")) or "songs done" in line]
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert len(summary) == 3, summary
    assert summary[-1] == "2 of 2 songs done", summary
    # Names with spaces become safe stems (README: batch folder naming): "slow waltz" -> "slow_waltz".
    for stem in ("slow_waltz", "quick"):
        folder = out / stem
        assert {p.suffix for p in folder.iterdir()} >= {".blend", ".bvh", ".fbx"}
        assert (folder / f"{stem}.bvh").stat().st_size > 10_000
        # --fps 30: the model's 25-fps dance slerp-resampled onto a 30-fps scene, so the BVH is at 30.
        frame_time = next(line for line in (folder / f"{stem}.bvh").read_text().splitlines() if "Frame Time" in line)
        assert float(frame_time.split(":")[1]) == pytest.approx(1 / 30, abs=1e-6)

"""The preview's render workers and ffmpeg end with the run however it ends (a closed
terminal's SIGHUP, SIGKILL), never living on with their ~320 MB each. The analysis workers' test is
test_safety.py's `test_signal_during_analysis_leaves_no_worker_behind`."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from made_up import as_a_terminal_signals_it, small_motion
from test_safety import _alive, _children

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc")
@pytest.mark.parametrize("sig", [signal.SIGHUP, signal.SIGKILL], ids=["SIGHUP", "SIGKILL"])
def test_killed_render_leaves_no_worker_nor_ffmpeg(tmp_path: Path, sig: signal.Signals) -> None:
    motion = tmp_path / "long.npz"
    small_motion(6000).save(motion)
    env = {**os.environ, "DANCENET_WORKERS": "2", "DANCENET_CACHE": str(tmp_path / "cache")}
    with (tmp_path / "stderr").open("w") as log:  # a file, not a pipe: a helper left behind would hold a pipe open
        child = subprocess.Popen([sys.executable, "-m", "dancenet_core.cli", "render", str(motion), "-o",
                                  str(tmp_path / "long.mp4"), "--width", "64", "--height", "48"],
                                 cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=log, text=True,
                                 preexec_fn=as_a_terminal_signals_it)
    deadline = time.monotonic() + 180
    helpers: set[int] = set()
    while len(helpers) < 3:  # two render workers and ffmpeg
        assert child.poll() is None, (tmp_path / "stderr").read_text()
        assert time.monotonic() < deadline, "the render never started its workers"
        helpers = _children(child.pid)
        time.sleep(0.05)
    time.sleep(1.0)  # well into the frames
    child.send_signal(sig)
    code = child.wait(60)
    err = (tmp_path / "stderr").read_text()
    assert code != 0, err
    assert "Traceback" not in err, err
    deadline = time.monotonic() + 15
    while any(_alive(p) for p in helpers) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = [p for p in helpers if _alive(p)]
    for p in left:  # end them, so a failure here leaves nothing running
        os.kill(p, signal.SIGKILL)
    assert not left
    if sig != signal.SIGKILL:  # unwound: its half-written video removed (a SIGKILL's goes on the next run)
        assert not [p.name for p in tmp_path.iterdir() if ".tmp" in p.name]

"""The preview video: frames go raw (rgb24) down a pipe to ffmpeg, which encodes H.264 and muxes the music from
the dance's start, trimmed or padded to the dance, so sound and picture start and end together."""

from __future__ import annotations

import contextlib
import shutil
import subprocess
import tempfile
from fractions import Fraction
from pathlib import Path
from typing import IO, cast

from ..atomic import atomic_path
from ..errors import DanceNetError
from ..motion import Motion
from ..progress import Progress
from .frames import _check_size, iter_frames
from .stills import _make_dir, _save_png


def _tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        raise DanceNetError(f"{name} not found; install it (Debian: apt-get install ffmpeg)")
    return path


def _check_audio(audio: Path) -> None:
    """Fail before rendering, not after, when the music is missing or holds no sound."""
    if not audio.is_file():
        raise DanceNetError(f"audio file not found: {audio}")
    proc = subprocess.run(
        [_tool("ffprobe"), "-v", "error", "-select_streams", "a:0", "-show_entries", "stream=codec_type",
         "-of", "csv=p=0", str(audio)], capture_output=True, text=True)
    if "audio" not in proc.stdout:
        raise DanceNetError(f"{audio} holds no audio that ffmpeg can read")


def _last_line(text: str) -> str:
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[-1] if lines else "no message"


def render_motion(
    motion: Motion,
    out: str | Path,
    audio: str | Path | None = None,
    width: int = 640,
    height: int = 360,
    progress: Progress | None = None,
    frames_dir: str | Path | None = None,
    audio_start: float = 0.0,
) -> Path:
    """An H.264 MP4 of the dance at the motion's fps, with `audio` from `audio_start` seconds (a dance of
    a part of the song) trimmed or padded to the dance, muxed in.

    `progress(fraction)` is called after each frame; `frames_dir` also gets every frame as a PNG.
    The file appears only when complete.
    """
    out = Path(out)
    if width % 2 or height % 2:
        raise DanceNetError(f"video size {width}x{height}: H.264 needs an even width and height")
    _check_size(width, height)
    audio = Path(audio) if audio is not None else None
    if audio is not None:
        _check_audio(audio)
    _make_dir(out.parent)
    if frames_dir is not None:
        frames_dir = Path(frames_dir)
        _make_dir(frames_dir)
    rate = Fraction(motion.fps).limit_denominator(1001)
    cmd = [_tool("ffmpeg"), "-y", "-hide_banner", "-nostdin", "-loglevel", "error", "-f", "rawvideo",
           "-pix_fmt", "rgb24", "-s", f"{width}x{height}", "-framerate", str(rate), "-i", "pipe:0"]
    if audio is not None:
        cmd += ["-ss", f"{audio_start:.6f}", "-i", str(audio), "-map", "0:v:0", "-map", "1:a:0", "-af", "apad",
                "-c:a", "aac", "-b:a", "192k"]
    # -t ends every stream at the last frame: the music is cut there, or padded with silence up to it.
    cmd += ["-t", f"{float(motion.num_frames / rate):.6f}", "-c:v", "libx264", "-preset", "veryfast",
            "-crf", "20", "-pix_fmt", "yuv420p", "-movflags", "+faststart", "-f", "mp4"]
    frames = iter_frames(motion, None, width, height)
    with atomic_path(out) as partial, tempfile.TemporaryFile() as log, contextlib.closing(frames):
        proc = subprocess.Popen([*cmd, str(partial)], stdin=subprocess.PIPE, stderr=log)
        stdin = cast(IO[bytes], proc.stdin)
        try:
            with contextlib.suppress(BrokenPipeError):  # ffmpeg quit early: its own message says why
                for i, image in enumerate(frames):
                    stdin.write(image.tobytes())
                    if frames_dir is not None:
                        _save_png(image, frames_dir / f"frame_{i:05d}.png")
                    if progress:
                        progress((i + 1) / motion.num_frames)
                stdin.close()
            code = proc.wait()
        except BaseException:
            proc.kill()
            proc.wait()
            raise
        if code != 0:
            log.seek(0)
            message = _last_line(log.read().decode(errors="replace"))
            raise DanceNetError(f"ffmpeg could not write {out}: {message}")
    return out

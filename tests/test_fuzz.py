"""Fuzzing the readers: hundreds of generated malformed BVH and audio files. Each is read, or
refused with one line (a DanceNetError); never a traceback, never a hang (each bounded in time)."""

from __future__ import annotations

import io
import signal
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from dancenet_core.bvh import write_bvh
from dancenet_core.commands.render import load_motion
from dancenet_core.errors import DanceNetError
from dancenet_core.motion import Motion
from dancenet_core.music.audio import load_audio

SECONDS_EACH = 20  # generous for a shared 2-core machine; a hang is what this catches
TOKENS = ["nan", "inf", "-inf", "1e400", "-1e308", "", "{", "}", "JOINT", "ROOT", "End", "Site", "MOTION", "x", "-",
          "0x10", "１", "\x00", "99999999999999999999", "CHANNELS", "OFFSET", "Frames:", "3.5.1", "\ufeff", "é"]


@contextmanager
def time_limit(seconds: int) -> Iterator[None]:
    def expire(*_: object) -> None:
        raise TimeoutError(f"took over {seconds} s")

    old = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def check_reader(read: Callable[[Path], object], path: Path) -> str:
    """'ok' or 'refused'; anything but a one-line DanceNetError fails the test with the file to reproduce it."""
    try:
        with time_limit(SECONDS_EACH):
            read(path)
    except DanceNetError as e:
        message = str(e)
        assert message, (path.read_bytes()[:300], message)
        assert "\n" not in message, (path.read_bytes()[:300], message)
        assert "Traceback" not in message, (path.read_bytes()[:300], message)
        return "refused"
    except Exception as e:  # any exception (the point: report which file broke which reader, and how)
        pytest.fail(f"{type(e).__name__}: {e} on {path.name}: {path.read_bytes()[:300]!r}")
    return "ok"


# --------------------------------------------------------------------------------------------------- BVH

def _base_bvhs(tmp: Path) -> list[bytes]:
    rng = np.random.default_rng(0)
    rot = 0.3 * rng.standard_normal((6, 55, 3))
    root = np.stack([np.zeros(6), np.full(6, 0.9), np.linspace(0, 1, 6)], -1)
    write_bvh(tmp / "full.bvh", Motion(rot, root, 25.0))
    small = ("HIERARCHY\nROOT hips\n{\n\tOFFSET 0 0 0\n\tCHANNELS 6 Xposition Yposition Zposition Zrotation "
             "Xrotation Yrotation\n\tJOINT knee\n\t{\n\t\tOFFSET 0 -0.4 0\n\t\tCHANNELS 3 Zrotation Xrotation "
             "Yrotation\n\t\tEnd Site\n\t\t{\n\t\t\tOFFSET 0 -0.4 0\n\t\t}\n\t}\n}\nMOTION\nFrames: 2\n"
             "Frame Time: 0.033333\n0 1 0 10 20 30 5 5 5\n0 1 0.1 11 21 31 6 6 6\n")
    return [(tmp / "full.bvh").read_bytes(), small.encode()]


def _mutate_bvh(base: bytes, rng: np.random.Generator) -> bytes:
    lines = base.decode().split("\n")
    for _ in range(int(rng.integers(1, 4))):
        kind = int(rng.integers(12))
        i = int(rng.integers(len(lines))) if lines else 0
        if kind == 0 and lines:
            del lines[i]
        elif kind == 1 and lines:
            lines.insert(i, lines[int(rng.integers(len(lines)))])
        elif kind in (2, 3) and lines:  # replace or insert a token
            words = lines[i].split()
            k = int(rng.integers(len(words) + 1))
            token = TOKENS[int(rng.integers(len(TOKENS)))]
            words[k : k + (kind == 2)] = [token]
            lines[i] = " ".join(words)
        elif kind == 4 and len(lines) > 1:
            j = int(rng.integers(len(lines)))
            lines[i], lines[j] = lines[j], lines[i]
        elif kind == 5:
            k = lines.index("MOTION") if "MOTION" in lines else 0
            lines[min(k + 1, len(lines) - 1)] = f"Frames: {rng.choice(['0', '-3', '1e9', '2', '100000000', 'x'])}"
        elif kind == 6:
            k = lines.index("MOTION") if "MOTION" in lines else 0
            lines[min(k + 2, len(lines) - 1)] = f"Frame Time: {rng.choice(['0', '-1', 'inf', 'nan', '1e-300', 'x'])}"
        elif kind == 7:
            depth = int(rng.integers(50, 3000))
            chain = "".join(f"JOINT d{n}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n"
                            for n in range(depth))
            lines[i:i] = (chain + "}\n" * depth).split("\n")
        elif kind == 8:
            lines = lines[: max(1, int(rng.integers(len(lines) + 1)))]
        elif kind == 9 and lines:
            lines[i] = lines[i].replace(" ", rng.choice(["\t", "  ", "\r", ",", ""]))
        elif kind == 10:  # random bytes somewhere
            text = "\n".join(lines)
            k = int(rng.integers(len(text) + 1))
            noise = rng.bytes(int(rng.integers(1, 40))).decode("latin-1")
            lines = (text[:k] + noise + text[k:]).split("\n")
        else:
            lines = [line for line in lines if line.strip() not in ("{", "}") or rng.random() < 0.8]
    data = "\n".join(lines).encode("utf-8", errors="surrogateescape")
    return data if rng.random() < 0.9 else data[: int(rng.integers(len(data) + 1))]


def test_fuzz_bvh_reader(tmp_path: Path) -> None:
    rng = np.random.default_rng(16)
    bases = _base_bvhs(tmp_path)
    outcomes = []
    for n in range(240):
        path = tmp_path / f"fuzz_{n:03d}.bvh"
        path.write_bytes(rng.bytes(int(rng.integers(0, 2000))) if n % 20 == 0
                         else _mutate_bvh(bases[n % 2], rng))
        outcomes.append(check_reader(load_motion, path))
    assert outcomes.count("refused") >= 150, outcomes.count("refused")  # the mutations really are malformed


# ------------------------------------------------------------------------------------------------- audio

def _base_audio() -> list[tuple[str, bytes]]:
    rate = 22050
    t = np.arange(int(4 * rate)) / rate
    y = (0.3 * np.sin(2 * np.pi * 220 * t)).astype(np.float32)
    out = []
    for fmt, subtype, ext in [("WAV", "PCM_16", "wav"), ("WAV", "FLOAT", "wav"), ("FLAC", "PCM_16", "flac"),
                              ("OGG", "VORBIS", "ogg")]:
        buf = io.BytesIO()
        sf.write(buf, np.stack([y, y], -1), rate, format=fmt, subtype=subtype)
        out.append((ext, buf.getvalue()))
    return out


def _mutate_audio(ext: str, data: bytes, rng: np.random.Generator) -> tuple[str, bytes]:
    b = bytearray(data)
    kind = int(rng.integers(9))
    if kind == 0:  # truncated anywhere, header included
        b = b[: int(rng.integers(len(b)))]
    elif kind == 1:  # bytes flipped in the header
        for _ in range(int(rng.integers(1, 8))):
            b[int(rng.integers(min(64, len(b))))] = int(rng.integers(256))
    elif kind == 2:  # bytes flipped anywhere
        for _ in range(int(rng.integers(1, 200))):
            b[int(rng.integers(len(b)))] = int(rng.integers(256))
    elif kind == 3:
        b = bytearray(rng.bytes(int(rng.integers(0, 5000))))
    elif kind == 4:  # a float WAV with NaN or inf samples
        y = np.frombuffer(bytes(b[44:]), dtype="<f4").copy() if ext == "wav" else np.zeros(0, "<f4")
        if len(y):
            y[rng.integers(len(y), size=10)] = rng.choice([np.nan, np.inf, -np.inf])
            b = b[:44] + bytearray(y.tobytes())
    elif kind == 5:  # huge declared sizes / channel counts
        if len(b) > 40:
            b[22:24] = int(rng.integers(0, 65536)).to_bytes(2, "little")
            b[4:8] = b"\xff\xff\xff\xff"
    elif kind == 6:
        b = bytearray(b"this is not a song\n" * int(rng.integers(0, 100)))
    elif kind == 7:
        b = b[:44] + bytearray(len(b) - 44)  # silence
    else:
        b = b + bytearray(rng.bytes(int(rng.integers(1, 3000))))
    ext = ext if rng.random() < 0.8 else str(rng.choice(["mp3", "opus", "wav", "flac", "txt"]))
    return ext, bytes(b)


def test_fuzz_audio_reader(tmp_path: Path) -> None:
    rng = np.random.default_rng(160)
    bases = _base_audio()
    outcomes = []
    for n in range(120):
        ext, data = _mutate_audio(*bases[n % len(bases)], rng)
        path = tmp_path / f"fuzz_{n:03d}.{ext}"
        path.write_bytes(data)
        outcomes.append(check_reader(load_audio, path))
    assert outcomes.count("refused") >= 50, outcomes.count("refused")

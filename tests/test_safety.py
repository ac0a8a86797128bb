"""Issue 16: never lose a user's work. Weights load without unpickling, files are written whole or not at all,
existing outputs are not overwritten silently, the cache heals itself, bad input gets one line."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest
import torch

from dancenet_core.checkpoint import load_weights
from dancenet_core.errors import DanceNetError
from dancenet_core.footfix import WEIGHTS as FOOTFIX_WEIGHTS
from dancenet_core.footfix import FootFixer
from dancenet_core.model.bundle import DEFAULT_BUNDLE, DanceNetBundle

SHIPPED = sorted((Path(__file__).resolve().parents[1] / "dancenet_core" / "weights").glob("*.pt"))


def one_line(e: BaseException) -> str:
    msg = str(e)
    assert msg and "\n" not in msg and "Traceback" not in msg, msg
    return msg


# --- item 6: safe weights -------------------------------------------------------------------------------------

@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_shipped_weights_are_plain_data(path: Path) -> None:
    torch.load(path, map_location="cpu", weights_only=True)


class _Exploit:
    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple:
        return (Path.touch, (self.marker,))


def test_crafted_weights_do_not_run_code(tmp_path: Path) -> None:
    marker, bad = tmp_path / "pwned", tmp_path / "evil.pt"
    torch.save({"config": _Exploit(marker)}, bad)
    for load in (DanceNetBundle.load, FootFixer.load):
        with pytest.raises(DanceNetError) as e:
            load(bad)
        assert "plain weights" in one_line(e.value)
    assert not marker.exists()


@pytest.mark.parametrize("content", [b"", b"\x00" * 7, np.random.default_rng(0).bytes(4096),
                                     pickle.dumps([1, 2, 3]), b"PK\x03\x04truncated zip"],
                         ids=["empty", "zeros", "random", "plain-pickle", "truncated-zip"])
def test_bad_weights_file_gives_one_line(tmp_path: Path, content: bytes) -> None:
    bad = tmp_path / "bad.pt"
    bad.write_bytes(content)
    for load in (DanceNetBundle.load, FootFixer.load):
        with pytest.raises(DanceNetError) as e:
            load(bad)
        assert str(bad) in one_line(e.value)


def test_wrong_dict_gives_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "wrong.pt"
    torch.save({"state_dict": {"w": torch.zeros(2)}}, bad)
    for load in (DanceNetBundle.load, FootFixer.load):
        with pytest.raises(DanceNetError) as e:
            load(bad)
        one_line(e.value)


def test_corrupted_shipped_footfix_gives_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "footfix.pt"
    data = FOOTFIX_WEIGHTS.read_bytes()
    bad.write_bytes(data[: len(data) // 2])
    with pytest.raises(DanceNetError) as e:
        FootFixer.load(bad)
    assert "footfix.pt" in one_line(e.value)


def test_bundle_save_round_trip_is_plain_and_exact(tmp_path: Path) -> None:
    shipped = DanceNetBundle.load(DEFAULT_BUNDLE)
    out = tmp_path / "again.pt"
    shipped.save(out)
    load_weights(out, "DanceNet weights", "")  # weights_only=True
    again = DanceNetBundle.load(out)
    for k, v in shipped.model.state_dict().items():
        assert torch.equal(v, again.model.state_dict()[k])
    for k, v in shipped.start_frames.items():
        assert again.start_frames[k].dtype == v.dtype and np.array_equal(again.start_frames[k], v)
    assert np.array_equal(again.normalizer.constant, shipped.normalizer.constant)
    assert np.array_equal(again.skeleton.offsets, shipped.skeleton.offsets)
    assert list(tmp_path.iterdir()) == [out]  # no temporary left behind

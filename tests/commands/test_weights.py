"""`dancenet weights export`: the runtime files made from the checkpoints in a folder are the shipped ones;
`dancenet weights upgrade`: old weights files converted without running any code they hold."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from dancenet_core.checkpoint import load_weights
from dancenet_core.cli import main
from dancenet_core.environment import WEIGHTS_DIR
from dancenet_core.runtime.weights import read_arrays

NAMES = ("dancenet", "style_classifier", "footfix")


def test_export_remakes_the_shipped_runtime_files(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    for name in NAMES:
        shutil.copy(WEIGHTS_DIR / f"{name}.pt", tmp_path)
    assert main(["weights", "export", "--weights", str(tmp_path)]) == 0
    assert [line.split(":")[0] for line in capsys.readouterr().out.splitlines()] == [
        str(tmp_path / f"{n}.npz") for n in NAMES]
    for name in NAMES:
        made, made_meta = read_arrays(tmp_path / f"{name}.npz", name, "")
        shipped, shipped_meta = read_arrays(WEIGHTS_DIR / f"{name}.npz", name, "")
        assert made_meta == shipped_meta  # the music feature spec included
        assert made.keys() == shipped.keys()
        for k in shipped:
            np.testing.assert_array_equal(made[k], shipped[k], err_msg=f"{name}: {k}")


def test_a_folder_without_checkpoints_exports_nothing(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["weights", "export", "--weights", str(tmp_path)]) == 0
    assert capsys.readouterr().out == "" and not any(tmp_path.iterdir())


class _Runs:
    """Unpickled, it would make a folder: what a crafted weights file's code could do instead."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple:
        return os.mkdir, (str(self.marker),)


def test_upgrade_converts_the_old_format_and_runs_no_code(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """A weights file of the pickled format (numpy arrays, numpy numbers, paths) becomes plain weights with the
    same numbers; a file with any other object is refused in one line, left as it was, and none of its code runs."""
    old = tmp_path / "old.pt"
    rotations = np.random.default_rng(0).standard_normal((4, 3)).astype(np.float32)
    torch.save({"normalizer": {"mean": rotations, "count": np.int64(7)}, "data": Path("/runs/x"),
                "state_dict": {"w": torch.ones(2)}}, old)
    assert main(["weights", "upgrade", str(old)]) == 0
    plain = load_weights(old, "weights", "")
    np.testing.assert_array_equal(plain["normalizer"]["mean"].numpy(), rotations)
    assert (plain["normalizer"]["count"], plain["data"]) == (7, str(Path("/runs/x")))

    crafted = tmp_path / "crafted.pt"
    torch.save({"state_dict": {}, "info": _Runs(tmp_path / "ran")}, crafted)
    before = crafted.read_bytes()
    capsys.readouterr()
    assert main(["weights", "upgrade", str(crafted)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "not converted" in err, err
    assert not (tmp_path / "ran").exists() and crafted.read_bytes() == before

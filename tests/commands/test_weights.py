"""`dancenet weights export`: the runtime files made from the checkpoints in a folder are the shipped ones."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

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

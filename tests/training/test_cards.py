"""DanceNet's model card: its test table measures generation's defaults beside the dance without the clean-up and
without the beat lock, and a rewrite keeps the measured tables of the card it replaces, byte for byte."""

from __future__ import annotations

from pathlib import Path

import pytest

from dancenet_core.cli import main
from dancenet_core.environment import WEIGHTS_DIR
from dancenet_core.nets.bundle import DEFAULT_BUNDLE, DanceNetBundle
from dancenet_core.training.cards import VALIDATION_HEADING, dancenet_card, kept_sections, validation_sections

KEYS = ("beat_align_score", "rhythm_hit_rate", "foot_slide_ratio", "foot_slide_m_per_contact_frame", "contact_ratio",
        "min_lowest_toe_m", "max_lowest_toe_m", "floor_reach", "jitter_m_s2", "joint_speed_m_s", "longest_freeze_s",
        "max_longest_freeze_s", "root_extent_m", "contact_accuracy", "max_root_extent_m")


def _measured(real: float, generated: float) -> dict:
    """An `evaluate_on_test_split` result whose every figure is `real` for the real dances, `generated` else."""
    return {"temperature": 1.0, "seed": 0,
            "summary": {"real": dict.fromkeys(KEYS, real), "generated": dict.fromkeys(KEYS, generated)}}


@pytest.fixture(scope="module")
def bundle() -> DanceNetBundle:
    return DanceNetBundle.load(DEFAULT_BUNDLE)


def test_the_test_table_has_generations_defaults_and_both_comparisons(bundle: DanceNetBundle) -> None:
    card = dancenet_card(bundle, _measured(0.1, 0.2), _measured(0.1, 0.3), _measured(0.1, 0.4), None)
    assert "| beat_align_score | 0.1000 | 0.2000 | 0.3000 | 0.4000 |" in card
    assert "Beat Align Score, generated / real: 3.00 (4.00 without the beat lock)" in card
    assert "Foot sliding, generated / real: 3.00 (2.00 without the foot clean-up)" in card
    assert "## Beat lock" in card and VALIDATION_HEADING not in card


def test_a_rewritten_card_keeps_its_measured_tables_verbatim(bundle: DanceNetBundle, tmp_path: Path) -> None:
    (tmp_path / "validation.md").write_text("| model | FID_k |\n|---|---|\n| shipped | 28.6 |\n\nMeasured so.\n")
    first = dancenet_card(bundle, _measured(0.1, 0.2), _measured(0.1, 0.3), _measured(0.1, 0.4), None,
                          validation_sections(tmp_path))
    path = tmp_path / "CARD.md"
    path.write_text(first)
    second = dancenet_card(bundle, _measured(0.1, 0.5), _measured(0.1, 0.6), _measured(0.1, 0.7), None,
                           kept_sections(path))
    tail = first[first.index(VALIDATION_HEADING):]
    assert second.endswith(tail) and second.count(VALIDATION_HEADING) == 1
    assert "| shipped | 28.6 |" in tail and "| beat_align_score | 0.1000 | 0.5000 |" in second
    assert kept_sections(tmp_path / "none.md") == []


def test_the_shipped_card_has_measured_tables_to_keep() -> None:
    assert "| shipped weights, foot clean-up: lock, beat lock on |" in "\n".join(
        kept_sections(WEIGHTS_DIR / "DANCENET_MODEL_CARD.md"))


def test_card_refuses_a_single_measurement_setting(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["card", "dancenet", "--card", str(tmp_path / "CARD.md"), "--no-beat-lock"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "leave out --footfix and --no-beat-lock" in err
    assert not (tmp_path / "CARD.md").exists()


def test_the_library_card_is_written_from_its_arrays_and_keeps_its_measured_sections(tmp_path: Path) -> None:
    """The shipped library's card: its table counts the file's own clips and minutes by style, and a rewrite keeps
    the measured sections below `LIBRARY_MEASURED_HEADING` byte for byte."""
    import shutil

    from dancenet_core.library.store import DEFAULT_LIBRARY, MotionLibrary
    from dancenet_core.training.cards import LIBRARY_MEASURED_HEADING, write_library_card

    path = tmp_path / DEFAULT_LIBRARY.name
    shutil.copy(DEFAULT_LIBRARY, path)
    library = MotionLibrary.load(path)
    card = write_library_card(path)
    text = card.read_text()
    for style in set(library.styles):
        clips = sum(s == style for s in library.styles)
        assert f"| {style} | {clips} | " in text
    assert f"{library.num_clips} dance trials" in text and LIBRARY_MEASURED_HEADING not in text
    measured = f"\n{LIBRARY_MEASURED_HEADING}\n\n| figure | 1.23 |\n"
    card.write_text(text + measured)
    assert write_library_card(path).read_text().endswith(measured)
    assert main(["card", "library", "--library", str(tmp_path / "none.npz")]) == 2

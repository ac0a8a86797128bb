"""What each part that makes a dance may be used for, and the `licence` block every output's JSON carries: the
parts a run used and their terms, so that a studio can tell a dance it may use from one it may not.

The commercial mode (`DanceRequest.commercial`) runs only the parts marked `commercial`: this project's code,
the weight-free music analysis (`music.weightfree`) and the library engine on the user's own clips, its style the
user's or read from the song's tempo and meter (`engines.styles.style_by_tempo`). `NON_COMMERCIAL_FILES` names the
files it never opens (tests/test_commercial.py records every file a commercial run opens against them).
docs/licence.md has the table and what was searched for a library that may be shipped for commercial use.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Part:
    what: str
    terms: str
    commercial: bool


PARTS = {
    "code": Part("DanceNet's code (dancenet_core, the add-on)", "GPL-3.0-or-later; puts no terms on the dances it "
                 "writes", True),
    "weightfree_analysis": Part("music analysis from signal processing (music/weightfree.py: onsets, tempo, beats, "
                                "meter, chroma; no trained weights)", "GPL-3.0-or-later (this project's code)", True),
    "madmom_models": Part("madmom's onset, beat/downbeat and deep chroma networks (the default music analysis)",
                          "CC BY-NC-SA 4.0: non-commercial", False),
    "dancenet_weights": Part("DanceNet's weights, trained on Dance with Melody", "no licence granted by the "
                             "dataset: research and non-commercial use only", False),
    "foot_model": Part("the Foot Constraint Model's weights, trained on Dance with Melody", "no licence granted by "
                       "the dataset: research and non-commercial use only", False),
    "style_classifier": Part("the music style classifier, trained on Dance with Melody", "no licence granted by the "
                             "dataset: research and non-commercial use only", False),
    "learned_match": Part("the learned match of music and movement (library/match.py), trained on Dance with "
                          "Melody", "no licence granted by the dataset: research and non-commercial use only", False),
    "shipped_library": Part("the shipped CMU motion library, built from AMASS conversions of CMU's dance trials",
                            "AMASS: non-commercial research only (CMU's own files allow commercial use)", False),
    "own_library": Part("your library of clips (--library FOLDER)", "the terms of your clips: yours to check",
                        True),
    "style_by_tempo": Part("the style matched to the song's tempo and meter (public dance-sport tempo ranges)",
                           "facts, no terms", True),
    "chosen_style": Part("the style you chose", "yours", True),
}

# Files under the package, madmom's package and the data folder that the commercial mode never opens (path
# fragments, '/'-separated): every trained weight file shipped, madmom's model files, the training data.
NON_COMMERCIAL_FILES = ("dancenet_core/weights/", "madmom/models/", "dance_with_melody", "cmu_dance")


def licence_block(parts: list[str], commercial: bool) -> dict:
    """The JSON block: the mode, whether every part used allows commercial use, and each part with its terms."""
    used = list(dict.fromkeys(["code", *parts]))
    return {"mode": "commercial" if commercial else "non-commercial",
            "commercial_use": all(PARTS[p].commercial for p in used),
            "parts": [{"part": PARTS[p].what, "terms": PARTS[p].terms, "commercial_use": PARTS[p].commercial}
                      for p in used]}


def analysis_part(commercial: bool) -> str:
    """The music analysis a mode runs."""
    return "weightfree_analysis" if commercial else "madmom_models"

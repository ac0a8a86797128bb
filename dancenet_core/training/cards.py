"""The model cards (Markdown beside the shipped weights), written from what the weights store and from
measurements, so a card can be rewritten without retraining: the style classifier's, the motion style
classifier's, DanceNet's and the shipped motion library's (`dancenet card ...`)."""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..atomic import write_text
from ..constants import WARP_RANGE
from ..data.dance_with_melody import Recording, read_manifest
from ..data.split import SPLIT_FILE, validation_songs
from ..engines.dancenet import FOOT_CLEANUP
from ..errors import DanceNetError
from ..evaluation.metrics import balanced_accuracy
from ..evaluation.motion_style import DEFAULT_WEIGHTS as MOTION_STYLE_WEIGHTS
from ..evaluation.motion_style import FPS, HOP_S, MODEL_CARD, N_INPUTS, MotionStyleModel
from ..library.store import DEFAULT_LIBRARY, LIBRARY_VERSION, MotionLibrary
from ..music.features import FEATURE_VERSION
from ..music.style import (
    BASELINE_WEIGHTS,
    BUMP_SIGMA_FRAMES,
    DEFAULT_WEIGHTS,
    TEMPO_MEDIAN_BEATS,
    TEMPO_REF_BPM,
    WINDOW_S,
)
from ..music.style import HOP_S as STYLE_HOP_S
from ..music.style import N_INPUTS as STYLE_INPUTS
from ..nets.bundle import DanceNetBundle
from ..nets.style_torch import StyleModel
from ..shaping.footlock import GROUND_M, STILL_MPS
from .motion_style import AUG_TEMPO as MOTION_AUG_TEMPO
from .motion_style import Dance, load_dances
from .style import AUG_CHROMA_DROP, AUG_GAIN, AUG_NOISE, VALIDATION, VALIDATION_METER_TEMPO, VALIDATION_WITH_TANGO
from .style import AUG_TEMPO as STYLE_AUG_TEMPO


def write_style_card(data_dir: str | Path, out_dir: str | Path, split_path: str | Path | None = None) -> Path:
    """STYLE_MODEL_CARD.md in out_dir, from the two checkpoints' training metadata, the split and the
    manifest (so the card can be rewritten without retraining)."""
    out_dir = Path(out_dir)
    rows = read_manifest(Path(data_dir))
    split = json.loads(Path(split_path or out_dir / SPLIT_FILE.name).read_text())
    trained = {}
    for arch, path in (("conv", DEFAULT_WEIGHTS), ("baseline", BASELINE_WEIGHTS)):
        model = StyleModel.load(out_dir / path.name)
        if "metrics" not in model.meta.get("training", {}):
            raise DanceNetError(f"{out_dir / path.name} has no training metrics; retrain it with this version")
        trained[arch] = model
    card = out_dir / "STYLE_MODEL_CARD.md"
    write_text(card, style_card(trained["conv"], trained["baseline"], split, rows))
    return card


def _confusion(styles: Sequence[str], m: list[list[int]]) -> list[str]:
    """A confusion matrix (rows: the truth) as a markdown table."""
    lines = ["| truth \\ predicted | " + " | ".join(styles) + " |", "|---" * (len(styles) + 1) + "|"]
    return lines + [f"| {st} | " + " | ".join(str(v) for v in row) + " |" for st, row in zip(styles, m, strict=True)]


def _majority(m: list[list[int]]) -> float:
    """Accuracy of always answering the style with most test items (rows of confusion matrix m)."""
    return max(sum(r) for r in m) / max(1, sum(sum(r) for r in m))


def style_card(conv: StyleModel, baseline: StyleModel, split: dict, rows: Sequence[Recording]) -> str:
    """Markdown summary of data, split, settings and held-out results of both models, like Table 2."""
    card = _StyleCard(conv, baseline, split, rows)
    return "\n".join(card._title() + card._data() + card._training() + card._differences() + card._results()
                     + card._limits())


class _StyleCard:
    """The style classifiers' card, section by section, from the two models' training metadata, the split and
    the manifest."""

    def __init__(self, conv: StyleModel, baseline: StyleModel, split: dict, rows: Sequence[Recording]) -> None:
        self.conv, self.split, self.rows = conv, split, rows
        self.styles = styles = conv.styles
        self.settings = conv.meta["training"]
        self.c, self.b = conv.meta["training"]["metrics"], baseline.meta["training"]["metrics"]
        self.style_of = {r.seq: r.style for r in rows}
        self.seconds = {r.seq: r.song_s for r in rows}
        per_style = {st: [s for s in split["train"] if self.style_of[s] == st] for st in styles}
        self.common = max(styles, key=lambda st: len(per_style[st]))
        counts = sorted(len(v) for st, v in per_style.items() if st != self.common) or [0]
        self.few = str(counts[0]) if counts[0] == counts[-1] else f"{counts[0]}-{counts[-1]}"

    def count(self, seqs: Sequence[str], st: str) -> str:
        chosen = [s for s in seqs if self.style_of[s] == st]
        return f"{len(chosen)} ({sum(self.seconds[s] for s in chosen) / 60:.1f} min)"

    def confusion(self, m: list[list[int]]) -> list[str]:
        return _confusion(self.styles, m)

    def minority(self, m: dict) -> str:
        rest = {s: p for s, p in m["predictions"].items() if p["truth"] != self.common}
        return f"{sum(p['predicted'] == p['truth'] for p in rest.values())} of {len(rest)} right"

    def _title(self) -> list[str]:
        """What the models are and their files."""
        return [
            "# Style classifier model card",
            "",
            "Musical style classifier of DanceNet (Zhuang et al. 2020, section 4.2), trained by "
            "`dancenet train style`. Files: `style_classifier.pt` (temporal conv + Bi-LSTM + FC), "
            "`style_baseline.pt` (FC + Bi-LSTM + FC, the paper's baseline), `song_split.json`.",
            "",
        ]

    def _data(self) -> list[str]:
        """The songs, the input and the split."""
        styles, split, count, style_of = self.styles, self.split, self.count, self.style_of
        return [
            "## Data",
            "",
            "Dance with Melody (Tang et al. 2018) songs, the whole audio of each (not only the danced span); "
            f"research use only, no licence. Input: {STYLE_INPUTS} channels at 10 fps in "
            f"{WINDOW_S:g}-second windows: the music features' deep chroma (12) and onset (1) (feature version "
            f"`{FEATURE_VERSION}`), in place of their beat and downbeat activations a bump of height 1 (Gaussian, "
            f"sigma {BUMP_SIGMA_FRAMES:g} frame) at each beat and downbeat tracked by madmom's DBN (3 or 4 beats a "
            "bar), and the metre and tempo spelt out from the same tracked beats: the number of beats in the bar "
            "that each frame lies in, minus 3, and the local tempo as log2(bpm / "
            f"{TEMPO_REF_BPM:g}), the median of {TEMPO_MEDIAN_BEATS} beat intervals; see below for why. No two "
            "sequences share a recording (checked by waveform cross-correlation).",
            "",
            "| style | train songs | test songs |",
            "|---|---|---|",
            *[f"| {st} | {count(split['train'], st)} | {count(split['test'], st)} |" for st in styles],
            "",
            f"Split by song, stratified by style, seed {split['seed']}: "
            f"round({split['test_fraction']} x n) songs of each style held out (at least one). Excluded:",
            "",
            *[f"- {s} ({style_of[s]}): {why}" for s, why in split["excluded"].items()],
            "",
        ]

    def _training(self) -> list[str]:
        """The optimiser, the schedule and the augmentation."""
        settings, split, rows, conv = self.settings, self.split, self.rows, self.conv
        return [
            "## Training",
            "",
            f"Adam, learning rate {settings['lr']:g} divided by 10 at 60% and 83% of {settings['steps']} steps "
            f"(the supplement's schedule shape), batch {settings['batch']} windows, seed {settings['seed']}, "
            "cross-entropy; the last step is shipped. Each window: style drawn uniformly (waltz has most songs), "
            "then a song and a random offset; "
            + (f"played up to {100 * STYLE_AUG_TEMPO:g}% faster or slower (chroma and onset resampled in time, the "
               "bumps, beats per bar and tempo redrawn from the moved beat times: beats per second change, beats "
               "per bar do not), " if STYLE_AUG_TEMPO else "played at its own tempo (no stretch: see below), ")
            + "transposed by a random number of semitones (chroma rolled), the onset channel times "
            f"a gain in [{1 - AUG_GAIN:g}, {1 + AUG_GAIN:g}], plus Gaussian noise (sigma {AUG_NOISE:g})"
            + (f"; chroma blanked in {100 * AUG_CHROMA_DROP:g}% of windows. " if AUG_CHROMA_DROP else ". ")
            + f"Both models: Bi-LSTM of {conv.config['hidden']} units each way, dropout {conv.config['dropout']:g}, "
            "mean over time, then FC; trained by the same code with the same settings.",
            "",
            "These settings were chosen with `train --validate`, which holds out training songs by song ("
            + ", ".join(validation_songs(split, rows))
            + ") and never loads the test songs; the shipped models were then trained on all training songs.",
            "",
        ]

    def _differences(self) -> list[str]:
        """Where and why the models differ from the paper's."""
        styles, split, seconds, conv = self.styles, self.split, self.seconds, self.conv
        return [
            "## What differs from the paper, and why",
            "",
            "- Architecture as in section 4.2 (three temporal conv layers, kernel 2, channels 1-16-24-32, then a "
            "Bi-LSTM and a fully connected layer; the baseline puts a per-frame fully connected layer in place of "
            "the convolutions), 30-second windows, cross-entropy.",
            "- Input: the paper feeds its music features as they are. Here the beat and downbeat activation "
            "channels are replaced by bumps at the DBN-tracked beats and downbeats. Sampled at 10 fps, madmom's "
            "100-fps activations miss many of their peaks (a training song's highest sampled beat value ranges "
            "0.24-0.93), so the metre and tempo that tell these ballroom styles apart (waltz 3 beats a bar at "
            "83-88 bpm; cha-cha 115-125 bpm; rumba mostly 88-95 bpm) come through blurred; the tracked beats "
            "carry them intact. On the validation songs, with the same settings, the balanced accuracy of ours by "
            f"window (by song) is {VALIDATION['bumps']} with the bumps against {VALIDATION['activations']} with the "
            f"activations; the baseline's with bumps is {VALIDATION['baseline']}. DanceNet's own music input "
            "keeps the activation channels.",
            f"- Tango (from the extra data folder): with the same settings the balanced accuracy on the "
            f"validation songs is {VALIDATION_WITH_TANGO['200']} by window (by song) at 200 steps and "
            f"{VALIDATION_WITH_TANGO['400']} at 400: tango's songs (about 120-130 bpm, four beats a bar) are learnt, "
            "and cha-cha's, in the same tempo range, are taken for tango (see the confusion below). The style can "
            "always be chosen by hand (`--style`, the panel).",
            "- Metre and tempo as inputs: from the bumps alone the net has to count beats between "
            "downbeats and time their spacing, and trained so it calls a held-out waltz rumba and cha-cha tango; "
            "so beats per bar and the local tempo are two more input columns. With them the augmentation "
            "stretches no tempo: cha-cha (115-125 bpm here) and tango (125-128 bpm) lie within any stretch tried. "
            "Balanced accuracy by window (by song) of ours on the validation songs (one tango among them, "
            "DANCE_T_3, is taken for a cha-cha by every setting):",
            "",
            "| setting | validation, balanced by window (by song) |",
            "|---|---|",
            *[f"| {setting} | {figures} |" for setting, figures in VALIDATION_METER_TEMPO.items()],
            "",
            f"- Styles: the dance styles of the training data ({len(styles)} here) instead of the paper's two music "
            f"styles, and {sum(seconds[q] for q in split['train']) / 3600:.1f} hours of music instead of 35.7: hence "
            "the augmentation, the small Bi-LSTM "
            f"({conv.config['hidden']} units), dropout and the short schedule, all chosen on validation songs.",
            "",
        ]

    def _results(self) -> list[str]:
        """Accuracy on the held-out songs, the confusions and each song."""
        styles, c, b, split, confusion = self.styles, self.c, self.b, self.split, self.confusion
        return [
            "## Held-out results",
            "",
            f"Windows every {STYLE_HOP_S:g} s over each test song ({c['windows']} windows, {c['songs']} songs); "
            "a song's style is the mean of its windows' probabilities.",
            "",
            "Balanced accuracy is the mean of the per-style recalls: the fairer number with this many waltzes, "
            f"since always answering the most common style scores {100 / len(styles):.1f}% on it.",
            "",
            "| method | window accuracy | balanced, by window | song accuracy | balanced, by song "
            "| train window accuracy | training time |",
            "|---|---|---|---|---|---|---|",
            f"| Always the most common style | {100 * _majority(c['confusion_window']):.1f}% "
            f"| {100 / len(styles):.1f}% | {100 * _majority(c['confusion_song']):.1f}% | {100 / len(styles):.1f}% "
            "| - | - |",
            *[
                f"| {name} | {100 * m['window_accuracy']:.1f}% | {100 * balanced_accuracy(m['confusion_window']):.1f}% "
                f"| {100 * m['song_accuracy']:.1f}% | {100 * balanced_accuracy(m['confusion_song']):.1f}% "
                f"| {100 * m['train']['window_accuracy']:.1f}% | {m['train_seconds']} s |"
                for name, m in (("Baseline (FC + Bi-LSTM)", b), ("Ours (Temporal Conv + Bi-LSTM)", c))
            ],
            "",
            "The paper's Table 2 (its own 35.7 h of music, two styles, accuracy): baseline 88.0%, ours 92.1%. With "
            f"{len(split['test'])} test songs here, one song is {100 / max(1, len(split['test'])):.1f} points "
            "of song accuracy: the numbers are indicative only.",
            "",
            "### Confusion by window, ours",
            "",
            *confusion(c["confusion_window"]),
            "",
            "### Confusion by window, baseline",
            "",
            *confusion(b["confusion_window"]),
            "",
            "### By song",
            "",
            "| song | truth | ours | baseline |",
            "|---|---|---|---|",
            *[
                f"| {s} | {p['truth']} | {p['predicted']} ({p['p_truth']:.2f}) "
                f"| {b['predictions'][s]['predicted']} ({b['predictions'][s]['p_truth']:.2f}) |"
                for s, p in c["predictions"].items()
            ],
            "",
            "(In brackets: the probability given to the true style.)",
            "",
        ]

    def _limits(self) -> list[str]:
        """What the figures do not promise."""
        c, b, minority, common, few = self.c, self.b, self.minority, self.common, self.few
        return [
            "## Limits",
            "",
            f"Held-out songs of the styles other than {common}: ours gets {minority(c)}, the baseline "
            f"{minority(b)}. Ballroom styles differ mostly in tempo and metre, which the input spells out, but the "
            f"models have learnt from {few} songs per style apart from {common} and fit their training songs far "
            "better than new ones: treat the style as a suggestion that the user can override. The models know "
            "only the styles listed above. Beats per bar set waltz (3) apart; cha-cha, rumba and tango are all 4 "
            "beats a bar and told apart mostly by tempo, where the tracker's tempo of a rumba is anywhere from 70 "
            "to 190 bpm (it often counts the beat at 1.5 or 2 times its speed): a rumba tracked at tango's tempo "
            "(as the test rumba here, 130 bpm; the tangos are at 125-128 bpm) is taken for a tango, and so are "
            "many windows of a cha-cha at the top of its range (125 bpm).",
            "",
        ]


def motion_style_card(model: MotionStyleModel, train: Sequence[Dance], test: Sequence[Dance], split: dict) -> str:
    """Markdown: data, split, settings, held-out accuracy by segment and by dance, confusions."""
    m, meta, styles = model.meta["metrics"], model.meta, model.styles

    def minutes(ds: Sequence[Dance], st: str) -> str:
        chosen = [d for d in ds if d.style == st]
        return f"{len(chosen)} ({sum(len(d.positions) for d in chosen) / FPS / 60:.1f} min)"

    majority = max(sum(r) for r in m["confusion_segment"]) / sum(map(sum, m["confusion_segment"]))
    return "\n".join([
        "# Motion style classifier model card",
        "",
        "Dance-style classifier on motion (`dancenet_core/evaluation/motion_style.py`, weights `motion_style.pt`): the "
        "feature extractor of the paper's FID (its embedding, the Bi-LSTM output averaged over time, "
        f"{model.embedding_size} numbers) and the judge of style consistency. Trained by "
        "`dancenet train motion-style`.",
        "",
        "## Data",
        "",
        "Dance with Melody captures fitted to each performer's skeleton (the paired dataset of `dancenet data "
        f"build`), the 22 body joints' world positions at {FPS:g} fps, in {model.segment_s:g}-second segments, "
        "moved onto one body (each bone keeps its direction and takes our default skeleton's length; the "
        "root's path scales with the legs): each style here was danced by its own performers, and a model "
        "that saw their own bodies learnt their sizes (perfect on held-out captures, wrong on the same dances "
        "on another skeleton). Input per frame: joints relative to the root in the "
        "dancer's heading frame, the root's velocity in that frame and its turning rate "
        f"({N_INPUTS} numbers; no height above the floor, so floating or sinking feet do not pass for a "
        "style), standardised with the training set's statistics. Split: the song split the whole "
        f"project uses (`song_split.json`, by song, stratified by style, seed {split['seed']}); styles only "
        "in excluded songs are not learnt "
        f"({', '.join(f'{s}: {why}' for s, why in split['excluded'].items()) or 'none'}).",
        "",
        "| style | train dances | test dances |",
        "|---|---|---|",
        *[f"| {st} | {minutes(train, st)} | {minutes(test, st)} |" for st in styles],
        "",
        "## Training",
        "",
        f"Adam, learning rate {meta['lr']:g} (divided by 10 for the last quarter), {meta['steps']} steps of "
        f"{meta['batch']} segments, seed {meta['seed']}, cross-entropy, one CPU thread: "
        f"{meta['train_seconds']} s. Each segment: a style drawn uniformly (waltz has most dances), then one "
        f"of its dances and a random crop, time-stretched by up to +-{100 * MOTION_AUG_TEMPO:g}% and mirrored "
        f"left/right half the time. Network: Conv1d {N_INPUTS}-{model.config['channels']} "
        f"x3 (kernel 5, strides 1-2-2, BatchNorm, ReLU), Bi-LSTM of {model.config['hidden']} units each way, "
        f"mean over time, dropout {model.config['dropout']:g}, FC. No validation split, no early stopping: "
        "the last step is shipped.",
        "",
        "## Held-out results (test split)",
        "",
        f"Segments every {HOP_S:g} s over each test dance; a dance's style is the mean of its segments' "
        "probabilities.",
        "",
        "| | segment accuracy | balanced (mean recall) | dance accuracy | train segment accuracy |",
        "|---|---|---|---|---|",
        f"| always the most common style | {100 * majority:.1f}% | {100 / len(styles):.1f}% | - | - |",
        f"| this model | {100 * m['segment_accuracy']:.1f}% | {100 * m['segment_balanced_accuracy']:.1f}% "
        f"| {100 * m['dance_accuracy']:.1f}% | {100 * meta['train_metrics']['segment_accuracy']:.1f}% |",
        "",
        "### Confusion by segment",
        "",
        *_confusion(styles, m["confusion_segment"]),
        "",
        "### By dance",
        "",
        "| dance | truth | predicted (p of truth) | segments right |",
        "|---|---|---|---|",
        *[f"| {k} | {p['truth']} | {p['predicted']} ({p['p_truth']:.2f}) | {p['segments_right']} of {p['segments']} |"
          for k, p in m["predictions"].items()],  # fmt: skip
        "",
        "## Limits",
        "",
        f"{len(test)} held-out dances, some styles with one each: the accuracy is indicative, and since each "
        "style comes from its own performers, a performer's personal way of moving (not only the style) may "
        "be part of what it recognises; body size and proportions are not. The model knows "
        "only the styles above, and only motion like our captures (one dancer, ballroom, fitted skeleton). "
        "Generated dances that drift from real motion can land anywhere in its embedding: that is what the "
        "FID measures.",
        "",
    ])  # fmt: skip


def write_motion_style_card(weights: Path = MOTION_STYLE_WEIGHTS) -> Path:
    """Rewrite the model card beside `weights` from the metrics stored in it (no retraining)."""
    model = MotionStyleModel.load(weights)
    if "metrics" not in model.meta:
        raise DanceNetError(f"{weights} has no held-out metrics; train it with `dancenet train motion-style`")
    train, test, split = load_dances()
    card = weights.with_name(MODEL_CARD.name)
    write_text(card, motion_style_card(model, train, test, split))
    return card


VALIDATION_HEADING = "## Settings chosen on the validation songs (`dancenet validate`)"


def kept_sections(card: Path, heading: str = VALIDATION_HEADING) -> list[str]:
    """The measured tables of an existing card, from `heading` to its end, verbatim: they come from runs (`dancenet
    validate`, `dancenet evaluate`, a library's checks) that the card command does not repeat, so a rewritten card
    keeps them, and the card stays their one home."""
    if not card.is_file():
        return []
    text = card.read_text()
    at = text.find("\n" + heading + "\n")
    return [] if at < 0 else ["", text[at + 1:].rstrip("\n")]


LIBRARY_CARD = DEFAULT_LIBRARY.with_name("CMU_LIBRARY_CARD.md")
LIBRARY_MEASURED_HEADING = "## Measured (kept when the card is written again)"


def library_card(library: MotionLibrary, size_bytes: int, kept: Sequence[str] = ()) -> str:
    """Markdown: what the shipped motion library holds, read from its arrays (clips, minutes, styles, the tempi and
    meters its build read, the skeletons it read them from), how it is built and its terms; `kept`: the measured
    sections of the card it replaces (`kept_sections` with `LIBRARY_MEASURED_HEADING`)."""
    minutes = np.diff(library.clip_starts) / library.fps / 60
    assumed = np.array([s.startswith("tempo: assumed") for s in library.source])
    rows = []
    for style in sorted(set(library.styles)):
        c = np.array([s == style for s in library.styles])
        meters = Counter(int(m) for m in library.meter[c])
        rows.append(f"| {style} | {c.sum()} | {minutes[c].sum():.1f} | {library.tempo_bpm[c].min():.0f}-"
                    f"{library.tempo_bpm[c].max():.0f} | {', '.join(f'{m}/4: {n}' for m, n in sorted(meters.items()))} "
                    f"| {assumed[c].sum()} |")
    skeletons = Counter(library.skeletons) if library.skeletons else Counter({"-": library.num_clips})
    height = float(np.ptp(library.skeleton.rest_positions()[:, 1]))
    return "\n".join([
        "# Shipped motion library card",
        "",
        f"`{DEFAULT_LIBRARY.name}` ({size_bytes / 1e6:.1f} MB, `{LIBRARY_VERSION}`): the clips the motion-library "
        "engine dances when a user names no library of their own (`dancenet generate SONG --engine library`, the "
        "add-on's Motion Library engine with the shipped library). Not trained: built from capture by `python "
        "scripts/build_default_library.py` (from `$DANCENET_DATA/cmu_dance`; never at run time, nothing is "
        "downloaded), which gives the same bytes every time. This card is written from the file by `dancenet card "
        "library`.",
        "",
        "## Data",
        "",
        f"{library.num_clips} dance trials of the CMU Motion Capture Database (mocap.cs.cmu.edu), "
        f"{minutes.sum():.1f} minutes at {library.fps:g} fps, {len(library.beats)} beats; each clip's style is the "
        "dance CMU's index gives its subject. Only the built arrays ship (rotations as float16, compressed), no "
        "BVH file.",
        "",
        "| style | clips | minutes | tempo read (BPM) | meter | tempo assumed |",
        "|---|---|---|---|---|---|",
        *rows,
        "",
        "## Build",
        "",
        "Read as a user's folder of the same clips is (`dancenet library build`): each skeleton through the bone "
        f"mapper ({', '.join(f'{k}: {n}' for k, n in sorted(skeletons.items()))} clips), onto a dancer "
        f"{height:.2f} m tall at rest (the clips' mean bones), at {library.fps:g} fps, each on the floor under "
        "the body's lowest point. Each clip's tempo and beats are read from its motion, its meter from the motion "
        "or its style's; a clip too short to read takes the library's tempo (\"tempo assumed\"). Clips whose "
        "tempo the analysis is unsure of (confidence under 0.25): "
        f"{int((library.confidence < 0.25).sum())} of {library.num_clips}.",
        "",
        "## Terms",
        "",
        "CMU's: free for all uses, in products sold commercially too, but the data may not be resold as motion "
        "capture, even converted. The copies it was built from appear to be AMASS conversions (AMASS: "
        "non-commercial research only), so the commercial mode does not dance it (docs/licence.md, `NOTICE`).",
        "",
        "## Limits",
        "",
        "Few styles, most of its minutes salsa; the dances it makes are the clips' own figures cut on the song's "
        "bars, so a style it lacks is danced with the nearest it has. A library of one's own clips (any humanoid "
        "skeleton, BVH or FBX: docs/library.md) replaces it.",
        *kept,
        "",
    ])


def write_library_card(path: Path = DEFAULT_LIBRARY) -> Path:
    """Write the shipped library's card beside it from its arrays, keeping the card's measured sections."""
    try:
        library = MotionLibrary.load(path)
    except ValueError as e:
        raise DanceNetError(f"{e}; rebuild it with python scripts/build_default_library.py") from e
    card = path.with_name(LIBRARY_CARD.name)
    write_text(card, library_card(library, path.stat().st_size, kept_sections(card, LIBRARY_MEASURED_HEADING)))
    return card


def validation_sections(folder: Path | None) -> list[str]:
    """The card's validation table and learning curve, from `dancenet validate` outputs in `folder`."""
    if folder is None:
        return []
    lines = []
    if (folder / "validation.md").is_file():
        lines += ["", VALIDATION_HEADING, "", (folder / "validation.md").read_text().strip()]
    curve = folder / "learning_curve.json"
    if curve.is_file():
        c = json.loads(curve.read_text())
        lines += ["", f"## Learning curve (`dancenet validate --curve`, temperature {c['temperature']}, foot model on)",
                  "", "![learning curve](../../docs/learning_curve.png)", "",
                  "| step | minutes | validation loss | FID_k (validation songs) | joint speed m/s | root extent m |",
                  "|---|---|---|---|---|---|"]
        for p in c["points"]:
            loss = "-" if p["val_loss"] is None else f"{p['val_loss']:.3f}"
            lines.append(f"| {p['step']} | {p['minutes']} | {loss} | {p['fid_k']:.1f} | "
                         f"{p['joint_speed_m_s']:.3f} | {p['root_extent_m']:.2f} |")
        lines.append(f"\nReal validation dances: FID_k {c['real_fid_k']:.1f} against the same training dances.")
    return lines


def _dancenet_facts(bundle: DanceNetBundle) -> list[str]:
    """The card's title, data and settings: the bundle's training facts."""
    info, cfg = bundle.info, bundle.model.cfg
    return [
        "# DanceNet model card",
        "",
        f"Weights: `dancenet.pt` ({sum(p.numel() for p in bundle.model.parameters()):,} parameters). "
        "Generated by `dancenet train dancenet`; figures below by `dancenet card dancenet --card`.",
        "",
        "## Data",
        f"- {info.get('data')}; {info.get('train_minutes', 0):.1f} minutes of training motion "
        f"({len(info.get('train_sequences', []))} sequences), mirrored copies added (same music).",
        f"- Styles: {', '.join(cfg.styles)}. Left out: "
        + (", ".join(f"{k} ({v})" for k, v in info.get("styles_left_out", {}).items()) or "none") + ".",
        "- Minutes of training motion per style: "
        + ", ".join(f"{k} {v:.1f}" for k, v in info.get("minutes_per_style", {}).items()) + ".",
        f"- Test sequences (never trained on): {', '.join(info.get('test_sequences', []))}.",
        f"- Validation sequences (training songs left out of training; settings chosen on them): "
        f"{', '.join(info.get('validation_sequences', [])) or 'none'}.",
        f"- Started from: {info.get('init') or 'random initialisation'}.",
        f"- {info.get('windows', 0)} training windows of {cfg.music_window} frames (stride 3), k-means "
        f"clusters of sizes {info.get('cluster_sizes')}, sampled so each cluster weighs the same.",
        "",
        "## Settings",
        f"- {cfg.fps:g} fps; {cfg.layers} gated residual layers, dilations {cfg.dilations[:cfg.dilation_cycle]} "
        f"repeated, receptive field {cfg.receptive_field} frames ({cfg.receptive_field / cfg.fps:.1f} s); "
        f"residual {cfg.residual_channels}, skip {cfg.skip_channels}, motion encoder {cfg.motion_channels} "
        f"channels; music code {cfg.music_code}, style embedding {cfg.style_dim}; a mixture of {cfg.mixtures} "
        f"Gaussian(s), sampled by drawing a component by its weight, then sigma x temperature within it.",
        f"- RMSprop, lr {info['settings']['lr']} dropped by 10 at 77% of the run, batch {info['settings']['batch']}, "
        f"input dropout {cfg.input_dropout}, noise 0.04 on inputs and 0.01 on targets, gradient clip 10, "
        f"seed {info['settings']['seed']}.",
        f"- Trained {info.get('steps')} steps in {info.get('train_seconds', 0) / 60:.1f} minutes on "
        f"{info.get('device', 'a 2-core CPU')}"
        + (f"{', travel loss weight ' + format(info['settings']['travel_weight'], 'g')}"
           if info["settings"].get("travel_weight") else "") + ".",
        *([f"- Shipped as a blend (`dancenet train blend`): {1 - info['blend']['alpha']:g} x "
           f"`{info['blend']['start']}` (step {info['blend']['start_steps']}) + {info['blend']['alpha']:g} x "
           f"`{info['blend']['end']}` (step {info['blend']['end_steps']}), weight by weight."]
          if "blend" in info else []),
        "",
    ]


def _foot_sections(footfix_info: dict | None) -> list[str]:
    """The foot clean-up, and the Foot Constraint Model's figures where its training facts are given."""
    lines = [
        "",
        "## Foot clean-up",
        "Every dance is stood on the floor from its predicted contacts (the root's height only, frame by frame). "
        + ("The clean-up holds each foot where it stands through each contact the model predicts, and wherever it "
           f"leaves a foot still on the floor (within {GROUND_M * 100:g} cm of it, slower than {STILL_MPS:g} m/s), the "
           "legs reaching it by two-bone IK (hip and knee; the foot's own turn, the path and the upper body kept); "
           "no training."
           if FOOT_CLEANUP == "lock" else f"The clean-up is `{FOOT_CLEANUP}` (`engines/dancenet.py`).")
        + " Chosen on the validation songs among the contact lock, the Foot Constraint Model and both "
          "(`dancenet validate --cleanup`; docs/experiments.md).",
        "",
        "## Beat lock",
        "Each dance is time-warped, ahead of the foot clean-up, so that its kinematic beats (the Beat Align Score's) "
        f"land on the song's beats, no frame more than {WARP_RANGE:.0%} faster or slower than sampled "
        "(`shaping/beatlock.py`; on by default, `--no-beat-lock` or the panel's Beat Lock off). The test metrics "
        "above are measured with it, as generation dances, and without it in their last column. It aims at the "
        "tracked beats that the Beat Align Score is measured against (a user's song gives them too), so the score "
        "measures the retiming, not the model.",
    ]
    if footfix_info:
        lines += [
            "",
            "## Foot Constraint Model (`footfix.pt`"
            + ("" if "model" in FOOT_CLEANUP else ", not the default clean-up: `dancenet validate --cleanup model`")
            + ")",
            f"Test MSE on simulated sliding (normalised lower-body channels): ours (temporal conv) "
            f"{footfix_info['ours']['test_mse']:.4f}, baseline (FC + LSTM + FC) "
            f"{footfix_info['baseline_lstm']['test_mse']:.4f}, "
            f"uncorrected {footfix_info['ours']['test_mse_without_model']:.4f}.",
            f"- Trained {footfix_info['steps']} steps with sliding weight "
            f"{footfix_info['contact_weights']['slide_weight']:g} on {footfix_info['dancenet_dances']} of "
            "DanceNet's dances to the training songs; it corrects the legs and the pelvis' height and tilt, "
            "never the root's travel (docs/experiments.md: its sweeps of the sliding weight on the validation songs).",
        ]
    return lines


def dancenet_card(bundle: DanceNetBundle, raw: dict, cleaned: dict, unlocked: dict, footfix_info: dict | None,
                  extra: list[str] | None = None) -> str:
    """The DanceNet model card, from the bundle's training facts, this run's measurements on the test split
    (`evaluate_on_test_split`: beat-locked without and with the foot clean-up, and cleaned without the beat lock)
    and `extra` sections (validation, learning curve)."""
    info = bundle.info
    real, gen = raw["summary"]["real"], raw["summary"]["generated"]
    fixed, free = cleaned["summary"]["generated"], unlocked["summary"]["generated"]
    held = "val" if "val_loss" in info else "test"
    held_name = "validation songs" if held == "val" else "test songs"
    lines = _dancenet_facts(bundle) + [
        "## Test metrics",
        f"{held.capitalize()} loss (mixture NLL per modelled channel + 0.1 x contact BCE): "
        f"{info.get(f'{held}_loss', float('nan')):.3f} (NLL {info.get(f'{held}_nll', float('nan')):.3f}, "
        f"BCE {info.get(f'{held}_bce', float('nan')):.3f}), on the {held_name}.",
        "",
        f"Generated (temperature {raw['temperature']}, seed {raw['seed']}) vs real dances on the same "
        "music spans of the test sequences, one take each; Beat Align Score with sigma 50 ms (Bailando's 3 frames "
        "at 60 fps). Generation's defaults are the third column: the beat lock and the foot clean-up.",
        "",
        f"| metric | real | generated, beat lock | + foot clean-up ({FOOT_CLEANUP}) | foot clean-up, no beat lock |",
        "|---|---|---|---|---|",
    ]
    for key in ("beat_align_score", "rhythm_hit_rate", "foot_slide_ratio", "foot_slide_m_per_contact_frame",
                "contact_ratio", "min_lowest_toe_m", "max_lowest_toe_m", "floor_reach", "jitter_m_s2",
                "joint_speed_m_s", "longest_freeze_s", "max_longest_freeze_s", "root_extent_m"):
        lines.append(f"| {key} | {real[key]:.4f} | {gen[key]:.4f} | {fixed[key]:.4f} | {free[key]:.4f} |")
    lines += [
        "",
        "- contact_ratio: share of toe frames within 5 cm of the dance's floor; min/max_lowest_toe_m: each dance's "
        "lowest toe (floor at y = 0), lowest and highest over the dances; floor_reach: share of 2-s windows whose "
        "lowest toe end comes within 1.5 cm of the floor; max_longest_freeze_s: worst dance.",
        f"- Beat Align Score, generated / real: {fixed['beat_align_score'] / real['beat_align_score']:.2f} "
        f"({free['beat_align_score'] / real['beat_align_score']:.2f} without the beat lock).",
        f"- Foot sliding, generated / real: {fixed['foot_slide_ratio'] / max(real['foot_slide_ratio'], 1e-9):.2f} "
        f"({gen['foot_slide_ratio'] / max(real['foot_slide_ratio'], 1e-9):.2f} without the foot clean-up).",
        f"- Longest freeze over all test dances: {fixed['max_longest_freeze_s']:.2f} s; largest distance from the "
        f"start: {fixed['max_root_extent_m']:.2f} m.",
        f"- Foot-contact accuracy of DanceNet's predictions against contacts detected on the real dance at the "
        f"same frames: {fixed['contact_accuracy']:.3f} (a different dance, so this is agreement, not error).",
    ]
    return "\n".join(lines + _foot_sections(footfix_info) + (extra or [])) + "\n"

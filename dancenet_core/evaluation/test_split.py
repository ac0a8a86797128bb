"""Generated vs real dances on the test-split songs: the figures in the model cards and the notes.

For each test sequence, DanceNet dances to the same span of the song the real dancer danced to (the
music features at the motion's frames), in the sequence's style, from the sequence's first frame; both
dances are then measured the same way.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..data.build import PairedSequence, build_dataset
from ..data.dance_with_melody import read_manifest
from ..data.pack import read_pack
from ..data.split import load_split
from ..engines.dancenet import FOOT_CLEANUP, OUTPUT_SMOOTHING_FRAMES, clean_feet, finish_frames, lock_beats
from ..motion import Motion
from ..music.features import analyze_music
from ..nets.bundle import DanceNetBundle
from ..nets.variants import sample_normalized
from ..representation import FeatureLayout, decode
from ..skeleton import BODY_JOINTS, TOE_ENDS
from .metrics import (
    beat_align_score,
    floor_reach,
    foot_sliding,
    jitter,
    longest_freeze_s,
    mean_joint_speed,
    rhythm_hit_rate,
    root_extent_m,
)


def dance_metrics(motion: Motion, beats_s: np.ndarray) -> dict[str, float]:
    body = motion.positions()[:, :BODY_JOINTS]
    ends = motion.end_effectors()
    slide = foot_sliding(ends[:, list(TOE_ENDS)], motion.fps)
    return {
        "beat_align_score": beat_align_score(body, motion.fps, beats_s),
        "rhythm_hit_rate": rhythm_hit_rate(body, motion.fps, beats_s),
        "foot_slide_ratio": slide.slide_ratio,
        "foot_slide_m_per_contact_frame": slide.mean_slide_m,
        "contact_ratio": slide.contact_ratio,
        "lowest_toe_m": float(ends[:, list(TOE_ENDS), 1].min()),
        "floor_reach": floor_reach(ends[:, list(TOE_ENDS), 1].min(axis=1), motion.fps),
        "jitter_m_s2": jitter(body, motion.fps),
        "longest_freeze_s": longest_freeze_s(body, motion.fps),
        "root_extent_m": root_extent_m(motion.root_positions),
        "joint_speed_m_s": mean_joint_speed(body, motion.fps),
    }


def generate_for_pair(bundle: DanceNetBundle, pair: PairedSequence, seed: int, temperature: float,
                      footfix: bool, smoothing: float | None = None,
                      footfix_weights: Path | None = None, cleanup: str = FOOT_CLEANUP,
                      beats_s: np.ndarray | None = None) -> tuple[Motion, np.ndarray]:
    """The bundle's model's dance to a test sequence's music span, from the real dance's first frame, locked to
    the song's beats `beats_s` (dance time, s) when given (`engines.dancenet.lock_beats`), its feet cleaned by
    `cleanup` when `footfix` (`engines.dancenet.clean_feet`; on the floor either way); returns the motion and
    predicted contacts. `footfix_weights`: a foot model other than the shipped one."""
    cfg = bundle.model.cfg
    style = pair.style if pair.style in bundle.styles else bundle.styles[0]
    first = bundle.normalizer.normalize(pair.motion[:1])[0]
    frames = sample_normalized(bundle.model, pair.music, bundle.styles.index(style), first, temperature,
                               np.random.default_rng(seed))
    feats = finish_frames(bundle, frames, OUTPUT_SMOOTHING_FRAMES if smoothing is None else smoothing)
    if beats_s is not None:
        feats = lock_beats(bundle, feats, beats_s)
    feats = clean_feet(bundle, feats, cleanup if footfix else None, footfix_weights)
    layout = FeatureLayout.for_skeleton(bundle.skeleton)
    return decode(feats, cfg.fps, bundle.skeleton), feats[:, layout.contacts]


def split_with_beats(
    data_dir: Path, part: str = "test", pack: Path | None = None
) -> tuple[dict, dict[str, PairedSequence], dict[str, np.ndarray]]:
    """The song split, every paired sequence by id, and the music beats in dance time (s) of each sequence of
    `part` of the split ("test" or "validation"); from a training pack (`dancenet data pack`) instead of the
    data folder when one is given (its validation songs, on a machine without madmom)."""
    split = load_split()
    if pack:
        pairs, beats = read_pack(pack)
        return split, {p.seq: p for p in pairs}, {s: beats[s] for s in split.get(part, [])}
    pairs = {p.seq: p for p in build_dataset(data_dir, progress=False)}
    seqs = {s.seq: s for s in read_manifest(data_dir)}
    beats = {s: analyze_music(seqs[s].audio).beat_times - seqs[s].music_offset_s for s in split.get(part, [])}
    return split, pairs, beats


def evaluate_on_test_split(bundle: DanceNetBundle, data_dir: Path, temperature: float, seed: int = 0,
                           footfix: bool = False, beat_lock: bool = True) -> dict:
    """Metrics of real and generated dances on every test-split sequence of a style the model knows (locked to
    the song's beats when `beat_lock`, as generation dances)."""
    split, pairs, beats = split_with_beats(data_dir)
    layout = FeatureLayout.for_skeleton(bundle.skeleton)
    rows = []
    for seq_id in split["test"]:
        pair = pairs[seq_id]
        if pair.style not in bundle.styles:
            continue
        real = decode(pair.motion, 25.0, bundle.skeleton)
        gen, contacts = generate_for_pair(bundle, pair, seed, temperature, footfix,
                                          beats_s=beats[seq_id] if beat_lock else None)
        acc = float((contacts == pair.motion[: len(contacts), layout.contacts]).mean())
        rows.append({"seq": seq_id, "style": pair.style, "real": dance_metrics(real, beats[seq_id]),
                     "generated": dance_metrics(gen, beats[seq_id]), "contact_accuracy": acc})
    keys = rows[0]["real"].keys()
    summary = {
        kind: {k: float(np.mean([r[kind][k] for r in rows])) for k in keys} for kind in ("real", "generated")
    }
    for kind in ("real", "generated"):
        summary[kind]["max_longest_freeze_s"] = max(r[kind]["longest_freeze_s"] for r in rows)
        summary[kind]["min_lowest_toe_m"] = min(r[kind]["lowest_toe_m"] for r in rows)
        summary[kind]["max_lowest_toe_m"] = max(r[kind]["lowest_toe_m"] for r in rows)
    summary["generated"]["contact_accuracy"] = float(np.mean([r["contact_accuracy"] for r in rows]))
    summary["generated"]["max_root_extent_m"] = max(r["generated"]["root_extent_m"] for r in rows)
    return {"temperature": temperature, "seed": seed, "footfix": footfix, "beat_lock": beat_lock, "summary": summary,
            "per_sequence": rows}

"""Generated vs real dances on the test-split songs: the figures in the model cards and the notes.

For each test sequence, DanceNet dances to the same span of the song the real dancer danced to (the
music features at the motion's frames), in the sequence's style, from the sequence's first frame; both
dances are then measured the same way.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from .data.build import PairedSequence, build_dataset, default_data_dir, load_split
from .data.dance_with_melody import read_manifest
from .metrics import (
    beat_align_score,
    foot_sliding,
    jitter,
    longest_freeze_s,
    rhythm_hit_rate,
    root_extent_m,
)
from .motion import Motion
from .representation import FeatureLayout, decode
from .skeleton import JOINT_INDEX, TOE_ENDS


def dance_metrics(motion: Motion, beats_s: np.ndarray) -> dict[str, float]:
    pos = motion.positions()
    ends = motion.end_effectors()
    toes = ends[:, list(TOE_ENDS)]
    ankles = pos[:, [JOINT_INDEX["left_ankle"], JOINT_INDEX["right_ankle"]]]
    slide = foot_sliding(toes, ankles, motion.fps)
    return {
        "beat_align_score": beat_align_score(pos[:, :22], motion.fps, beats_s),
        "rhythm_hit_rate": rhythm_hit_rate(pos[:, :22], motion.fps, beats_s),
        "foot_slide_ratio": slide.slide_ratio,
        "foot_slide_m_per_contact_frame": slide.mean_slide_m,
        "contact_ratio": slide.contact_ratio,
        "jitter_m_s2": jitter(pos[:, :22], motion.fps),
        "longest_freeze_s": longest_freeze_s(pos[:, :22], motion.fps),
        "root_extent_m": root_extent_m(motion.root_positions),
    }


def generate_for_pair(bundle, pair: PairedSequence, seed: int, temperature: float,  # noqa: ANN001
                      footfix: bool) -> tuple[Motion, np.ndarray]:
    """DanceNet's dance to a test sequence's music span; returns the motion and predicted contacts."""
    from .footfix import shipped_fixer
    from .model.sampler import CachedSampler, Sampling, music_conditioning

    cfg = bundle.model.cfg
    style = pair.style if pair.style in bundle.styles else bundle.styles[0]
    cond = music_conditioning(bundle.model, pair.music, bundle.styles.index(style))
    first = bundle.normalizer.normalize(pair.motion[:1])
    frames, _ = CachedSampler(bundle.model).run(first, cond, Sampling(temperature, np.random.default_rng(seed)))
    feats = bundle.normalizer.denormalize(frames[0])
    if footfix:
        feats = shipped_fixer()(feats)
    layout = FeatureLayout.for_skeleton(bundle.skeleton)
    return decode(feats, cfg.fps, bundle.skeleton), feats[:, layout.contacts]


def evaluate(bundle, data_dir: Path, temperature: float, seed: int = 0,  # noqa: ANN001
             footfix: bool = False) -> dict:
    """Metrics of real and generated dances on every test-split sequence of a style the model knows."""
    from .features import analyze_music

    split = load_split()
    pairs = {p.seq: p for p in build_dataset(data_dir, progress=False)}
    seqs = {s.seq: s for s in read_manifest(data_dir)}
    rows = []
    for seq_id in split["test"]:
        pair = pairs[seq_id]
        if pair.style not in bundle.styles:
            continue
        seq = seqs[seq_id]
        beats = analyze_music(seq.audio).beat_times - seq.music_offset_s
        real = decode(pair.motion, 25.0, bundle.skeleton)
        gen, contacts = generate_for_pair(bundle, pair, seed, temperature, footfix)
        layout = FeatureLayout.for_skeleton(bundle.skeleton)
        acc = float((contacts == pair.motion[: len(contacts), layout.contacts]).mean())
        rows.append({"seq": seq_id, "style": pair.style, "real": dance_metrics(real, beats),
                     "generated": dance_metrics(gen, beats), "contact_accuracy": acc})
    keys = rows[0]["real"].keys()
    summary = {
        kind: {k: float(np.mean([r[kind][k] for r in rows])) for k in keys} for kind in ("real", "generated")
    }
    summary["generated"]["contact_accuracy"] = float(np.mean([r["contact_accuracy"] for r in rows]))
    summary["generated"]["max_longest_freeze_s"] = max(r["generated"]["longest_freeze_s"] for r in rows)
    summary["generated"]["max_root_extent_m"] = max(r["generated"]["root_extent_m"] for r in rows)
    return {"temperature": temperature, "seed": seed, "footfix": footfix, "summary": summary, "per_sequence": rows}


def main(argv: list[str] | None = None) -> None:
    from .generate import DEFAULT_TEMPERATURE
    from .model.bundle import DEFAULT_BUNDLE, DanceNetBundle

    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--weights", type=Path, default=DEFAULT_BUNDLE)
    p.add_argument("--data", type=Path, default=None)
    p.add_argument("--temperature", type=float, default=DEFAULT_TEMPERATURE)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--footfix", action="store_true")
    p.add_argument("--json", type=Path, default=None)
    args = p.parse_args(argv)
    result = evaluate(DanceNetBundle.load(args.weights), args.data or default_data_dir(), args.temperature,
                      args.seed, args.footfix)
    text = json.dumps(result, indent=1)
    if args.json:
        args.json.write_text(text + "\n")
    print(json.dumps(result["summary"], indent=1))


if __name__ == "__main__":
    main()

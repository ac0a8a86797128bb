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

from .atomic import write_text
from .data.build import PairedSequence, build_dataset, default_data_dir, load_split
from .data.dance_with_melody import read_manifest
from .metrics import (
    beat_align_score,
    foot_sliding,
    jitter,
    longest_freeze_s,
    mean_joint_speed,
    rhythm_hit_rate,
    root_extent_m,
)
from .motion import Motion
from .representation import FeatureLayout, decode
from .skeleton import TOE_ENDS


def dance_metrics(motion: Motion, beats_s: np.ndarray) -> dict[str, float]:
    pos = motion.positions()
    ends = motion.end_effectors()
    slide = foot_sliding(ends[:, list(TOE_ENDS)], motion.fps)
    return {
        "beat_align_score": beat_align_score(pos[:, :22], motion.fps, beats_s),
        "rhythm_hit_rate": rhythm_hit_rate(pos[:, :22], motion.fps, beats_s),
        "foot_slide_ratio": slide.slide_ratio,
        "foot_slide_m_per_contact_frame": slide.mean_slide_m,
        "contact_ratio": slide.contact_ratio,
        "lowest_toe_m": float(ends[:, list(TOE_ENDS), 1].min()),
        "jitter_m_s2": jitter(pos[:, :22], motion.fps),
        "longest_freeze_s": longest_freeze_s(pos[:, :22], motion.fps),
        "root_extent_m": root_extent_m(motion.root_positions),
        "joint_speed_m_s": mean_joint_speed(pos[:, :22], motion.fps),
    }


def generate_for_pair(bundle, pair: PairedSequence, seed: int, temperature: float,  # noqa: ANN001
                      footfix: bool, smoothing: float | None = None) -> tuple[Motion, np.ndarray]:
    """The bundle's model's dance to a test sequence's music span, from the real dance's first frame;
    returns the motion and predicted contacts."""
    from .footfix import shipped_fixer
    from .generate import OUTPUT_SMOOTHING_FRAMES, finish_frames
    from .model.variants import sample_normalized

    cfg = bundle.model.cfg
    style = pair.style if pair.style in bundle.styles else bundle.styles[0]
    first = bundle.normalizer.normalize(pair.motion[:1])[0]
    frames = sample_normalized(bundle.model, pair.music, bundle.styles.index(style), first, temperature,
                               np.random.default_rng(seed))
    feats = finish_frames(bundle, frames, OUTPUT_SMOOTHING_FRAMES if smoothing is None else smoothing)
    if footfix:
        feats = shipped_fixer()(feats)
    layout = FeatureLayout.for_skeleton(bundle.skeleton)
    return decode(feats, cfg.fps, bundle.skeleton), feats[:, layout.contacts]


def split_with_beats(
    data_dir: Path, part: str = "test"
) -> tuple[dict, dict[str, PairedSequence], dict[str, np.ndarray]]:
    """The song split, every paired sequence by id, and the music beats in dance time (s) of each sequence of
    `part` of the split ("test" or "validation")."""
    from .features import analyze_music

    split = load_split()
    pairs = {p.seq: p for p in build_dataset(data_dir, progress=False)}
    seqs = {s.seq: s for s in read_manifest(data_dir)}
    beats = {s: analyze_music(seqs[s].audio).beat_times - seqs[s].music_offset_s for s in split.get(part, [])}
    return split, pairs, beats


def evaluate(bundle, data_dir: Path, temperature: float, seed: int = 0,  # noqa: ANN001
             footfix: bool = False) -> dict:
    """Metrics of real and generated dances on every test-split sequence of a style the model knows."""
    split, pairs, beats = split_with_beats(data_dir)
    layout = FeatureLayout.for_skeleton(bundle.skeleton)
    rows = []
    for seq_id in split["test"]:
        pair = pairs[seq_id]
        if pair.style not in bundle.styles:
            continue
        real = decode(pair.motion, 25.0, bundle.skeleton)
        gen, contacts = generate_for_pair(bundle, pair, seed, temperature, footfix)
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
    return {"temperature": temperature, "seed": seed, "footfix": footfix, "summary": summary, "per_sequence": rows}


def validation_sections(folder: Path | None) -> list[str]:
    """The card's validation table and learning curve, from `dancenet validate` outputs in `folder`."""
    if folder is None:
        return []
    lines = []
    if (folder / "validation.md").is_file():
        lines += ["", "## Settings chosen on the validation songs (`dancenet validate`)", "",
                  (folder / "validation.md").read_text().strip()]
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


def model_card(bundle, before: dict, after: dict | None, footfix_info: dict | None,  # noqa: ANN001
               extra: list[str] | None = None) -> str:
    """The DanceNet model card, from the bundle's training facts, this run's measurements and `extra`
    sections (validation, learning curve)."""
    info, cfg = bundle.info, bundle.model.cfg
    real, gen = before["summary"]["real"], before["summary"]["generated"]
    held = "val" if "val_loss" in info else "test"
    held_name = "validation songs" if held == "val" else "test songs"
    lines = [
        "# DanceNet model card",
        "",
        f"Weights: `dancenet.pt` ({sum(p.numel() for p in bundle.model.parameters()):,} parameters). "
        "Generated by `python -m dancenet_core.train`; figures below by `python -m dancenet_core.evaluation "
        "--card`.",
        "",
        "## Data",
        f"- {info.get('data')}; {info.get('train_minutes', 0):.1f} minutes of training motion "
        f"({len(info.get('train_sequences', []))} sequences), mirrored copies added (same music).",
        f"- Styles: {', '.join(cfg.styles)}. Left out: "
        + ", ".join(f"{k} ({v})" for k, v in info.get("styles_left_out", {}).items()) + ".",
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
        f"- Trained {info.get('steps')} steps in {info.get('train_seconds', 0) / 60:.0f} minutes on a 2-core CPU.",
        "",
        "## Test metrics",
        f"{held.capitalize()} loss (mixture NLL per modelled channel + 0.1 x contact BCE): "
        f"{info.get(f'{held}_loss', float('nan')):.3f} (NLL {info.get(f'{held}_nll', float('nan')):.3f}, "
        f"BCE {info.get(f'{held}_bce', float('nan')):.3f}), on the {held_name}.",
        "",
        f"Generated (temperature {before['temperature']}, seed {before['seed']}) vs real dances on the same "
        "music spans of the test sequences; Beat Align Score with sigma 50 ms (Bailando's 3 frames at 60 fps):",
        "",
        "| metric | real | generated | generated + foot model |",
        "|---|---|---|---|",
    ]
    fixed = after["summary"]["generated"] if after else {}
    for key in ("beat_align_score", "rhythm_hit_rate", "foot_slide_ratio", "foot_slide_m_per_contact_frame",
                "contact_ratio", "min_lowest_toe_m", "max_lowest_toe_m", "jitter_m_s2", "longest_freeze_s",
                "max_longest_freeze_s", "root_extent_m"):
        lines.append(f"| {key} | {real[key]:.4f} | {gen[key]:.4f} | {fixed.get(key, float('nan')):.4f} |")
    lines += [
        "",
        "- contact_ratio: share of toe frames within 5 cm of the dance's floor; min/max_lowest_toe_m: each dance's "
        "lowest toe (floor at y = 0), lowest and highest over the dances; max_longest_freeze_s: worst dance.",
        f"- Beat Align Score, generated / real: {gen['beat_align_score'] / real['beat_align_score']:.2f}.",
        f"- Foot sliding before the foot model, generated / real: "
        f"{gen['foot_slide_ratio'] / max(real['foot_slide_ratio'], 1e-9):.2f}.",
        f"- Longest freeze over all test dances: {gen['max_longest_freeze_s']:.2f} s; largest distance from the "
        f"start: {gen['max_root_extent_m']:.2f} m.",
        f"- Foot-contact accuracy of DanceNet's predictions against contacts detected on the real dance at the "
        f"same frames: {gen['contact_accuracy']:.3f} (a different dance, so this is agreement, not error).",
    ]
    if footfix_info:
        lines += [
            "",
            "## Foot Constraint Model (`footfix.pt`)",
            f"Test MSE on simulated sliding (normalised lower-body channels): ours (temporal conv) "
            f"{footfix_info['ours']['test_mse']:.4f}, baseline (FC + LSTM + FC) "
            f"{footfix_info['baseline_lstm']['test_mse']:.4f}, "
            f"uncorrected {footfix_info['ours']['test_mse_without_model']:.4f}.",
        ]
    return "\n".join(lines + (extra or [])) + "\n"


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
    p.add_argument("--card", type=Path, default=None, help="write the model card (runs with and without footfix)")
    p.add_argument("--validation", type=Path, default=None,
                   help="folder of `dancenet validate` outputs to put in the card (validation table, learning curve)")
    args = p.parse_args(argv)
    bundle = DanceNetBundle.load(args.weights)
    data = args.data or default_data_dir()
    result = evaluate(bundle, data, args.temperature, args.seed, args.footfix)
    if args.json:
        write_text(args.json, json.dumps(result, indent=1) + "\n")
    print(json.dumps(result["summary"], indent=1))
    if args.card:
        from .checkpoint import load_weights
        from .footfix import WEIGHTS

        fixed = evaluate(bundle, data, args.temperature, args.seed, footfix=True)
        print(json.dumps({"with_footfix": fixed["summary"]["generated"]}, indent=1))
        ff = load_weights(WEIGHTS, "Foot Constraint Model weights", "train it")["info"] if WEIGHTS.is_file() \
            else None
        write_text(args.card, model_card(bundle, result, fixed, ff, validation_sections(args.validation)))


if __name__ == "__main__":
    main()

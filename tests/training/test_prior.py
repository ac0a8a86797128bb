"""The motion prior: DanceNet trained on the dances without music, in one style, then fine-tuned."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from test_pipeline import _tiny_dataset

from dancenet_core.nets.bundle import DanceNetBundle
from dancenet_core.training.configs import TrainSettings
from dancenet_core.training.dancenet import train
from dancenet_core.training.prior import PRIOR_STYLE, prior_sequences


def test_the_prior_is_silent_and_one_style_and_its_fine_tune_starts_from_it(tmp_path: Path) -> None:
    pairs, split = _tiny_dataset()
    silent = prior_sequences(pairs, tmp_path)  # a data folder without CMU clips: the dances alone
    assert [p.seq for p in silent] == [p.seq for p in pairs]
    assert all(p.style == PRIOR_STYLE and not p.music.any() and p.music.shape == q.music.shape
               for p, q in zip(silent, pairs, strict=True))
    assert all(np.array_equal(p.motion, q.motion) for p, q in zip(silent, pairs, strict=True))

    common = {"minutes": 5, "steps": 2, "batch": 2, "window": 100, "log_every": 1, "checkpoint_every": 2,
              "data": tmp_path}
    prior = DanceNetBundle.load(train(TrainSettings(out=tmp_path / "prior", motion_prior=True, **common),
                                      pairs, split))
    assert prior.styles == [PRIOR_STYLE] and "without music" in prior.info["data"]
    tuned = DanceNetBundle.load(train(TrainSettings(out=tmp_path / "tuned", init=tmp_path / "prior" / "dancenet.pt",
                                                    lr=0.0, **common), pairs, split))
    assert sorted(tuned.styles) == ["rumba", "waltz"]
    emb = tuned.model.style_embedding.weight
    assert torch.equal(emb[0], prior.model.style_embedding.weight[0]) and torch.equal(emb[0], emb[1])
    # Every other weight starts as the prior's, the normaliser too (a learning rate of 0 keeps the weights there;
    # batch norms' running statistics move with the batches).
    tuned_weights = dict(tuned.model.named_parameters())
    differ = [k for k, v in prior.model.named_parameters() if not torch.equal(v, tuned_weights[k])]
    assert differ == ["style_embedding.weight"]
    assert np.array_equal(tuned.normalizer.mean, prior.normalizer.mean)

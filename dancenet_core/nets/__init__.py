"""The torch side: the networks as training builds, trains and evaluates them. DanceNet (`dancenet`, with the
naive sampler the cached one is measured against), the weights bundle a checkpoint loads into (`bundle`), the
Foot Constraint Model (`footfix`), torch forward kinematics for it and for the skeleton fit
(`kinematics_torch`), the music style classifier's networks (`style_torch`), the comparison's ablations and
baselines (`variants`, `baselines`), and the export of checkpoints to the arrays generation runs (`export`).

Everything here needs torch; generation never imports it (import-linter holds this), except to convert a
training checkpoint (`.pt`) a user hands it. What a Generate Dance runs, in numpy, is `runtime/`."""

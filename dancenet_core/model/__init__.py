"""The trained networks, inference only: DanceNet and its cached sampler (`dancenet`, `sampler`), the
weights bundle generation loads (`bundle`), the Foot Constraint Model (`footfix`), torch forward
kinematics for it and for the skeleton fit (`kinematics_torch`), and the comparison's ablations and
baselines (`variants`, `baselines`). Training them is `training/`."""

"""Retarget a BVH clip from another rig onto our 55-joint skeleton by a joint-name map, fitted to the source's joint
positions: what the CMU dance clips of the training data go through.

The joint map, the source's world pose (metres, Y up), the performer skeleton and the start rotations (each
mapped joint given the source joint's world rotation) are `jointmap.py`'s, which needs no torch. This module adds
the fit: rotations such that our joints land on the source's joints (`data.fit.optimise_rotations`, the same fit
as the Dance with Melody markers). Positions leave the turn of end joints open (head, hands, feet), so each end
joint also gets two points that turn with the source joint; this, and the start of the fit, assume the source's
rest pose is, like ours, a Y-up T-pose facing +Z (true of CMU/AMASS BVH and of our own BVH).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..bvh import BvhData
from ..jointmap import JointMap, SourcePose, mapped_ancestor, pinned, rotation_motion, source_pose
from ..motion import Motion
from ..skeleton import BODY_JOINTS, DEFAULT_SKELETON
from .fit import Target, fit_errors, optimise_rotations, target_positions

_TURN_POINT = 0.1  # metres from an end joint to each of its two turn points


@dataclass
class Retargeted:
    """A retargeted clip: our motion, the source it was fitted to, and the points fitted."""

    motion: Motion
    source: SourcePose
    targets: list[Target]

    def errors(self) -> np.ndarray:
        """Per-frame distances (metres) between our joints and the source's, [T, K] (mapped joints)."""
        return fit_errors(self.motion, _points(self.source, self.targets), self.targets)


def _end_joints(joints: list[int]) -> list[int]:
    return [j for j in joints if not any(mapped_ancestor(c, set(joints)) == j for c in joints)]


def fit_targets(source: SourcePose) -> list[Target]:
    """One target per mapped joint (points 0..K-1), then two turn points per end joint."""
    targets = [Target(DEFAULT_SKELETON.names[j], j, (0.0, 0.0, 0.0), (k,)) for k, j in enumerate(source.joints)]
    n = len(source.joints)
    for j in _end_joints(source.joints):
        for axis in (0, 2):  # two points off the joint in different directions fix its whole turn
            offset = [0.0, 0.0, 0.0]
            offset[axis] = _TURN_POINT
            targets.append(Target(f"{DEFAULT_SKELETON.names[j]}_turn{'xyz'[axis]}", j, tuple(offset), (n,),
                                  0.3, matched=False))
            n += 1
    return targets


def _points(source: SourcePose, targets: list[Target]) -> np.ndarray:
    """The source side of every target, [T, P, 3]: joints, then turn points carried by the joints' rotations."""
    col = {j: k for k, j in enumerate(source.joints)}
    extra = [source.positions[:, col[t.joint]] + source.rotations[:, col[t.joint]] @ np.array(t.offset)
             for t in targets if not t.matched]
    return np.concatenate([source.positions, np.stack(extra, axis=1)], axis=1)


def retarget(data: BvhData, joint_map: JointMap, fps: float, steps: int = 200, path: str = "BVH") -> Retargeted:
    """Our skeleton doing the clip `data`, at `fps`, fitted to the source joints' world positions."""
    source = source_pose(data, joint_map, fps, path)
    start = rotation_motion(source)
    targets = fit_targets(source)
    mapped = set(source.joints)
    # Body joints that nothing pins (no mapped joint below them) keep the start rotation.
    frozen = [j for j in range(BODY_JOINTS) if not pinned(j, mapped)]
    motion = optimise_rotations(start.skeleton, targets, target_positions(_points(source, targets), targets),
                                start.rotations, start.root_positions, fps, frozen, steps)
    return Retargeted(motion, source, targets)

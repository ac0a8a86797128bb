"""Bone mapping by the skeleton's shape, for rigs whose bone names follow no rule. Pure numpy (no bpy).

A humanoid reads from its rest pose alone: the hips are where three long chains meet (the spine up to the
top of the head, two legs down to the floor), the arms are the two long branches off the spine, the feet
point forward (which gives the body's left: up × forward), and along each chain the joints sit at the
proportions every human shares (the knee halfway down the leg, the elbow halfway from shoulder to wrist).
Twist, in-between and end bones on the chains are passed over. Positions are in a Z-up space (Blender's
world), so a rig stored Y-up and turned by its object reads the same.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

# The joints the shape can tell (fingers, jaw and eyes are left to names).
BODY_JOINTS: tuple[str, ...] = (
    "pelvis", "spine1", "spine2", "spine3", "neck", "head",
    *(f"{side}_{part}" for side in ("left", "right") for part in (
        "hip", "knee", "ankle", "foot", "collar", "shoulder", "elbow", "wrist")),
)  # fmt: skip

# Shares of the body's height H (the armature's extent along Z).
_FLOOR = 0.1  # a foot ends this near the lowest point...
_FOOT_HOLDS = 0.5  # ...and nothing it holds reaches this high
_HIPS_ABOVE = 0.3  # the hips are above the knees: a bone on the floor holding the legs is no pelvis
_ARM_REACH = 0.15  # an arm reaches this far sideways from the spine bone it hangs from
_TOE_REACH = 0.02  # a toe reaches this far ahead of the ankle
# Shares of a chain.
_FOOT_ZONE = 0.25  # the ankle's head is in the lowest quarter of the leg's drop
_HEAD_END = 0.6  # bones starting above 60% of the way from the neck to the top are end bones (head top, eyes)
_HAND_ZONE = 0.45  # the hand's head is within 45% of the shoulder's distance from the fingertip
_STRAIGHT = math.cos(math.radians(25))  # a thigh points at its knee (a pelvis.L side bone does not)


class RestBone(NamedTuple):
    """A bone at rest: its parent's name (None for a root) and head and tail, Z up."""

    name: str
    parent: str | None
    head: Sequence[float]
    tail: Sequence[float]


class _Tree:
    """Bones by index, with parents, children and subtrees."""

    def __init__(self, bones: Sequence[RestBone]) -> None:
        self.names = [b.name for b in bones]
        index = {n: i for i, n in enumerate(self.names)}
        self.parent = [index.get(b.parent, -1) if b.parent is not None else -1 for b in bones]
        self.children: list[list[int]] = [[] for _ in bones]
        for i, p in enumerate(self.parent):
            if p >= 0:
                self.children[p].append(i)
        self.head = np.array([b.head for b in bones], dtype=np.float64).reshape(-1, 3)
        self.tail = np.array([b.tail for b in bones], dtype=np.float64).reshape(-1, 3)

    def topmost(self, z: np.ndarray) -> np.ndarray:
        """Per bone, the highest of `z` over its subtree."""
        out = z.copy()
        for i in sorted(range(len(out)), key=lambda b: -len(self.chain(b))):  # children before parents
            if self.parent[i] >= 0:
                out[self.parent[i]] = max(out[self.parent[i]], out[i])
        return out

    def chain(self, i: int) -> list[int]:
        """The root's index down to i."""
        out = [i]
        while self.parent[out[-1]] >= 0:
            out.append(self.parent[out[-1]])
        return out[::-1]

    def lca(self, *bones: int) -> int:
        """The lowest common ancestor (a bone counts as its own ancestor), or -1 in different trees."""
        chains = [self.chain(b) for b in bones]
        common = -1
        for level in zip(*chains, strict=False):
            if any(b != level[0] for b in level):
                break
            common = level[0]
        return common

    def below(self, top: int, i: int) -> list[int]:
        """The chain from `top` (exclusive) down to its descendant i."""
        chain = self.chain(i)
        return chain[chain.index(top) + 1 :]

    def subtree(self, i: int) -> list[int]:
        out, todo = [], [i]
        while todo:
            out.append(todo.pop())
            todo.extend(self.children[out[-1]])
        return out

    def points(self, bones: list[int]) -> np.ndarray:
        return np.concatenate([self.head[bones], self.tail[bones]])


def _flat(v: np.ndarray) -> np.ndarray:
    return v * np.array([1.0, 1.0, 0.0])


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.linalg.norm(v)), 1e-12)


def match_shape(bones: Sequence[RestBone]) -> dict[str, str]:
    """Joint -> bone for the joints of `BODY_JOINTS` the skeleton's shape shows; {} for no humanoid."""
    if not bones:
        return {}
    t = _Tree(bones)
    z_low = np.minimum(t.head[:, 2], t.tail[:, 2])
    z_high = np.maximum(t.head[:, 2], t.tail[:, 2])
    floor, height = float(z_low.min()), float(z_high.max() - z_low.min())
    if height <= 0:
        return {}
    # Two feet on the floor in different legs (their common ancestor well above the floor), the top of the head.
    # A foot is low and so is all it holds (a root bone on the floor holds the whole body).
    above_knees = floor + _HIPS_ABOVE * height
    feet = np.flatnonzero(t.topmost(z_high) < floor + _FOOT_HOLDS * height)
    if not len(feet):
        return {}
    foot1 = int(feet[np.argmin(z_low[feet])])
    meet = {int(i): t.lca(int(i), foot1) for i in feet}
    other = [i for i, m in meet.items() if m >= 0 and t.head[m, 2] > above_knees]
    if not other:
        return {}
    foot2 = min(other, key=lambda i: z_low[i])
    top = int(np.argmax(z_high))
    hips = t.lca(foot1, foot2, top)
    if z_low[foot2] > floor + _FLOOR * height or hips in (-1, top) or t.head[hips, 2] < above_knees:
        return {}
    found = {"pelvis": hips}
    spine = t.below(hips, top)

    legs = [_leg(t, t.below(t.lca(foot1, foot2), f), floor) for f in (foot1, foot2)]
    ankles = [a[2] for a in legs if a is not None]
    forward = _unit(_flat(sum((t.tail[a] - t.head[a] for a in ankles), np.zeros(3))))
    if not np.any(forward):  # feet that point nowhere: Blender's convention, the front is -Y
        forward = np.array([0.0, -1.0, 0.0])
    left = np.cross([0.0, 0.0, 1.0], forward)

    def sided(parts: list[dict[str, int] | None], names: tuple[str, ...], at: str) -> None:
        """Both limbs' joints under `names`, left and right by the side their `at` joint lies on."""
        if any(p is None for p in parts):
            return
        sides = [float((t.head[p[at]] - t.head[hips]) @ left) for p in parts]
        if sides[0] * sides[1] >= 0:
            return
        for side, part in zip(("left", "right") if sides[0] > 0 else ("right", "left"), parts, strict=True):
            found.update({f"{side}_{n}": part[n] for n in names if n in part})

    sided([None if a is None else dict(zip(("hip", "knee", "ankle"), a, strict=True)) | _toe(t, a[2], forward, height)
           for a in legs], ("hip", "knee", "ankle", "foot"), "ankle")  # fmt: skip

    # The arms: the two longest branches reaching sideways off the spine; the chest is where they meet it.
    branches = []
    for s in spine:
        for c in t.children[s]:
            if c not in spine:
                reach = float(np.linalg.norm(_flat(t.points(t.subtree(c)) - t.head[s]), axis=1).max())
                branches.append((reach, c))
    arms = [c for reach, c in sorted(branches, reverse=True)[:2] if reach >= _ARM_REACH * height]
    if len(arms) < 2:
        return {j: t.names[i] for j, i in found.items()}
    chest = t.lca(*(t.parent[c] for c in arms))
    sided([_arm(t, c, chest) for c in arms], ("collar", "shoulder", "elbow", "wrist"), "wrist")

    torso = spine[: spine.index(chest) + 1]
    found["spine1"] = torso[0]
    if len(torso) >= 2:
        found["spine3"] = torso[-1]
    if len(torso) >= 3:
        found["spine2"] = torso[len(torso) // 2]
    neck = spine[spine.index(chest) + 1 :]
    if neck:
        z_top, z_neck = z_high[top], t.head[neck[0], 2]
        while len(neck) > 1 and t.head[neck[-1], 2] >= z_neck + _HEAD_END * (z_top - z_neck):
            neck.pop()
        found["head"] = neck[-1]
        if len(neck) >= 2:
            found["neck"] = neck[0]
    return {j: t.names[i] for j, i in found.items()}


def _leg(t: _Tree, chain: list[int], floor: float) -> tuple[int, int, int] | None:
    """(thigh, shin, foot) on a chain from below the hips down to the floor.

    The foot is the first bone in the lowest quarter of the drop that points forward more than down; the
    shin is the bone starting nearest halfway down to it; the thigh is the highest bone pointing at the knee.
    """
    if len(chain) < 3:
        return None
    top = t.head[chain[0], 2]
    drop = top - floor
    ankle = next((k for k, b in enumerate(chain[2:], start=2) if t.head[b, 2] <= floor + _FOOT_ZONE * drop
                  and np.linalg.norm(_flat(t.tail[b] - t.head[b])) > t.head[b, 2] - t.tail[b, 2]), None)  # fmt: skip
    if ankle is None:  # a foot bone pointing down: the bone nearest the usual ankle height
        ankle = 2 + int(np.argmin(np.abs(t.head[chain[2:], 2] - (floor + 0.08 * drop))))
    mid = (top + t.head[chain[ankle], 2]) / 2
    knee = 1 + int(np.argmin(np.abs(t.head[chain[1:ankle], 2] - mid)))
    goes_to_knee = [float(_unit(t.tail[b] - t.head[b]) @ _unit(t.head[chain[knee]] - t.head[b])) >= _STRAIGHT
                    for b in chain[:knee]]  # fmt: skip
    thigh = goes_to_knee.index(True) if True in goes_to_knee else knee - 1
    return chain[thigh], chain[knee], chain[ankle]


def _toe(t: _Tree, ankle: int, forward: np.ndarray, height: float) -> dict[str, int]:
    """{"foot": the ankle's child reaching furthest forward} if one reaches ahead of the ankle."""
    ahead = [(float(((t.points(t.subtree(c)) - t.head[ankle]) @ forward).max()), c) for c in t.children[ankle]]
    best = max(ahead, default=(0.0, -1))
    return {"foot": best[1]} if best[0] >= _TOE_REACH * height else {}


def _arm(t: _Tree, root: int, chest: int) -> dict[str, int] | None:
    """{"collar"?, "shoulder", "elbow", "wrist"} along the branch from `root` to its farthest fingertip.

    A first bone starting near the spine and short against the rest of the arm is a collar; the wrist is the
    first bone in the hand's zone where fingers fan out, else the one that leaves an elbow halfway along the
    arm and a hand no longer than the forearm; the elbow is the bone starting nearest halfway to the wrist.
    """
    bones = t.subtree(root)
    tip_bone = max(bones, key=lambda b: float(np.linalg.norm(t.tail[b] - t.head[root])))
    chain = [root, *t.below(root, tip_bone)]
    if len(chain) < 3:
        return None
    tip = t.tail[tip_bone]

    def off_spine(b: int) -> float:
        return float(np.linalg.norm(_flat(t.head[b] - t.head[chest])))

    first = float(np.linalg.norm(t.head[chain[1]] - t.head[chain[0]]))
    collar = off_spine(chain[0]) < 0.5 * off_spine(chain[1]) and first < 0.4 * np.linalg.norm(tip - t.head[chain[1]])
    s = 1 if collar else 0

    def apart(a: int, b: int) -> float:
        return max(float(np.linalg.norm(t.head[chain[a]] - t.head[chain[b]])), 1e-9)

    def elbow_for(w: int) -> int:
        return min(range(s + 1, w), key=lambda k: abs(apart(s, k) - apart(s, w) / 2))

    def misfit(w: int) -> float:
        """How far wrist w is from an elbow halfway along the arm and a hand no longer than the forearm."""
        e = elbow_for(w)
        hand = float(np.linalg.norm(tip - t.head[chain[w]]))
        return abs(apart(s, e) - apart(e, w)) / apart(s, w) + max(0.0, hand / apart(e, w) - 1.0)

    reach = np.linalg.norm(tip - t.head[chain], axis=1)
    after = range(s + 2, len(chain))
    if not after:
        return None
    fan = (k for k in after if reach[k] <= _HAND_ZONE * reach[s] and len(t.children[chain[k]]) >= 3)
    wrist = next(fan, None)
    if wrist is None:
        wrist = min(after, key=misfit)
    elbow = elbow_for(wrist)
    arm = {"shoulder": chain[s], "elbow": chain[elbow], "wrist": chain[wrist]}
    return arm | {"collar": chain[0]} if collar else arm

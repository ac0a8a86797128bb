"""AIST++'s kinetic and geometric dance features, the inputs of FID_k / FID_g and Div_k / Div_g.

Re-implemented (vectorised numpy) after google/aistplusplus_api `features/kinetic.py` and
`features/manual.py` (Apache-2.0, themselves after fairmotion), which Bailando's `metrics_new.py` uses.
Both work on SMPL's 24 joints in metres with +Y up, as ours: AIST++'s `up_vec="y"` and its "y_unit"
planes carry over without any axis swap, and our frame is SMPL's (faces +Z, left is +X), so the
handedness of the cross-product features is the same too.

Rates: AIST++ runs at 60 fps. Its kinetic features average velocities over +-2 frames; we keep that
window in seconds (+-33 ms, at least one frame). Its geometric features divide 60-fps displacements by a
hard-coded 1/120 s, so every speed they threshold is twice the true one; we keep that factor, so a
feature means the same at 25 or 60 fps as in AIST++'s own numbers.
"""

from __future__ import annotations

import numpy as np

from ..skeleton import BODY_JOINTS, JOINT_INDEX

# Bailando's metrics_new.py crops every dance to its first 20 s (1200 frames at 60 fps).
CROP_S = 20.0
KINETIC_WINDOW_S = 2 / 60
AIST_SPEED_FACTOR = 2.0  # 60-fps displacements divided by 1/120 s

SMPL_JOINTS: tuple[str, ...] = (
    "root", "lhip", "rhip", "belly", "lknee", "rknee", "spine", "lankle", "rankle", "chest",
    "ltoes", "rtoes", "neck", "linshoulder", "rinshoulder", "head", "lshoulder", "rshoulder",
    "lelbow", "relbow", "lwrist", "rwrist", "lhand", "rhand",
)  # fmt: skip
_J = {n: i for i, n in enumerate(SMPL_JOINTS)}

# Body scales AIST++ measures once on the SMPL template (not per dancer): humerus length, shoulder
# width, hip width, from the template joint positions its manual.py lists.
_TEMPLATE = {
    "lshoulder": (1.99113488e-01, 2.36807942e-01, -1.80702247e-02),
    "rshoulder": (-1.91692337e-01, 2.36928746e-01, -1.23055102e-02),
    "lelbow": (4.54445392e-01, 2.21158922e-01, -4.10167128e-02),
    "lhip": (5.64076714e-02, -3.23069185e-01, 1.09197125e-02),
    "rhip": (-6.24834076e-02, -3.31302464e-01, 1.50412619e-02),
}
SCALES: dict[str, float] = {
    "hl": float(np.linalg.norm(np.subtract(_TEMPLATE["lshoulder"], _TEMPLATE["lelbow"]))),
    "sw": float(np.linalg.norm(np.subtract(_TEMPLATE["lshoulder"], _TEMPLATE["rshoulder"]))),
    "hw": float(np.linalg.norm(np.subtract(_TEMPLATE["lhip"], _TEMPLATE["rhip"]))),
}

# The 32 boolean relations of manual.py, in its order: (kind, four points, threshold factor, scale)
# for distances and speeds, or (kind, four points, (low, high) degrees) for angles. Besides joints, a
# point may be "zero", "y_unit", "minus_y_unit" or "y_min" (the lowest joint's height on the Y axis).
GEOMETRIC_FEATURES: tuple[tuple, ...] = (
    ("nmove", ("neck", "rhip", "lhip", "rwrist"), 1.8, "hl"),
    ("nmove", ("neck", "lhip", "rhip", "lwrist"), 1.8, "hl"),
    ("nplane", ("chest", "neck", "neck", "rwrist"), 0.2, "hl"),  # right hand above the neck
    ("nplane", ("chest", "neck", "neck", "lwrist"), 0.2, "hl"),  # left hand above the neck
    ("move", ("belly", "chest", "chest", "rwrist"), 1.8, "hl"),
    ("move", ("belly", "chest", "chest", "lwrist"), 1.8, "hl"),
    ("angle", ("relbow", "rshoulder", "relbow", "rwrist"), (0, 110)),  # right elbow bent
    ("angle", ("lelbow", "lshoulder", "lelbow", "lwrist"), (0, 110)),
    ("nplane", ("lshoulder", "rshoulder", "lwrist", "rwrist"), 2.5, "sw"),  # hands apart
    ("move", ("lwrist", "rwrist", "rwrist", "lwrist"), 1.4, "hl"),
    ("move", ("rwrist", "root", "lwrist", "root"), 1.4, "hl"),
    ("move", ("lwrist", "root", "rwrist", "root"), 1.4, "hl"),
    ("fast", ("rwrist",), 2.5, "hl"),
    ("fast", ("lwrist",), 2.5, "hl"),
    ("plane", ("root", "lhip", "ltoes", "rankle"), 0.38, "hl"),
    ("plane", ("root", "rhip", "rtoes", "lankle"), 0.38, "hl"),
    ("nplane", ("zero", "y_unit", "y_min", "rankle"), 1.2, "hl"),  # right foot raised
    ("nplane", ("zero", "y_unit", "y_min", "lankle"), 1.2, "hl"),
    ("nplane", ("lhip", "rhip", "lankle", "rankle"), 2.1, "hw"),  # feet apart
    ("angle", ("rknee", "rhip", "rknee", "rankle"), (0, 110)),  # right knee bent
    ("angle", ("lknee", "lhip", "lknee", "lankle"), (0, 110)),
    ("fast", ("rankle",), 2.5, "hl"),
    ("fast", ("lankle",), 2.5, "hl"),
    ("angle", ("neck", "root", "rshoulder", "relbow"), (25, 180)),  # right arm raised from the side
    ("angle", ("neck", "root", "lshoulder", "lelbow"), (25, 180)),
    ("angle", ("neck", "root", "rhip", "rknee"), (50, 180)),  # right leg lifted
    ("angle", ("neck", "root", "lhip", "lknee"), (50, 180)),
    ("plane", ("rankle", "neck", "lankle", "root"), 0.5, "hl"),
    ("angle", ("neck", "root", "zero", "y_unit"), (70, 110)),  # torso horizontal
    ("nplane", ("zero", "minus_y_unit", "y_min", "rwrist"), -1.2, "hl"),  # right hand low
    ("nplane", ("zero", "minus_y_unit", "y_min", "lwrist"), -1.2, "hl"),
    ("fast", ("root",), 2.3, "hl"),
)
GEOMETRIC_INDEX = {  # the features the tests and readers refer to by name
    "rwrist_above_neck": 2,
    "lwrist_above_neck": 3,
    "rankle_raised": 16,
    "root_fast": 31,
}


def smpl24_positions(positions55: np.ndarray) -> np.ndarray:
    """Our 55-joint SMPL-X positions [T, 55, 3] -> SMPL's 24 joints [T, 24, 3].

    Joints 0-21 are shared; SMPL's hand joints 22/23 sit at the knuckles, where our left/right middle1 are.
    """
    p = np.asarray(positions55, dtype=np.float64)
    if p.ndim != 3 or p.shape[1:] != (55, 3):
        raise ValueError(f"expected [T, 55, 3] SMPL-X joint positions, got {p.shape}")
    hands = [JOINT_INDEX["left_middle1"], JOINT_INDEX["right_middle1"]]
    return np.concatenate([p[:, :BODY_JOINTS], p[:, hands]], axis=1)


def _check24(positions24: np.ndarray, min_frames: int) -> np.ndarray:
    p = np.asarray(positions24, dtype=np.float64)
    if p.ndim != 3 or p.shape[1:] != (24, 3):
        raise ValueError(f"expected [T, 24, 3] SMPL joint positions, got {p.shape}")
    if len(p) < min_frames:
        raise ValueError(f"need at least {min_frames} frames, got {len(p)}")
    return p


def _window_means(x: np.ndarray, first: int, last: int, w: int, frames: np.ndarray) -> np.ndarray:
    """For each frame i, the mean of x[k] over k in [i - w, i + w] clipped to [first, last] (x indexed by k)."""
    c = np.concatenate([np.zeros((1, *x.shape[1:])), np.cumsum(x[first : last + 1], axis=0)])
    lo = np.clip(frames - w, first, last) - first
    hi = np.clip(frames + w, first, last) - first
    return (c[hi + 1] - c[lo]) / (hi - lo + 1)[:, None, None]


def kinetic_features(positions24: np.ndarray, fps: float) -> np.ndarray:
    """72 numbers: per joint, mean horizontal and vertical "kinetic energy" (squared speed, unit mass, over
    a +-KINETIC_WINDOW_S average of the velocity) and mean "energy expenditure" (acceleration magnitude)."""
    p = _check24(positions24, 3)
    t, dt = len(p), 1.0 / fps
    w = max(1, round(KINETIC_WINDOW_S * fps))
    frames = np.arange(1, t)  # AIST++ averages over frames 1..T-1
    d = np.zeros_like(p)
    d[1:] = p[1:] - p[:-1]  # d[k] = p[k] - p[k-1], k >= 1
    vel = _window_means(d, 1, t - 1, w, frames) / dt  # [T-1, 24, 3]
    a = np.zeros_like(p)
    a[1:-1] = p[2:] - 2 * p[1:-1] + p[:-2]  # a[k] for 1 <= k <= T-2
    acc = _window_means(a, 1, t - 2, w, frames) / dt**2
    horizontal = (vel[..., 0] ** 2 + vel[..., 2] ** 2).mean(axis=0)
    vertical = (vel[..., 1] ** 2).mean(axis=0)
    expenditure = np.linalg.norm(acc, axis=-1).mean(axis=0)
    return np.stack([horizontal, vertical, expenditure], axis=1).reshape(-1).astype(np.float32)


def _points(p: np.ndarray, name: str) -> np.ndarray:
    """[N, 3] positions of a joint or of one of AIST++'s fixed points, for frames p [N, 24, 3]."""
    if name in _J:
        return p[:, _J[name]]
    out = np.zeros((len(p), 3))
    if name == "y_unit":
        out[:, 1] = 1.0
    elif name == "minus_y_unit":
        out[:, 1] = -1.0
    elif name == "y_min":
        out[:, 1] = p[..., 1].min(axis=1)
    elif name != "zero":
        raise KeyError(name)
    return out


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def _along(v: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Component of v along direction (NaN for a zero direction, which compares False, as in AIST++)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return _dot(v, direction) / np.linalg.norm(direction, axis=1)


def _relation(spec: tuple, cur: np.ndarray, prev: np.ndarray, speed: float) -> np.ndarray:
    """One of manual.py's relations over frames: cur/prev [N, 24, 3], speed = displacement -> AIST++ speed."""
    kind, names = spec[0], spec[1]
    j = [_points(cur, n) for n in names]
    if kind == "angle":
        low, high = spec[2]
        u, v = j[1] - j[0], j[3] - j[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            cos = _dot(u, v) / (np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1))
        angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
        return (angle > low) & (angle < high)
    threshold = spec[2] * SCALES[spec[3]]
    if kind == "plane":  # distance of j3 from the plane through j0, j1, j2
        return _along(j[3] - j[0], np.cross(j[2] - j[0], j[1] - j[0])) > threshold
    if kind == "nplane":  # distance of j3 from the plane through j2 with normal j1 - j0
        return _along(j[3] - j[2], j[1] - j[0]) > threshold
    jp = [_points(prev, n) for n in names]
    if kind == "fast":
        return np.linalg.norm(j[0] - jp[0], axis=1) * speed > threshold
    if kind == "move":  # velocity of j2 relative to j0, along j1 - j0 (manual.py never reads j3)
        return _along((j[2] - j[0]) - (jp[2] - jp[0]), j[1] - j[0]) * speed > threshold
    if kind == "nmove":  # velocity of j3 relative to j0, along the normal of the plane j0, j1, j2
        return _along((j[3] - j[0]) - (jp[3] - jp[0]), np.cross(j[2] - j[0], j[1] - j[0])) * speed > threshold
    raise ValueError(f"unknown relation {kind!r}")


def geometric_frames(positions24: np.ndarray, fps: float) -> np.ndarray:
    """The 32 relations on each frame 1..T-1 (each against its previous frame), [T-1, 32] booleans."""
    p = _check24(positions24, 2)
    speed = fps * AIST_SPEED_FACTOR
    return np.stack([_relation(s, p[1:], p[:-1], speed) for s in GEOMETRIC_FEATURES], axis=1)


def geometric_features(positions24: np.ndarray, fps: float) -> np.ndarray:
    """32 numbers: the share of frames on which each of AIST++'s Mueller-style relations holds."""
    return geometric_frames(positions24, fps).mean(axis=0).astype(np.float32)


def dance_features(positions55: np.ndarray, fps: float, crop_s: float = CROP_S) -> tuple[np.ndarray, np.ndarray]:
    """Kinetic [72] and geometric [32] features of a dance as Bailando evaluates it: its first `crop_s`
    seconds. (Bailando also moves the dance so its root starts at the origin; neither feature set depends
    on where the dance is, so that step is left out.)"""
    p = smpl24_positions(positions55)[: max(3, int(round(crop_s * fps)))]
    return kinetic_features(p, fps), geometric_features(p, fps)

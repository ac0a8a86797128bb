"""Which bone of a rig plays which of our 55 joints, for any humanoid skeleton: the add-on's target rigs and the
motion library's source clips share it. Pure numpy (no bpy).

`bonemap`: the shipped JSON maps (`bonemaps/*.json`: Mixamo, VRM, Unreal, ...) and the user's, matched by names;
`shapemap`: by the skeleton's shape for names that follow no rule; `vrmhumanoid`: the VRM add-on's assignments;
`humanoid`: a skeleton's bones as our joint indices, or one line saying what it lacks.
"""

from .bonemap import (
    MAP_DIR,
    REQUIRED_JOINTS,
    SHIPPED,
    SPINE_JOINTS,
    BoneMap,
    auto_map,
    closest,
    detect,
    load_file,
    load_shipped,
    match,
    name_key,
    parse,
    resolve,
    user_maps,
)
from .humanoid import humanoid_joints
from .shapemap import BODY_JOINTS, RestBone, match_shape
from .vrmhumanoid import humanoid_map

__all__ = [
    "BODY_JOINTS", "MAP_DIR", "REQUIRED_JOINTS", "SHIPPED", "SPINE_JOINTS", "BoneMap", "RestBone", "auto_map",
    "closest", "detect", "humanoid_joints", "humanoid_map", "load_file", "load_shipped", "match", "match_shape",
    "name_key", "parse", "resolve", "user_maps",
]  # fmt: skip

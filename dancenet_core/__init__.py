"""DanceNet for Blender: music-driven dance generation (Zhuang et al., 2020). Never imports bpy."""

import os

# OpenMP threads that spin while waiting for each other turn a busy 2-core machine into a crawl
# (measured here: 21 s per training step with two spinning threads while other jobs ran, 0.9 s with
# one passive thread). It must be set before torch loads its OpenMP runtime, hence here.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

# numba reads its cache folder from the environment when it compiles; set before any of our @njit(cache=True)
# functions is defined, so compiled code goes to the user's cache, never into the (maybe read-only) install.
from .environment import cache_root

os.environ.setdefault("NUMBA_CACHE_DIR", str(cache_root() / "numba"))

__version__ = "0.1.0"

"""Which off-screen OpenGL the preview draws with (EGL, on a GPU or Mesa's llvmpipe; OSMesa where EGL is missing),
chosen once per process by trying each in a child, and the render extra checked before anything is drawn."""

from __future__ import annotations

import ctypes
import functools
import importlib.util
import os
import subprocess
import sys

from ..errors import DanceNetError

_PLATFORMS = ("egl", "osmesa")
# Exactly what rendering needs, run in a child process: PyOpenGL picks its platform once, at import,
# and a failed EGL start cannot be undone in the process that tried it.
_PROBE = (
    "from dancenet_core.render.gl import pyopengl_compat\n"
    "pyopengl_compat()\n"
    "import pyrender\n"
    "scene = pyrender.Scene()\n"
    "scene.add(pyrender.PerspectiveCamera(yfov=1.0))\n"
    "renderer = pyrender.OffscreenRenderer(8, 8)\n"
    "renderer.render(scene)\n"
    "renderer.delete()\n"
)


@functools.cache
def gl_platform() -> str:
    """The off-screen OpenGL platform that works here, 'egl' or 'osmesa', set in PYOPENGL_PLATFORM.

    A platform already named in PYOPENGL_PLATFORM is tried first. Each is tried in a child process
    before OpenGL is imported here, because PyOpenGL cannot switch platforms after its first import.
    """
    _check_render_extra()
    wanted = os.environ.get("PYOPENGL_PLATFORM", "")
    if "OpenGL" in sys.modules:
        if wanted in _PLATFORMS:
            return wanted
        raise DanceNetError(
            "OpenGL was loaded before the renderer could choose an off-screen platform; "
            "start again with PYOPENGL_PLATFORM=egl (or osmesa) set"
        )
    order = [wanted] if wanted in _PLATFORMS else []
    order += [p for p in _PLATFORMS if p not in order]
    failures = []
    for platform in order:
        error = _probe(platform)
        if error is None:
            os.environ["PYOPENGL_PLATFORM"] = platform
            return platform
        failures.append(f"{platform}: {error}")
    raise DanceNetError(
        f"no off-screen OpenGL works here ({'; '.join(failures)}); install one (Debian/Ubuntu: apt-get install "
        "libegl1 libgl1-mesa-dri libopengl0 libgl1 libglu1-mesa, or libosmesa6; a checkout lists them in "
        "scripts/apt-packages.txt)"
    )


def pyopengl_compat() -> None:
    """Let PyOpenGL 3.1.0, which pyrender pins and `pip install ".[render]"` therefore installs, take ctypes
    `byref` arguments on Python 3.12+: it looks their type up as builtins.CArgObject, which Python 3.12 renamed
    _ctypes.CArgObject, so pyrender's off-screen contexts failed ("No array-type handler for type _ctypes.type").
    Registers the type under the name it has here, as PyOpenGL 3.1.10 does itself; a no-op where it is known."""
    from OpenGL.plugins import FormatHandler  # imports no platform: safe before the window system is chosen

    byref = type(ctypes.byref(ctypes.c_int()))
    if FormatHandler.match(byref) is None:
        FormatHandler("ctypesparameter", "OpenGL.arrays.ctypesparameters.CtypesParameterHandler",
                      [f"{byref.__module__}.{byref.__name__}"], isOutput=True)


def _check_render_extra() -> None:
    """One line saying what to install when the render extra is missing (a pip install has no
    scripts/apt-packages.txt to point at)."""
    missing = [m for m in ("pyrender", "trimesh", "PIL", "OpenGL") if importlib.util.find_spec(m) is None]
    if missing:
        raise DanceNetError(f"the preview needs the render extra ({', '.join(missing)} missing): "
                            'pip install "dancenet[render]" (from a checkout: ".[render]")')


def _probe(platform: str) -> str | None:
    """None if pyrender renders with `platform` in a child process, else the last line of its error."""
    env = {**os.environ, "PYOPENGL_PLATFORM": platform}
    try:
        proc = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True,
                              timeout=180)
    except subprocess.TimeoutExpired:
        return "timed out"
    if proc.returncode == 0:
        return None
    lines = [line.strip() for line in proc.stderr.splitlines() if line.strip()]
    return lines[-1][:160] if lines else f"exit status {proc.returncode}"

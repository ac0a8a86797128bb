"""One dance drawn off-screen with raw OpenGL on pyrender's context (`_Stage` says why not a pyrender scene):
the figure's mesh re-posed each frame, the floor, the shadows, read back as RGB."""

from __future__ import annotations

import os

import numpy as np

from ..errors import DanceNetError
from ..motion import Motion
from ..skeleton import Skeleton
from .camera import _CAMERA_OFFSET, YFOV, Camera, figure_scale
from .geometry import _FLOOR_MARGIN, _FOOT_WORDS, _blob_texture, _build_figure, _grid_texture, floor_quad
from .gl import pyopengl_compat
from .shaders import _FRAGMENT_SHADER, _VERTEX_SHADER

BACKGROUND_RGB: tuple[int, int, int] = (206, 219, 236)  # the sky above the floor's far edge


def _perspective(yfov: float, aspect: float, znear: float, zfar: float) -> np.ndarray:
    """OpenGL projection matrix, as pyrender's PerspectiveCamera makes it."""
    t = np.tan(yfov / 2)
    return np.array([[1 / (aspect * t), 0, 0, 0], [0, 1 / t, 0, 0],
                     [0, 0, (zfar + znear) / (znear - zfar), 2 * zfar * znear / (znear - zfar)], [0, 0, -1, 0]])


def _rigid_inverse(pose: np.ndarray) -> np.ndarray:
    """Inverse of a rotation-plus-translation 4x4, without a general (LAPACK) inverse in every frame."""
    inverse = np.eye(4)
    inverse[:3, :3] = pose[:3, :3].T
    inverse[:3, 3] = -pose[:3, :3].T @ pose[:3, 3]
    return inverse


class _Stage:
    """One dance drawn off-screen: the figure, re-posed each frame, on a grid floor under soft shadows, lit
    as pyrender lights it (4x multisampled, as pyrender draws), read back as RGB.

    Raw OpenGL on pyrender's off-screen context, not a pyrender scene: for every frame pyrender re-uploads
    each mesh, looks up every uniform, runs its general shader (loops over absent lights and textures, an
    sRGB decode of each texture channel) and reads back depth, and on Mesa's software rasteriser that was
    most of a frame. Here the meshes stay in GPU buffers (only the figure's and shadows' vertices change),
    and a frame is three draw calls.
    """

    # (direction the light shines, intensity), white; ambient light
    _LIGHTS = (((-0.35, -1.0, -0.55), 2.6), ((0.8, -0.45, -0.3), 1.1))
    _AMBIENT = (0.32, 0.32, 0.34)

    def __init__(self, motion: Motion, width: int, height: int, floor: float) -> None:
        pyopengl_compat()
        import pyrender  # the render extra; it loads OpenGL, which must wait until a window system is chosen
        from OpenGL import GL

        self.gl = gl = GL
        skel = motion.skeleton
        self.size = (width, height)
        self.floor = floor
        self.unit = unit = figure_scale(skel)
        # pixels per metre (of a 1.70 m figure) at the follow camera's distance
        px_per_m = height / (2 * np.tan(YFOV / 2) * float(np.linalg.norm(_CAMERA_OFFSET)))
        self.figure = _build_figure(skel, unit, px_per_m)
        self.projection = _perspective(YFOV, width / height, 0.05 * unit, 4 * _FLOOR_MARGIN * unit)
        try:
            self.context = pyrender.OffscreenRenderer(width, height)  # used for its EGL or OSMesa context only
        except Exception as e:  # pyrender raises bare RuntimeError/ValueError/ctypes errors
            raise DanceNetError(
                f"cannot start off-screen OpenGL ({os.environ.get('PYOPENGL_PLATFORM')}): {e}"
            ) from e
        self._framebuffers(width, height)
        lights = np.array([-np.asarray(d) / np.linalg.norm(d) for d, _ in self._LIGHTS], np.float32)
        intensities = np.array([i for _, i in self._LIGHTS], np.float32)
        self.programs: dict[str, tuple[int, int, int]] = {}
        for kind, roughness in (("FIGURE", 0.55), ("FLOOR", 1.0), ("SHADOW", 1.0)):
            program = self._program(kind, len(self._LIGHTS))
            gl.glUseProgram(program)
            gl.glUniform3fv(gl.glGetUniformLocation(program, "to_light"), len(lights), lights)
            gl.glUniform1fv(gl.glGetUniformLocation(program, "intensity"), len(lights), intensities)
            gl.glUniform3f(gl.glGetUniformLocation(program, "ambient"), *self._AMBIENT)
            gl.glUniform1f(gl.glGetUniformLocation(program, "roughness"), roughness)
            gl.glUniform1i(gl.glGetUniformLocation(program, "tex"), 0)
            self.programs[kind] = (program, gl.glGetUniformLocation(program, "view_projection"),
                                   gl.glGetUniformLocation(program, "cam_pos"))
        fig = self.figure
        self.figure_mesh = self._mesh(fig.faces, {0: fig.vertices, 1: fig.normals, 2: fig.colours})
        corners, uv = floor_quad(motion, floor)
        self.floor_mesh = self._mesh(np.array([[0, 1, 2], [0, 2, 3]]), {0: corners, 3: uv})  # normal: +Y
        self._init_shadows(skel)
        self.floor_texture = self._texture(_grid_texture())
        self.shadow_texture = self._texture(_blob_texture())

    def _program(self, kind: str, lights: int) -> int:
        from OpenGL.GL import shaders

        gl = self.gl
        header = f"#version 330 core\n#define {kind}\n#define N_LIGHTS {lights}\n"
        return shaders.compileProgram(
            shaders.compileShader(header + _VERTEX_SHADER, gl.GL_VERTEX_SHADER),
            shaders.compileShader(header + _FRAGMENT_SHADER, gl.GL_FRAGMENT_SHADER),
            validate=False)  # validation wants a vertex array bound, which comes later

    def _framebuffers(self, width: int, height: int) -> None:
        """4x multisampled colour and depth to draw into, and plain colour to resolve them into and read."""
        gl = self.gl
        self.fb_multi, self.fb_resolved = gl.glGenFramebuffers(2)
        colour_multi, depth_multi, colour = gl.glGenRenderbuffers(3)
        for fb, buffer, attachment, fmt, samples in (
                (self.fb_multi, colour_multi, gl.GL_COLOR_ATTACHMENT0, gl.GL_RGBA8, 4),
                (self.fb_multi, depth_multi, gl.GL_DEPTH_ATTACHMENT, gl.GL_DEPTH_COMPONENT24, 4),
                (self.fb_resolved, colour, gl.GL_COLOR_ATTACHMENT0, gl.GL_RGBA8, 0)):
            gl.glBindRenderbuffer(gl.GL_RENDERBUFFER, buffer)
            gl.glRenderbufferStorageMultisample(gl.GL_RENDERBUFFER, samples, fmt, width, height)
            gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, fb)
            gl.glFramebufferRenderbuffer(gl.GL_FRAMEBUFFER, attachment, gl.GL_RENDERBUFFER, buffer)
        gl.glViewport(0, 0, width, height)
        gl.glEnable(gl.GL_DEPTH_TEST)
        gl.glDepthFunc(gl.GL_LESS)
        gl.glEnable(gl.GL_CULL_FACE)
        gl.glEnable(gl.GL_MULTISAMPLE)
        gl.glBlendFunc(gl.GL_SRC_ALPHA, gl.GL_ONE_MINUS_SRC_ALPHA)
        gl.glPixelStorei(gl.GL_PACK_ALIGNMENT, 1)
        gl.glPixelStorei(gl.GL_UNPACK_ALIGNMENT, 1)

    def _mesh(self, faces: np.ndarray, attributes: dict[int, np.ndarray]) -> tuple[int, int, dict[int, int]]:
        """(vertex array, index count, {attribute location: its buffer}) for float vertex attributes
        (0 position, 1 normal, 2 colour, 3 texture coordinates) and triangles."""
        gl = self.gl
        vao = gl.glGenVertexArrays(1)
        gl.glBindVertexArray(vao)
        buffers = {}
        for location, values in attributes.items():
            data = np.ascontiguousarray(values, np.float32)
            buffers[location] = gl.glGenBuffers(1)
            gl.glBindBuffer(gl.GL_ARRAY_BUFFER, buffers[location])
            gl.glBufferData(gl.GL_ARRAY_BUFFER, data.nbytes, data, gl.GL_DYNAMIC_DRAW)
            gl.glEnableVertexAttribArray(location)
            gl.glVertexAttribPointer(location, data.shape[1], gl.GL_FLOAT, False, 0, None)
        indices = np.ascontiguousarray(faces, np.uint32)
        gl.glBindBuffer(gl.GL_ELEMENT_ARRAY_BUFFER, gl.glGenBuffers(1))
        gl.glBufferData(gl.GL_ELEMENT_ARRAY_BUFFER, indices.nbytes, indices, gl.GL_STATIC_DRAW)
        gl.glBindVertexArray(0)
        return vao, indices.size, buffers

    def _texture(self, image: np.ndarray) -> int:
        """A one-channel texture with mipmaps, sampled as pyrender samples its textures (trilinear, repeating)."""
        gl = self.gl
        texture = gl.glGenTextures(1)
        gl.glBindTexture(gl.GL_TEXTURE_2D, texture)
        height, width = image.shape
        gl.glTexImage2D(gl.GL_TEXTURE_2D, 0, gl.GL_R8, width, height, 0, gl.GL_RED, gl.GL_UNSIGNED_BYTE,
                        np.ascontiguousarray(image[::-1]))  # first row at the top, as pyrender uploads images
        gl.glGenerateMipmap(gl.GL_TEXTURE_2D)
        for name, value in ((gl.GL_TEXTURE_MAG_FILTER, gl.GL_LINEAR),
                            (gl.GL_TEXTURE_MIN_FILTER, gl.GL_LINEAR_MIPMAP_LINEAR),
                            (gl.GL_TEXTURE_WRAP_S, gl.GL_REPEAT), (gl.GL_TEXTURE_WRAP_T, gl.GL_REPEAT)):
            gl.glTexParameteri(gl.GL_TEXTURE_2D, name, value)
        return texture

    def _init_shadows(self, skel: Skeleton) -> None:
        """Soft dark discs under the feet and the body, placed per frame: they fade and spread as they rise."""
        feet = [j for j, n in enumerate(skel.names) if any(w in n.lower() for w in ("ankle", *_FOOT_WORDS))]
        self.shadow_joints = np.array([0, *feet], dtype=int)
        self.shadow_size = np.array([0.45] + [0.14] * len(feet)) * self.unit
        self.shadow_alpha = np.array([0.5] + [0.6] * len(feet))
        self.shadow_fade = np.array([4.0] + [0.5] * len(feet)) * self.unit  # height where it is gone
        n = len(self.shadow_joints)
        quad = np.array([[-1.0, 0.0, -1.0], [-1.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 0.0, -1.0]])
        self.shadow_corners = np.tile(quad, (n, 1))
        faces = (np.array([[0, 1, 2], [0, 2, 3]]) + 4 * np.arange(n)[:, None, None]).reshape(-1, 3)
        self.shadow_mesh = self._mesh(faces, {0: self.shadow_corners, 2: np.zeros((4 * n, 4)),
                                              3: (self.shadow_corners[:, [0, 2]] + 1) / 2})

    def shadow_quads(self, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The shadows' corners [4n, 3] and opacity [4n] for joint positions [J, 3]."""
        feet = pos[self.shadow_joints]
        heights = np.maximum(feet[:, 1] - self.floor, 0.0)
        alpha = self.shadow_alpha * np.clip(1.0 - heights / self.shadow_fade, 0.0, 1.0) ** 2
        size = self.shadow_size * (1.0 + heights / self.unit)
        # each disc a hair above the one before, so overlapping discs never fight over depth
        centres = np.column_stack([feet[:, 0], self.floor + (1 + np.arange(len(feet))) * 5e-4 * self.unit,
                                   feet[:, 2]])
        return np.repeat(centres, 4, axis=0) + self.shadow_corners * np.repeat(size, 4)[:, None], np.repeat(alpha, 4)

    def _update(self, mesh: tuple[int, int, dict[int, int]], location: int, values: np.ndarray) -> None:
        gl = self.gl
        data = np.ascontiguousarray(values, np.float32)
        gl.glBindBuffer(gl.GL_ARRAY_BUFFER, mesh[2][location])
        gl.glBufferSubData(gl.GL_ARRAY_BUFFER, 0, data.nbytes, data)

    def _draw(self, kind: str, mesh: tuple[int, int, dict[int, int]], view_projection: np.ndarray,
              eye: np.ndarray) -> None:
        gl = self.gl
        program, view_projection_at, eye_at = self.programs[kind]
        gl.glUseProgram(program)
        gl.glUniformMatrix4fv(view_projection_at, 1, gl.GL_TRUE, view_projection)
        gl.glUniform3f(eye_at, *eye)
        gl.glBindVertexArray(mesh[0])
        gl.glDrawElements(gl.GL_TRIANGLES, mesh[1], gl.GL_UNSIGNED_INT, None)

    def render(self, pos: np.ndarray, rot: np.ndarray, camera: Camera) -> np.ndarray:
        """One frame [H, W, 3] uint8 of the pose given by world positions [J, 3] and rotations [J, 3, 3]."""
        gl = self.gl
        self.context._platform.make_current()  # pyrender 0.1.45 (pinned, its last release) keeps it there
        vertices, normals = self.figure.posed(pos, rot)
        self._update(self.figure_mesh, 0, vertices)
        self._update(self.figure_mesh, 1, normals)
        corners, alpha = self.shadow_quads(pos)
        self._update(self.shadow_mesh, 0, corners)
        colours = np.zeros((len(alpha), 4))
        colours[:, 3] = alpha
        self._update(self.shadow_mesh, 2, colours)

        pose = camera.pose
        view_projection = (self.projection @ _rigid_inverse(pose)).astype(np.float32)
        eye = pose[:3, 3]
        gl.glBindFramebuffer(gl.GL_DRAW_FRAMEBUFFER, self.fb_multi)
        gl.glClearColor(*(c / 255 for c in BACKGROUND_RGB), 1.0)
        gl.glClear(gl.GL_COLOR_BUFFER_BIT | gl.GL_DEPTH_BUFFER_BIT)
        self._draw("FIGURE", self.figure_mesh, view_projection, eye)  # first: the floor behind it is not shaded
        gl.glBindTexture(gl.GL_TEXTURE_2D, self.floor_texture)
        self._draw("FLOOR", self.floor_mesh, view_projection, eye)
        gl.glBindTexture(gl.GL_TEXTURE_2D, self.shadow_texture)
        gl.glEnable(gl.GL_BLEND)
        self._draw("SHADOW", self.shadow_mesh, view_projection, eye)
        gl.glDisable(gl.GL_BLEND)
        width, height = self.size
        gl.glBindFramebuffer(gl.GL_READ_FRAMEBUFFER, self.fb_multi)
        gl.glBindFramebuffer(gl.GL_DRAW_FRAMEBUFFER, self.fb_resolved)
        gl.glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, gl.GL_COLOR_BUFFER_BIT, gl.GL_NEAREST)
        gl.glBindFramebuffer(gl.GL_READ_FRAMEBUFFER, self.fb_resolved)
        image = np.empty((height, width, 3), np.uint8)
        gl.glReadPixels(0, 0, width, height, gl.GL_RGB, gl.GL_UNSIGNED_BYTE, image)
        return image[::-1]  # OpenGL's first row is the bottom one

    def close(self) -> None:
        self.context.delete()  # the context, and with it every buffer, texture and program here

"""An offscreen MuJoCo renderer with a camera that follows the body from the side."""

from __future__ import annotations

import mujoco
import numpy as np

from xted.viz.gl import gl_context_class

TRACKED_BODY = 1  # the torso: the first body after the world in both envs


class OffscreenRenderer:
    """Renders ``data``'s state of ``model`` to ``[height, width, 3]`` uint8 arrays.

    Shadows and reflections are off: with a software OpenGL (Mesa on a CPU) they cost five times
    the rest of a frame.
    """

    def __init__(self, model: mujoco.MjModel, width: int, height: int, distance: float = 3.0):
        self.width, self.height = width, height
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, height)
        self._gl = gl_context_class()(width, height)
        self._gl.make_current()
        self._context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._context)
        self._model = model
        self._scene = mujoco.MjvScene(model, maxgeom=1000)
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
        self._scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
        self._option = mujoco.MjvOption()
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        self._camera.trackbodyid = TRACKED_BODY
        self._camera.distance = distance
        self._camera.azimuth = 90.0
        self._camera.elevation = -15.0
        self._viewport = mujoco.MjrRect(0, 0, width, height)

    def render(self, data: mujoco.MjData) -> np.ndarray:
        self._gl.make_current()
        mujoco.mjv_updateScene(self._model, data, self._option, None, self._camera, mujoco.mjtCatBit.mjCAT_ALL,
                               self._scene)
        mujoco.mjr_render(self._viewport, self._scene, self._context)
        pixels = np.empty((self.height, self.width, 3), dtype=np.uint8)
        mujoco.mjr_readPixels(pixels, None, self._viewport, self._context)
        return np.flipud(pixels)

    def close(self) -> None:
        if self._gl is not None:
            self._gl.make_current()
            self._context.free()
            self._gl.free()
            self._gl = None

    def __enter__(self) -> OffscreenRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

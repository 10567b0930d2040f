"""An offscreen MuJoCo renderer with a camera that follows the body from the side."""

from __future__ import annotations

import mujoco
import numpy as np

from xted.viz.gl import gl_context_class

TRACKED_BODY = 1  # the torso: the first body after the world in both envs


def floor_period(model: mujoco.MjModel, floor: int) -> float:
    """How far the floor geom can move without its look changing: one tile of its texture (0: no texture)."""
    material = model.geom_matid[floor]
    if material < 0 or model.mat_texrepeat[material, 0] <= 0:
        return 0.0
    repeat = model.mat_texrepeat[material, 0]
    # A plane's texture repeats texrepeat times across the plane, or per metre with texuniform.
    return float(1.0 / repeat if model.mat_texuniform[material] else 2.0 * model.geom_size[floor, 0] / repeat)


class OffscreenRenderer:
    """Renders ``data``'s state of ``model`` to ``[height, width, 3]`` uint8 arrays.

    The floor is drawn under the tracked body wherever it runs: the envs' floor is 80 m long, a
    good runner leaves it in half a minute. It moves in whole texture tiles, so it looks fixed.
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
        self._floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
        self._floor_period = floor_period(model, self._floor) if self._floor >= 0 else 0.0

    def render(self, data: mujoco.MjData) -> np.ndarray:
        self._gl.make_current()
        mujoco.mjv_updateScene(self._model, data, self._option, None, self._camera, mujoco.mjtCatBit.mjCAT_ALL,
                               self._scene)
        self._move_floor_under_body(data)
        mujoco.mjr_render(self._viewport, self._scene, self._context)
        pixels = np.empty((self.height, self.width, 3), dtype=np.uint8)
        mujoco.mjr_readPixels(pixels, None, self._viewport, self._context)
        return np.flipud(pixels)

    def _move_floor_under_body(self, data: mujoco.MjData) -> None:
        if self._floor < 0:
            return
        x = data.xpos[TRACKED_BODY, 0]
        shift = round(x / self._floor_period) * self._floor_period if self._floor_period else x
        for index in range(self._scene.ngeom):
            geom = self._scene.geoms[index]
            if geom.objtype == mujoco.mjtObj.mjOBJ_GEOM and geom.objid == self._floor:
                geom.pos[0] += shift

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

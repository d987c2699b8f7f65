"""A Panda env's camera image of a stock-MuJoCo scene, drawn by MuJoCo's own OpenGL renderer (`mujoco.Renderer`):
what the deployment loop gives a policy that reads cameras. Imports numpy and mujoco alone.

The env's image (`ArmBase.camera_image`) stacks, per camera, its gray then its depth: uint8 [R, R, 2 per
camera]. Gray is the Rec. 601 luma (`LUMA`) of a surface's colour lit by a head light, `AMBIENT` plus the rest
times the cosine of the light's angle to the surface; depth is metres along the optical axis over `DEPTH_RANGE`;
each clipped to 0-1 and scaled to 0-255. Here MuJoCo draws each named camera (its MJCF pose on its body, its
fovy) at R×R pixels: its RGB becomes gray by the same weights, its depth buffer (which `mujoco.Renderer`
linearises to metres along the optical axis) the depth channel.

Drawn `as_env` (the default), the scene is lit and coloured as the env's ray caster sees it: one light at the camera
(each pixel lit by the cosine of its own ray) of ambient `AMBIENT` and diffuse 1 - `AMBIENT`, no specular light, each
geom in the rgba it was built with (no material, texture, emission, reflection or shadow; none where its alpha is 0),
nothing behind (black: the caster's miss), each box face cut into `LIT_QUADS` × `LIT_QUADS` quads for the gray (OpenGL
lights a triangle at its corners alone), no multisampling, and the near plane at `NEAR_CLIP`. What still differs is how
each draws: the rasteriser's sampling of edges, what is left of OpenGL's interpolation of light across a quad, meshes
(menagerie's Panda) where the caster has primitives (tests/deploy/test_camera.py measures the difference). Drawn
otherwise, the scene looks as its MJCF declares (its lights, textures, reflections and shadows): a camera the env never
showed its policy.
"""

from collections.abc import Callable, Sequence
from typing import Any, Protocol

import mujoco
import numpy as np

from jaxarm.deploy.kinematics import ArmKinematics
from jaxarm.deploy.loop import Controller, Task
from jaxarm.deploy.reading import ArmReading
from jaxarm.export.numpy_policy import IMAGE, PROPRIO

LUMA = np.array([0.299, 0.587, 0.114])
"""Rec. 601 weights of red, green and blue in a colour's gray."""
AMBIENT = 0.3
"""Share of a surface's brightness lit regardless of its angle to the light."""
DEPTH_RANGE = 1.0
"""Metres of depth a camera image's depth channel spans (0 to 255); farther reads 255."""
LIT_QUADS = 32
"""Quads along each edge of a box face where the gray is drawn `as_env`. OpenGL lights each vertex and interpolates
between them; at MuJoCo's default of 4, the table under the wrist camera 6 cm above it was lit by corners a quarter
of a metre away and drawn 26 gray levels darker than the caster draws it (its bright spot under the camera gone), and
a camera policy that placed 95.8% in the env placed 26% in stock MuJoCo (BENCHMARKS.md#transfer). 32 quads leave 0.6
levels there, and an image of two 64-pixel cameras takes 24 ms where it took 5 (Mesa's software EGL, 2-core CPU)."""
NEAR_CLIP = 0.001
"""Metres from a camera within which MuJoCo draws nothing, where the scene is drawn `as_env` (the caster has no near
plane). MuJoCo's own, a hundredth of the model's extent, is 2.7 cm in the sorter's scene: a bin wall under the hand
was cut out of the wrist camera's image."""
HIDDEN_FLAGS = (
    mujoco.mjtRndFlag.mjRND_SHADOW,
    mujoco.mjtRndFlag.mjRND_REFLECTION,
    mujoco.mjtRndFlag.mjRND_SKYBOX,
    mujoco.mjtRndFlag.mjRND_FOG,
    mujoco.mjtRndFlag.mjRND_HAZE,
)
"""What MuJoCo draws beyond a geom's lit colour; off where the image is drawn as the env's."""


def to_channel(values: np.ndarray) -> np.ndarray:
    """[...] values in 0-1 (beyond them clipped) -> uint8 [...] in 0-255, rounded, as the env scales both channels."""
    return np.round(np.clip(values, 0.0, 1.0) * 255.0).astype(np.uint8)


def gray_of(rgb: np.ndarray) -> np.ndarray:
    """uint8 [..., 3] RGB -> uint8 [...] gray (`LUMA`)."""
    return to_channel(rgb.astype(np.float32) @ LUMA / 255.0)


def depth_of(depth: np.ndarray) -> np.ndarray:
    """[...] metres along the optical axis -> uint8 [...] over `DEPTH_RANGE`."""
    return to_channel(depth / DEPTH_RANGE)


def light_as_env(scene: mujoco.MjvScene, rgba: np.ndarray) -> None:
    """Edits a scene `mujoco.Renderer.update_scene` made from a camera: its head light alone, of the env's
    ambient and diffuse light, and each of the model's geoms in its colour of `rgba` [ngeom, 4], without material,
    texture, emission or specular highlight (in place)."""
    headlight = scene.lights[0]
    # A light at the camera, as the caster's: each pixel lit by the cosine of its own ray (a directional head light
    # lights a plane evenly, 25 gray levels off the caster's at a 64-pixel image's corners). A spot of a 90° cone
    # and no fall-off covers all the camera sees; the classic renderer does not light with a point light.
    headlight.type = mujoco.mjtLightType.mjLIGHT_SPOT
    headlight.cutoff, headlight.exponent = 90.0, 0.0
    headlight.attenuation[:] = (1.0, 0.0, 0.0)
    headlight.ambient[:] = AMBIENT
    headlight.diffuse[:] = 1.0 - AMBIENT
    headlight.specular[:] = 0.0
    scene.nlight = 1  # the head light comes first where the model has it on (`CameraRenderer` checks)
    for index in range(scene.ngeom):
        geom = scene.geoms[index]
        if geom.objtype == mujoco.mjtObj.mjOBJ_GEOM:
            geom.rgba[:] = rgba[geom.objid]
        geom.matid, geom.texid = -1, -1
        geom.emission, geom.specular, geom.reflectance = 0.0, 0.0, 0.0


class CameraRenderer:
    """Draws a scene's cameras into the env's camera image.

    Args:
      model: the scene (the robot's; its cameras those the env stacks, by name), as built: drawn `as_env`, its geoms
        keep the colours and visibility they have now, whatever an episode writes into it later, and its near
        clipping plane moves to `NEAR_CLIP` (a setting of drawing alone).
      cameras: the cameras' names, in the env's order.
      resolution: side of the square images, pixels.
      as_env: light and colour the scene as the env's caster does (see the module docstring).

    Two OpenGL contexts, the gray's and the depth's, reused for every image (building one costs more than drawing);
    `close` frees them.
    """

    def __init__(self, model: mujoco.MjModel, cameras: Sequence[str], resolution: int, as_env: bool = True):
        for name in cameras:
            model.camera(name)  # KeyError naming a camera the scene lacks, before a context is made
        if as_env and not model.vis.headlight.active:
            raise ValueError("the scene's head light is off: the env's images are lit by it alone")
        self.model = model
        self.cameras = tuple(cameras)
        self.as_env = as_env
        # The caster resolves its geoms' colours once, from the model as built: a task that recolours geoms per
        # episode (the sorter's objects, for its videos) does so for drawing alone.
        self._rgba = model.geom_rgba.copy()
        # MuJoCo cuts box faces and multisamples as the model says when a renderer's context is made, and only
        # then: the gray's renderer is made with LIT_QUADS, the depth's (which no light changes) with the model's
        # own; neither multisamples where drawn as the caster, whose one ray per pixel blends no edge.
        quality = model.vis.quality
        quads, samples = quality.numquads, quality.offsamples
        if as_env:
            quality.numquads, quality.offsamples = max(quads, LIT_QUADS), 0
            # Read at each drawing: it stays.
            model.vis.map.znear = min(model.vis.map.znear, NEAR_CLIP / model.stat.extent)
        self._posed = mujoco.MjData(model)
        self._gray = mujoco.Renderer(model, resolution, resolution)
        quality.numquads = quads
        self._depth = mujoco.Renderer(model, resolution, resolution)
        self._depth.enable_depth_rendering()
        quality.offsamples = samples
        if as_env:
            for renderer in (self._gray, self._depth):
                for flag in HIDDEN_FLAGS:
                    renderer.scene.flags[flag] = False

    def _pose(self, data: mujoco.MjData) -> mujoco.MjData:
        """The scene posed at `data`'s qpos and mocap poses, its cameras placed. After `mj_step`, `data`'s poses
        are those of the step's start, a physics step behind its qpos (10 ms in jaxarm's scenes, where the wrist
        camera turns a few pixels in that time); the env casts its images from the poses of its state's qpos."""
        posed = self._posed
        posed.qpos[:] = data.qpos
        posed.mocap_pos[:] = data.mocap_pos
        posed.mocap_quat[:] = data.mocap_quat
        mujoco.mj_kinematics(self.model, posed)
        mujoco.mj_comPos(self.model, posed)  # the centres of mass a tracking camera follows
        mujoco.mj_camlight(self.model, posed)
        return posed

    def _render(self, data: mujoco.MjData, camera: str, depth: bool) -> np.ndarray:
        renderer = self._depth if depth else self._gray
        renderer.update_scene(data, camera=camera)
        if self.as_env:
            light_as_env(renderer.scene, self._rgba)
        return renderer.render()

    def image(self, data: mujoco.MjData) -> np.ndarray:
        """uint8 [R, R, 2 per camera]: each camera's gray, then its depth, of the scene at `data`'s qpos (whether
        or not its poses have been computed since; `data` is left as it is)."""
        posed = self._pose(data)
        shown = self.model.geom_rgba.copy()
        if self.as_env:
            # MuJoCo leaves out each geom whose alpha is 0 in the model now; the caster casts those of the model as
            # built. A task that shows one of several shapes per episode hides the others (the sorter's cylinder is
            # a drawing-only geom, its collision prism made transparent): drawn with the episode's alphas, a
            # cylinder went missing from every image.
            self.model.geom_rgba[:] = self._rgba
        try:
            channels = []
            for camera in self.cameras:
                channels += [gray_of(self._render(posed, camera, False)), depth_of(self._render(posed, camera, True))]
        finally:
            self.model.geom_rgba[:] = shown
        return np.stack(channels, axis=-1)

    def close(self) -> None:
        self._gray.close()
        self._depth.close()


class SeesItself(Controller, Protocol):
    """A task's controller that also gives its observation's proprio part alone (`sort.SortController`,
    `peg.PegController`): the robot's own state, as the env's pixel modes observe it."""

    def proprio(self, reading: ArmReading, ctrl: np.ndarray) -> np.ndarray: ...


class CameraController:
    """A task's control with a camera policy's observation: {"image": the cameras' image now, "proprio": the
    task's proprio part} (no "proprio" where the env observes none). The deployment loop's estimate goes unread:
    what the task's objects are, the policy sees in the image.

    Args:
      controller: the task's controller.
      camera: () -> the cameras' image now, uint8 [R, R, 2 per camera] (`CameraRenderer.image` of the robot's
        data, or a real camera's frames in the env's format).
      proprio: whether the policy reads a proprio part.
    """

    def __init__(self, controller: SeesItself, camera: Callable[[], np.ndarray], proprio: bool):
        self.controller = controller
        self.camera = camera
        self.reads_proprio = proprio

    @property
    def task(self) -> Task:
        return self.controller.task

    @property
    def kinematics(self) -> ArmKinematics:
        return self.controller.kinematics

    @property
    def action_size(self) -> int:
        return self.controller.action_size

    def begin(self) -> None:
        self.controller.begin()

    def observe(self, reading: ArmReading, estimate: Any, ctrl: np.ndarray) -> dict[str, np.ndarray]:
        own = self.controller.proprio(reading, ctrl)  # poses the arm for `act` whether read or not
        image = self.camera()
        return {IMAGE: image, PROPRIO: own} if self.reads_proprio else {IMAGE: image}

    def act(self, reading: ArmReading, ctrl: np.ndarray, action: np.ndarray) -> np.ndarray:
        return self.controller.act(reading, ctrl, action)

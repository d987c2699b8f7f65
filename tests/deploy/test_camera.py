"""The deployment loop's camera (`jaxarm.deploy.camera`, MuJoCo's OpenGL renderer) against the env's own ray caster,
on the same scene at the same pose: the policy sees what it was trained on; and the loop driving a camera policy
in stock MuJoCo, with jaxarm's Panda and menagerie's.

Measured at the start posture, 64 pixels (mean |difference| of gray levels 0-255; depth levels are 1/255 m): the
peg's scene camera 0.17, its wrist camera 0.77, the sorter's 0.49 and 0.17; depth 0.04 and 0.00, 0.17 and 0.00.
The sorter's wrist camera 6 cm over the table: 0.58 (26.07 with box faces of MuJoCo's default 4 × 4 quads). Drawn
as the MJCF declares (its lights, textures), the same images differ by 51-79 gray levels.

Rendering needs an offscreen GL; MUJOCO_GL defaults to egl here (Mesa's software EGL works without a GPU).
"""

import copy
import os
from types import SimpleNamespace

os.environ.setdefault("MUJOCO_GL", "egl")

import jax
import mujoco
import numpy as np
import pytest

from experiments.benchmarks.deploy import random_camera_policy, random_inputs
from experiments.transfer import MODELS, plant_model
from jaxarm import deployable
from jaxarm.deploy.camera import CameraController, CameraRenderer, depth_of
from jaxarm.deploy.loop import DeploymentLoop
from jaxarm.deploy.mujoco_robot import MujocoRobot
from jaxarm.deploy.reading import HoleEstimate
from jaxarm.envs.panda.base import CAMERAS, CONTROL_DT, ArmOptions
from jaxarm.envs.panda.robot import resolve_robot_ids
from jaxarm.envs.panda_sort import PandaSort
from jaxarm.envs.panda_sort.layout import SHAPE_CUBE, SHAPE_CYLINDER, SHAPE_SPHERE
from jaxarm.envs.panda_sort.render import dress_objects
from jaxarm.envs.peg_insert import PegInsert
from jaxarm.envs.peg_insert.model import HOLE_NOMINAL
from jaxarm.robots import PANDA

RESOLUTION = 32


def cast_image(env, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """The env's ray-cast image (uint8 [R, R, 2 per camera]) of `model`'s scene posed in `data` (after a forward)."""
    poses = SimpleNamespace(**{name: getattr(data, name) for name in ("geom_xpos", "geom_xmat", "xpos", "xmat")})
    sizes = SimpleNamespace(geom_size=model.geom_size)
    return np.asarray(env.camera_image(sizes, poses, env.default_params(), jax.random.key(0)))


@pytest.fixture(scope="module")
def both_images():
    """(MuJoCo's image, the caster's image, the drawn image as the MJCF declares it) of the peg's scene, the arm
    at its start posture, uint8 [R, R, 4] each."""
    env = PegInsert(options=ArmOptions(obs_mode="pixels", resolution=RESOLUTION))
    model = copy.copy(env.mj_model)
    data = mujoco.MjData(model)
    data.qpos[env.ids.robot.arm_qpos] = env.start_qpos
    mujoco.mj_forward(model, data)
    cast = cast_image(env, model, data)
    drawn = []
    for as_env in (True, False):
        renderer = CameraRenderer(model, CAMERAS, RESOLUTION, as_env=as_env)
        drawn.append(renderer.image(data))
        renderer.close()
    return drawn[0], np.asarray(cast), drawn[1]


def test_mujocos_renderer_draws_the_casters_image(both_images):
    drawn, cast, _ = both_images
    assert drawn.shape == cast.shape == (RESOLUTION, RESOLUTION, 2 * len(CAMERAS)) and drawn.dtype == np.uint8
    difference = np.abs(drawn.astype(int) - cast.astype(int))
    gray, depth = difference[..., 0::2], difference[..., 1::2]
    # Edges sampled differently account for the rest: few pixels, most a level or two.
    assert gray.mean() < 2.0 and np.percentile(gray, 95) <= 4, gray.mean(axis=(0, 1))
    assert np.mean(depth > 2) < 0.01, np.mean(depth > 2, axis=(0, 1))
    assert cast[..., 0::2].std() > 20 and cast[..., 1::2].std() > 10, "the cameras see the scene, not a blank"


def test_the_scene_as_its_mjcf_declares_it_is_another_camera(both_images):
    drawn, cast, stock = both_images
    np.testing.assert_array_equal(stock[..., 1::2], drawn[..., 1::2])  # the same geometry
    assert np.abs(stock[..., 0::2].astype(int) - cast[..., 0::2]).mean() > 20  # textures, lights


def test_a_camera_the_scene_lacks_is_named():
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><camera name='c'/></worldbody></mujoco>")
    with pytest.raises(KeyError, match="hand_camera"):
        CameraRenderer(model, ("c", "hand_camera"), 8)


@pytest.mark.parametrize("model_name", MODELS)
def test_the_loop_drives_a_camera_policy_with_either_pandas_scene(model_name):
    env = PegInsert(options=ArmOptions(obs_mode="pixels+proprio", resolution=16))
    params = env.default_params()
    robot = MujocoRobot(plant_model(env, params, model_name), CONTROL_DT)
    robot.data.qpos[resolve_robot_ids(robot.model, PANDA).arm_qpos] = env.start_qpos
    mujoco.mj_forward(robot.model, robot.data)
    camera = deployable.camera_renderer(env, robot.model)
    controller = deployable.camera_controller(env, params, camera, robot.data)
    policy = random_camera_policy((16, 16, 4), 9, 3, np.random.default_rng(0))
    seen = []
    loop = DeploymentLoop(lambda obs: seen.append(obs) or policy(obs), controller, CONTROL_DT)
    hole = HoleEstimate(np.array(HOLE_NOMINAL))
    loop.begin(np.concatenate([env.start_qpos, [0.0, 0.0]]))
    for _ in range(4):
        reading = robot.reading()
        # The proprio part is the state observation's arm part (the env's pixel mode observes the same).
        state = controller.controller.observe(reading, hole, loop.ctrl)
        robot.command(loop.tick(reading, None))
        np.testing.assert_array_equal(seen[-1]["proprio"], state[3:])
        robot.step()
    camera.close()
    assert [sorted(obs) for obs in seen] == [["image", "proprio"]] * 4
    assert all(obs["image"].shape == (16, 16, 4) and obs["image"].dtype == np.uint8 for obs in seen)
    assert not np.array_equal(seen[0]["image"][..., 2:], seen[-1]["image"][..., 2:]), "the wrist camera moves"
    assert np.abs(robot.reading().arm_q - env.start_qpos).max() > 1e-3, "the policy moved the arm"


def test_the_wrist_camera_just_over_the_table_sees_it_lit_as_the_caster_does():
    # Where the sorter grasps, the wrist camera looks at the table from a few cm; OpenGL lights a triangle at its
    # corners alone, so the table's faces must be cut fine enough for the bright spot under the camera to show.
    env = PandaSort(options=ArmOptions(obs_mode="pixels", resolution=64))
    model = copy.copy(env.mj_model)  # the env's model stays as built
    data = mujoco.MjData(model)
    data.qpos[env.ids.robot.arm_qpos] = env.start_qpos + np.array([0.0, 0.4, 0.0, 0.0, 0.0, 0.0, 0.0])
    mujoco.mj_forward(model, data)
    assert data.site_xpos[env.ids.robot.tcp_site][2] < 0.07, "the gripper a few cm over the table"
    cast = cast_image(env, model, data)
    renderer = CameraRenderer(model, CAMERAS, 64)
    drawn = renderer.image(data)
    renderer.close()
    wrist_gray = np.abs(drawn[..., 2].astype(int) - cast[..., 2])
    assert wrist_gray.mean() < 1.5 and np.percentile(wrist_gray, 95) <= 3, (wrist_gray.mean(), wrist_gray.max())
    assert model.vis.quality.numquads == env.mj_model.vis.quality.numquads, "the model's own setting is back"


def test_a_surface_a_centimetre_from_a_camera_is_drawn():
    # MuJoCo's near plane is a hundredth of the model's extent (2.7 cm in the sorter's scene); the caster has none.
    xml = """<mujoco><statistic extent="2.7"/><worldbody><geom type="box" size="0.1 0.1 0.01"/>
      <camera name="c" pos="0 0 0.02"/></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    renderer = CameraRenderer(model, ("c",), 8)
    image = renderer.image(data)
    renderer.close()
    np.testing.assert_array_equal(image[..., 1], depth_of(np.full((8, 8), 0.01)))


def test_an_image_after_a_physics_step_shows_the_scene_where_the_step_left_it():
    # mj_step leaves the poses of the step's start beside the qpos it integrated: the wrist camera drawn from them
    # lagged the arm by 10 ms in the sorter's scene, where the caster draws the state's own qpos.
    env = PandaSort(options=ArmOptions(obs_mode="pixels", resolution=RESOLUTION))
    model = copy.copy(env.mj_model)
    data = mujoco.MjData(model)
    data.qpos[env.ids.robot.arm_qpos] = env.start_qpos
    data.qvel[env.ids.robot.arm_qpos] = 2.0  # rad/s on every arm joint: the arm's qpos doubles as its dof address
    mujoco.mj_step(model, data)
    stale = data.geom_xpos.copy()
    renderer = CameraRenderer(model, CAMERAS, RESOLUTION)
    drawn = renderer.image(data)
    np.testing.assert_array_equal(data.geom_xpos, stale)  # the robot's data is left as the step left it
    mujoco.mj_forward(model, data)
    assert np.abs(data.geom_xpos - stale).max() > 1e-3, "the step moved the arm"
    np.testing.assert_array_equal(drawn, renderer.image(data))
    renderer.close()
    cast = cast_image(env, model, data)
    assert np.abs(drawn[..., 2].astype(int) - cast[..., 2]).mean() < 1.5


def test_a_sorter_camera_policy_reads_the_state_observations_tool_part():
    env = PandaSort(options=ArmOptions(obs_mode="pixels+proprio", resolution=8))
    params = env.default_params()
    controller = deployable.controller(env, params)
    image = np.zeros((8, 8, 4), np.uint8)
    camera = CameraController(deployable.controller(env, params), lambda: image, proprio=True)
    rng = np.random.default_rng(0)
    for _ in range(3):
        reading, objects = random_inputs(controller, env.start_qpos, rng)
        ctrl = np.concatenate([reading.arm_q + 0.01, [0.02, 0.02]])
        state, obs = controller.observe(reading, objects, ctrl), camera.observe(reading, None, ctrl)
        proprio_size = env.spec.observation_parts["proprio"].shape[0]
        np.testing.assert_array_equal(obs["proprio"], state[-proprio_size:])
        assert obs["image"] is image
        action = rng.uniform(-1, 1, controller.action_size)
        np.testing.assert_array_equal(camera.act(reading, ctrl, action), controller.act(reading, ctrl, action))


@pytest.mark.parametrize("shape", [SHAPE_CUBE, SHAPE_CYLINDER, SHAPE_SPHERE])
def test_a_sorter_object_dressed_for_videos_is_drawn_as_the_caster_sees_it(shape):
    # Each shape hides the others' geoms; a cylinder is drawn for videos by a geom of its own, which the caster
    # never sees (it sees the collision prism the episode made transparent): drawn with the episode's alphas, the
    # renderer left cylinders out of every image.
    env = PandaSort(options=ArmOptions(obs_mode="pixels", resolution=64))
    model = copy.copy(env.mj_model)  # the env's model stays as built
    renderer = CameraRenderer(model, CAMERAS, 64)
    size, ids = 0.05, env.ids
    # As an episode dresses the robot's scene: the object's shape, size and a colour for the video.
    dress_objects(model, ids, np.array([shape]), np.array([size]), np.array([[0.1, 0.9, 0.1]]))
    data = mujoco.MjData(model)
    data.qpos[env.ids.robot.arm_qpos] = env.start_qpos
    data.qpos[ids.object_qpos[0] : ids.object_qpos[0] + 7] = [0.5, -0.05, size, 1, 0, 0, 0]
    mujoco.mj_forward(model, data)
    cast = cast_image(env, model, data)
    drawn, recoloured = renderer.image(data), CameraRenderer(model, CAMERAS, 64)
    renderer.close()
    as_dressed = recoloured.image(data)
    recoloured.close()
    segment = mujoco.Renderer(model, 64, 64)
    segment.enable_segmentation_rendering()
    segment.update_scene(data, camera=CAMERAS[0])
    on_object = np.isin(segment.render()[..., 0], [*ids.object_geom[0], ids.object_visual[0]])
    segment.close()
    assert on_object.sum() >= 12, "the scene camera sees the object"
    # Medians: an object of 15-21 pixels is mostly edges, where the two sample differently (edge pixels differ by 8-37).
    difference = np.abs(drawn.astype(int) - cast)[on_object]
    assert np.median(difference[:, 0]) <= 1 and np.median(difference[:, 1]) <= 1, np.median(difference, axis=0)
    assert np.median(np.abs(as_dressed[..., 0].astype(int) - cast[..., 0])[on_object]) > 20  # its video colour

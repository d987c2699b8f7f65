"""The analytic ray caster of the Panda envs' cameras against geometry worked by hand and MuJoCo's own mj_ray.

A small scene of every primitive, posed by MuJoCo on the CPU (no MJX program to compile): the caster reads
poses and sizes as arrays.
"""

import copy
import itertools
from functools import partial
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from jaxarm.envs.panda.base import CAMERAS, DEPTH_RANGE, ArmOptions, image_channels
from jaxarm.envs.panda.camera import AMBIENT, FAR, Camera, PoseOffset, Scene, ray_directions, render, rotation_of
from jaxarm.envs.panda.sim_to_real import RobotParams
from jaxarm.envs.panda_sort import PandaSort
from jaxarm.envs.panda_sort.layout import SHAPE_CUBE, SHAPE_CYLINDER, SHAPE_SPHERE
from jaxarm.envs.panda_sort.objects import object_geom_sizes
from jaxarm.envs.peg_insert import PegInsert

HEIGHT = 1.0
"""The overhead camera's height above the table."""
FOVY = 60.0
RESOLUTION = 32
BOX_HALF = 0.1
BOX_TOP = 0.2
SCENE = f"""
<mujoco>
  <worldbody>
    <geom name="table" type="plane" size="2 2 0.1" rgba="0.5 0.5 0.5 1"/>
    <body name="box" pos="0 0 {BOX_TOP / 2}">
      <freejoint/>
      <geom name="box" type="box" size="{BOX_HALF} {BOX_HALF} {BOX_TOP / 2}" rgba="1 1 1 1"/>
    </body>
    <body name="others" pos="0.35 0.3 0.1">
      <freejoint/>
      <camera name="carried" pos="0.1 0 0.3" euler="0.3 -0.2 0.1" fovy="50"/>
      <geom name="sphere" type="sphere" size="0.05" pos="0 0 0" rgba="1 0 0 1"/>
      <geom name="capsule" type="capsule" size="0.03 0.06" pos="-0.6 0 0" euler="0 1.2 0.3" rgba="0 1 0 1"/>
      <geom name="cylinder" type="cylinder" size="0.04 0.05" pos="0 -0.6 0" euler="0.4 0 0" rgba="0 0 1 1"/>
    </body>
    <camera name="overhead" pos="0 0 {HEIGHT}" fovy="{FOVY}"/>
    <camera name="oblique" pos="0.8 -0.6 0.6" xyaxes="0.6 0.8 0 -0.4 0.3 0.866" fovy="50"/>
  </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def scene():
    model = mujoco.MjModel.from_xml_string(SCENE)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def image(model, data, camera="overhead", resolution=RESOLUTION, offset=None):
    """(depth, gray) [R, R] of `camera`, moved by `offset` (a `PoseOffset`; None: the default argument)."""
    arrays = (data.geom_xpos, data.geom_xmat, data.xpos, data.xmat)
    cast = jax.jit(partial(render, Scene.from_model(model), Camera.from_model(model, camera), resolution))
    return cast(model.geom_size, *arrays) if offset is None else cast(model.geom_size, *arrays, offset)


def pose_offset(shift=(0.0, 0.0, 0.0), turn=(0.0, 0.0, 0.0)) -> PoseOffset:
    return PoseOffset(jnp.asarray(shift, jnp.float32), jnp.asarray(turn, jnp.float32))


def test_depth_of_the_table_is_the_cameras_height(scene):
    model, data = scene
    depth, gray = (np.asarray(a) for a in image(*scene))
    corners = depth[[0, 0, -1, -1], [0, -1, 0, -1]]  # the table, away from the box
    np.testing.assert_allclose(corners, HEIGHT, atol=1e-3)
    assert np.all(depth <= HEIGHT + 1e-3) and np.all(gray > 0)


def test_gray_is_the_surfaces_luma_lit_by_the_cosine_of_its_ray(scene):
    depth, gray = (np.asarray(a) for a in image(*scene))
    # Every visible surface straight below the overhead camera faces up: cos is the ray's vertical component.
    cosine = -np.asarray(ray_directions(FOVY, RESOLUTION))[..., 2]
    lit = AMBIENT + (1 - AMBIENT) * cosine
    on_box = np.abs(depth - (HEIGHT - BOX_TOP)) < 1e-3
    on_table = np.abs(depth - HEIGHT) < 1e-3
    assert on_box.sum() > 16 and on_table.sum() > 16
    np.testing.assert_allclose(gray[on_box], 1.0 * lit[on_box], atol=1e-5)  # white
    np.testing.assert_allclose(gray[on_table], 0.5 * lit[on_table], atol=1e-5)  # gray 0.5


def test_a_box_of_known_size_covers_the_predicted_pixels(scene):
    depth = np.asarray(image(*scene)[0])
    on_box = np.abs(depth - (HEIGHT - BOX_TOP)) < 1e-3
    # The box top's half-width seen from the camera, in pixels from the image centre.
    half_pixels = BOX_HALF / (HEIGHT - BOX_TOP) / np.tan(np.deg2rad(FOVY) / 2) * RESOLUTION / 2
    rows, columns = np.nonzero(on_box)
    for indices in (rows, columns):
        np.testing.assert_allclose(
            [indices.min(), indices.max() + 1], RESOLUTION / 2 + np.array([-1, 1]) * half_pixels, atol=1
        )


def test_the_image_changes_when_something_in_view_moves_and_not_otherwise(scene):
    model, _ = scene
    data = mujoco.MjData(model)
    data.qpos[7] = 5.0  # the sphere, capsule and cylinder, out of the overhead camera's view
    mujoco.mj_forward(model, data)
    before = [np.asarray(a) for a in image(model, data)]
    data.qpos[7] = 6.0  # moved, still out of view
    mujoco.mj_forward(model, data)
    for first, second in zip(before, image(model, data), strict=True):
        np.testing.assert_array_equal(first, second)
    data.qpos[0] += 0.05  # the box, in view
    mujoco.mj_forward(model, data)
    moved = [np.asarray(a) for a in image(model, data)]
    assert not np.array_equal(before[0], moved[0]) and not np.array_equal(before[1], moved[1])


CROWD = """
<mujoco>
  <worldbody>
    <geom type="plane" size="0 0 0.1" rgba="0.4 0.4 0.4 1"/>
    <geom type="box" size="0.05 0.08 0.04" pos="0 0 0.04" euler="0 0 0.3" rgba="1 0 0 1"/>
    <geom type="box" size="0.03 0.03 0.12" pos="0.1 -0.05 0.12" euler="0.2 0.1 0" rgba="0 1 0 1"/>
    <geom type="box" size="0.2 0.02 0.02" pos="-0.05 0.1 0.15" euler="0 0.3 0.5" rgba="0 0 1 1"/>
    <geom type="box" size="0.1 0.1 0.1" pos="0 0 0.1" rgba="1 1 1 0"/>
    <geom type="sphere" size="0.06" pos="0.15 0.1 0.06" rgba="1 1 0 1"/>
    <geom type="sphere" size="0.04" pos="0.2 0.05 0.2" rgba="0 1 1 1"/>
    <geom type="capsule" size="0.02 0.1" pos="-0.1 -0.1 0.1" euler="1.2 0 0.4" rgba="1 0 1 1"/>
    <geom type="capsule" size="0.03 0.05" pos="0.05 0.2 0.05" euler="0 1.5 0" rgba="0.8 0.5 0.2 1"/>
    <geom type="capsule" size="0.015 0.15" pos="0 -0.2 0.2" euler="0.3 0.9 0" rgba="0.2 0.5 0.8 1"/>
    <geom type="cylinder" size="0.05 0.03" pos="-0.2 0.05 0.03" rgba="0.6 0.2 0.6 1"/>
    <geom type="cylinder" size="0.03 0.08" pos="-0.15 0.15 0.2" euler="0.5 0.5 0" rgba="0.3 0.9 0.3 1"/>
    <camera name="oblique" pos="0.8 -0.6 0.6" xyaxes="0.6 0.8 0 -0.4 0.3 0.866" fovy="40"/>
  </worldbody>
</mujoco>
"""
"""Several geoms of every type, overlapping in the camera's view, and one hidden box (alpha 0) around the first."""


@pytest.mark.parametrize(
    ("xml", "camera", "geoms_seen"), [(SCENE, "overhead", 5), (SCENE, "oblique", 4), (CROWD, "oblique", 10)]
)
def test_images_match_mujocos_ray_caster(xml, camera, geoms_seen):
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    resolution = 16
    depth, gray = (np.asarray(a) for a in image(model, data, camera, resolution))
    cam = Camera.from_model(model, camera)
    position, rotation = (np.asarray(a) for a in cam.world_pose(jnp.asarray(data.xpos), jnp.asarray(data.xmat)))
    scene = Scene.from_model(model)
    luma = dict(zip(scene.geoms, scene.luma, strict=True))
    half = np.tan(np.deg2rad(cam.fovy) / 2)
    geom_id = np.zeros(1, np.int32)
    normal = np.zeros(3)
    hits, hit_geoms = 0, set()
    for row in range(resolution):
        for column in range(resolution):
            local = np.array(
                [(2 * (column + 0.5) / resolution - 1) * half, -(2 * (row + 0.5) / resolution - 1) * half, -1.0]
            )
            local /= np.linalg.norm(local)
            ray = rotation @ local
            distance = mujoco.mj_ray(model, data, position, ray, None, 1, -1, geom_id, normal)
            pixel = f"pixel {row}, {column}"
            if distance < 0:
                assert depth[row, column] == FAR and gray[row, column] == 0, pixel
                continue
            hits += 1
            hit_geoms.add(int(geom_id[0]))
            np.testing.assert_allclose(depth[row, column], distance * -local[2], atol=1e-4, err_msg=pixel)
            # Within a quarter of a gray level: a float32 cosine on a thin curved geom, (b + t) / r, loses ~1e-4.
            lit = AMBIENT + (1 - AMBIENT) * abs(normal @ ray)
            np.testing.assert_allclose(gray[row, column], luma[int(geom_id[0])] * lit, atol=1e-3, err_msg=pixel)
    assert hits > resolution * resolution // 2 and len(hit_geoms) == geoms_seen


def test_a_state_env_resolves_no_camera_and_says_so_when_asked_for_an_image():
    env = PegInsert()
    assert env.cameras == ()
    with pytest.raises(ValueError, match="pixel obs_mode"):
        env.camera_image(env.mjx_model, None, env.default_params(), jax.random.key(0))


def test_a_privileged_sorter_declares_its_state_observation_beside_the_cameras():
    # Its values come from the same `_observe` as the state env's (see PandaSort._observe); stepping it would
    # compile MJX, minutes on a CPU.
    spec = PandaSort(options=ArmOptions(obs_mode="pixels+proprio", resolution=16, privileged=True)).spec
    assert set(spec.observation) == {"image", "proprio", "privileged"}
    assert spec.observation["privileged"].shape == PandaSort().spec.observation_shape


def test_a_privileged_peg_declares_its_state_observation_beside_the_cameras():
    spec = PegInsert(options=ArmOptions(obs_mode="pixels", resolution=16, privileged=True)).spec
    assert set(spec.observation) == {"image", "privileged"}
    assert spec.observation["privileged"].shape == PegInsert().spec.observation_shape
    with pytest.raises(ValueError, match="privileged=True adds the state observation to a pixel obs_mode"):
        PegInsert(options=ArmOptions(privileged=True))


def test_the_cast_program_does_not_grow_with_the_number_of_geoms():
    def equations(xml):
        model = mujoco.MjModel.from_xml_string(xml)
        data = mujoco.MjData(model)
        cast = partial(render, Scene.from_model(model), Camera.from_model(model, "oblique"), 8)
        return len(jax.make_jaxpr(cast)(model.geom_size, data.geom_xpos, data.geom_xmat, data.xpos, data.xmat).eqns)

    more_boxes = '<geom type="box" size="0.02 0.02 0.02" pos="0.3 0 0.02" rgba="1 1 1 1"/>\n' * 5
    assert equations(CROWD) == equations(CROWD.replace("  <camera", more_boxes + "  <camera"))


def test_a_zero_pose_offset_moves_no_camera_by_a_single_bit(scene):
    model, data = scene
    # Traced zeros, as the params hold them, cannot be folded away by the compiler.
    for camera in ("overhead", "oblique", "carried"):
        for nominal, offset in zip(
            image(model, data, camera), image(model, data, camera, offset=pose_offset()), strict=True
        ):
            np.testing.assert_array_equal(nominal, offset)
        cam = Camera.from_model(model, camera)
        body_rotation = jnp.asarray(data.xmat[cam.body]).reshape(3, 3)
        pose = jax.jit(cam.world_pose)(jnp.asarray(data.xpos), jnp.asarray(data.xmat), pose_offset())
        # The pose as formed without an offset.
        np.testing.assert_array_equal(pose[0], data.xpos[cam.body] + jnp.matmul(body_rotation, cam.position))
        np.testing.assert_array_equal(pose[1], jnp.matmul(body_rotation, cam.rotation))


def test_a_camera_moved_back_sees_the_table_that_much_deeper(scene):
    depth = np.asarray(image(*scene, offset=pose_offset(shift=(0.0, 0.0, 0.03)))[0])
    np.testing.assert_allclose(depth[[0, 0, -1, -1], [0, -1, 0, -1]], HEIGHT + 0.03, atol=1e-3)


def test_a_camera_moved_sideways_sees_the_box_move_the_other_way_by_the_predicted_pixels(scene):
    # A shift of two pixels' width at the box top's depth moves its top by two whole columns.
    pixel_width = 2 * (HEIGHT - BOX_TOP) * np.tan(np.deg2rad(FOVY) / 2) / RESOLUTION
    box_top = [
        np.abs(np.asarray(image(*scene, offset=pose_offset(shift=shift))[0]) - (HEIGHT - BOX_TOP)) < 1e-3
        for shift in ((0.0, 0.0, 0.0), (2 * pixel_width, 0.0, 0.0))
    ]
    assert box_top[0].sum() > 16
    np.testing.assert_array_equal(box_top[1], np.roll(box_top[0], -2, axis=1))


def test_a_quarter_roll_turns_the_image_a_quarter_clockwise(scene):
    for nominal, rolled in zip(
        image(*scene), image(*scene, offset=pose_offset(turn=(0.0, 0.0, np.pi / 2))), strict=True
    ):
        np.testing.assert_allclose(rolled, np.rot90(np.asarray(nominal), -1), atol=1e-5)


def test_pitch_looks_up_and_yaw_looks_left():
    forward = np.array([0.0, 0.0, -1.0])  # a camera's view, in its own frame (x right, y up)
    assert (np.asarray(rotation_of(jnp.array([0.1, 0.0, 0.0]))) @ forward)[1] > 0.09
    assert (np.asarray(rotation_of(jnp.array([0.0, 0.1, 0.0]))) @ forward)[0] < -0.09


@pytest.mark.parametrize("camera", ["oblique", "carried"])
def test_an_offset_camera_sees_what_a_camera_placed_there_in_the_mjcf_sees(scene, camera):
    model, _ = scene
    data = mujoco.MjData(model)
    data.qpos[7:14] = [0.3, 0.25, 0.12, *np.array([0.9, 0.1, -0.2, 0.3]) / np.linalg.norm([0.9, 0.1, -0.2, 0.3])]
    mujoco.mj_forward(model, data)
    shift, turn = np.array([0.006, -0.004, 0.005]), np.deg2rad([2.0, -1.5, 2.5])
    # The same camera moved in the MJCF: its position by the shift in its own frame, its quaternion turned by the
    # rotation vector after its own (MuJoCo's quaternion maths, independent of the caster's).
    moved = copy.copy(model)
    camera_id = model.camera(camera).id
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, model.cam_quat[camera_id])
    moved.cam_pos[camera_id] = model.cam_pos[camera_id] + rotation.reshape(3, 3) @ shift
    turned, quat = np.zeros(4), np.zeros(4)
    mujoco.mju_axisAngle2Quat(turned, turn / np.linalg.norm(turn), np.linalg.norm(turn))
    mujoco.mju_mulQuat(quat, model.cam_quat[camera_id], turned)
    moved.cam_quat[camera_id] = quat
    moved_data = mujoco.MjData(moved)
    moved_data.qpos[:] = data.qpos
    mujoco.mj_forward(moved, moved_data)
    offset = pose_offset(shift, turn)
    position, rotation = Camera.from_model(model, camera).world_pose(
        jnp.asarray(data.xpos), jnp.asarray(data.xmat), offset
    )
    np.testing.assert_allclose(position, moved_data.cam_xpos[camera_id], atol=1e-6)
    np.testing.assert_allclose(np.asarray(rotation).ravel(), moved_data.cam_xmat[camera_id], atol=1e-6)
    offset_depth, offset_gray = image(model, data, camera, offset=offset)
    placed_depth, placed_gray = image(moved, moved_data, camera)
    np.testing.assert_allclose(offset_depth, placed_depth, atol=1e-4)
    np.testing.assert_allclose(offset_gray, placed_gray, atol=1e-4)
    assert np.abs(np.asarray(image(model, data, camera)[0]) - np.asarray(offset_depth)).max() > 0.01, "it moved"


def test_image_channels_scale_and_shift_the_gray_shift_the_depth_and_saturate():
    # Two cameras: gray 0.5 and depth 0.2 m, then gray 0.9 and depth 0.95 m.
    pixel = jnp.array([0.5, 0.2, 0.9, 0.95])
    key = jax.random.key(0)

    def channels(**params):
        return image_channels(pixel, RobotParams(**params), key)

    np.testing.assert_array_equal(channels(), [128, 51, 230, 242])
    np.testing.assert_array_equal(channels(camera_gray_gain=1.5, camera_depth_offset=0.2), [191, 102, 255, 255])
    np.testing.assert_array_equal(channels(camera_gray_gain=0.5, camera_depth_offset=-0.4), [64, 0, 115, 140])
    # The offset adds to the gray after the gain: 0.5 + 0.1 and 0.9 + 0.1; 0.5 · 0.5 − 0.3 and 0.9 · 0.5 − 0.3.
    np.testing.assert_array_equal(channels(camera_gray_offset=0.1), [153, 51, 255, 242])
    np.testing.assert_array_equal(channels(camera_gray_gain=0.5, camera_gray_offset=-0.3), [0, 51, 38, 242])


def test_depth_noise_has_its_std_and_zero_mean_on_depth_alone():
    # 200 x 200 pixels of two cameras at gray 0.5 and depth 0.4 m (level 102): noise of 2 cm spans 5 levels, so
    # rounding to levels adds only (1/255)² / 12 to its variance (Sheppard's correction).
    pixels = jnp.tile(jnp.array([0.5, 0.4, 0.5, 0.4]), (200, 200, 1))
    key = jax.random.key(1)
    noisy = np.asarray(image_channels(pixels, RobotParams(camera_depth_noise=0.02), key)).astype(float)
    np.testing.assert_array_equal(noisy[..., 0::2], 128)
    depth = noisy[..., 1::2] * DEPTH_RANGE / 255
    assert abs(depth.mean() - 0.4) < 3e-4  # 4 standard errors of the mean of 80,000
    np.testing.assert_allclose(depth.std(), np.sqrt(0.02**2 + (DEPTH_RANGE / 255) ** 2 / 12), rtol=0.02)
    assert abs(np.corrcoef(depth[..., 0].ravel(), depth[..., 1].ravel())[0, 1]) < 0.03, "each pixel its own"
    np.testing.assert_array_equal(
        image_channels(pixels, RobotParams(camera_depth_noise=0.0), key), np.tile([128, 102, 128, 102], (200, 200, 1))
    )


POSES = ("geom_xpos", "geom_xmat", "xpos", "xmat")
"""The poses the caster reads, in `render`'s order."""


def vars_of(data: mujoco.MjData) -> dict[str, np.ndarray]:
    """The poses the caster reads of MuJoCo's data."""
    return {name: getattr(data, name) for name in POSES}


@pytest.fixture(scope="module")
def peg_cameras():
    """(a pixel peg env, its model's geom sizes, its poses): posed by MuJoCo on the CPU, so only the caster compiles."""
    env = PegInsert(options=ArmOptions(obs_mode="pixels", resolution=8))
    data = mujoco.MjData(env.mj_model)
    mujoco.mj_forward(env.mj_model, data)
    return env, SimpleNamespace(geom_size=env.mj_model.geom_size), SimpleNamespace(**vars_of(data))


def test_a_panda_cameras_gain_and_offset_change_its_images_as_image_channels_says(peg_cameras):
    env, model, poses = peg_cameras
    image = jax.jit(lambda params: env.camera_image(model, poses, params, jax.random.key(0)))
    params = env.default_params()
    as_simulated = np.asarray(image(params)).astype(int)
    changed = np.asarray(image(params.replace(camera_gray_gain=0.5, camera_depth_offset=0.05))).astype(int)
    np.testing.assert_allclose(changed[..., 0::2], as_simulated[..., 0::2] / 2, atol=1.0)
    depth = as_simulated[..., 1::2] < 255 - 13  # not at the far clip, before or after the 5 cm
    assert depth.mean() > 0.5 and as_simulated[..., 0::2].mean() > 20, "the cameras see the scene"
    np.testing.assert_allclose(changed[..., 1::2][depth], as_simulated[..., 1::2][depth] + 0.05 * 255, atol=1.0)


def test_a_pandas_default_camera_params_leave_its_images_exactly_as_cast(peg_cameras):
    env, model, poses = peg_cameras
    image = jax.jit(lambda params, key: env.camera_image(model, poses, params, key))(
        env.default_params(), jax.random.key(2)
    )
    scene = Scene.from_model(env.mj_model)
    for index, view in enumerate(env.cameras):
        depth, gray = render(scene, view, env.resolution, model.geom_size, *(getattr(poses, name) for name in POSES))
        levels = (np.clip(np.asarray(channel), 0.0, 1.0) * 255 for channel in (gray, depth / DEPTH_RANGE))
        np.testing.assert_array_equal(image[..., 2 * index : 2 * index + 2], np.stack([*map(np.round, levels)], -1))


def test_the_cameras_draw_the_fingers_at_the_params_scale_and_nothing_else_changes():
    # Another model's fingers or the real robot's look otherwise than the model's pads, which the wrist camera sees.
    env = PandaSort(options=ArmOptions(obs_mode="pixels", resolution=32))
    data = mujoco.MjData(env.mj_model)
    data.qpos[env.ids.robot.arm_qpos] = env.start_qpos
    mujoco.mj_forward(env.mj_model, data)
    model, poses = SimpleNamespace(geom_size=env.mj_model.geom_size), SimpleNamespace(**vars_of(data))
    key = jax.random.key(0)
    image = jax.jit(lambda scale: env.camera_image(model, poses, RobotParams(camera_finger_scale=scale), key))
    fingers = env.ids.robot.finger_geoms
    assert [env.mj_model.geom(geom).name for geom in fingers] == ["left_pad", "right_pad"]
    np.testing.assert_array_equal(image(1.0), env.camera_image(model, poses, RobotParams(), key))
    hidden, larger = np.asarray(image(0.0)), np.asarray(image(1.5))
    sizes = env.mj_model.geom_size.copy()
    sizes[fingers] = 0.0
    np.testing.assert_array_equal(hidden, env.camera_image(SimpleNamespace(geom_size=sizes), poses, RobotParams(), key))
    wrist = 2 * env.camera_names.index("hand_camera")
    assert np.sum(hidden[..., wrist] != image(1.0)[..., wrist]) > 0, "the wrist camera sees the pads"
    assert np.sum(larger != image(1.0)) > np.sum(hidden != image(1.0)), "larger pads cover more"


def test_the_peg_draws_its_block_and_table_gray_each_episode_and_the_cameras_see_them(peg_cameras):
    env, model, poses = peg_cameras
    params = env.default_params()
    keys = jax.random.split(jax.random.key(3), 64)
    modelled = np.asarray(env.surface_gray(keys[0], params))
    assert np.all(np.asarray(jax.vmap(env.surface_gray, in_axes=(0, None))(keys, params)) == modelled)
    spread = params.replace(surface_gray_spread=jnp.float32(0.4))
    drawn = np.asarray(jax.vmap(env.surface_gray, in_axes=(0, None))(keys, spread))
    assert np.all(np.abs(drawn - modelled) <= 0.4 + 1e-6) and np.all((drawn >= 0) & (drawn <= 1))
    assert drawn.std(axis=0).min() > 0.15  # each surface's gray moves across the episodes
    image = jax.jit(lambda luma: env.camera_image(model, poses, params, jax.random.key(0), luma))
    as_modelled = np.asarray(image(env.episode_luma(SimpleNamespace(surface_gray=jnp.asarray(modelled)))))
    # The modelled grays are the scene's own: the images stay exactly as cast.
    np.testing.assert_array_equal(as_modelled, np.asarray(image(None)))
    dark = np.asarray(image(env.episode_luma(SimpleNamespace(surface_gray=jnp.zeros(2)))))
    gray, depth = dark[..., 0::2].astype(int), dark[..., 1::2]
    # Black surfaces read only the ambient light's share of nothing: darker wherever they are seen; depth unchanged.
    assert (gray < as_modelled[..., 0::2]).mean() > 0.3
    np.testing.assert_array_equal(depth, as_modelled[..., 1::2])


def test_a_pandas_depth_noise_is_drawn_from_its_sims_noise_key(peg_cameras, monkeypatch):
    # `images` poses the sim with MJX, minutes to compile on a CPU: here the MuJoCo-posed scene stands in for it.
    env, model, poses = peg_cameras
    monkeypatch.setattr(env, "episode_model", lambda sim, params: model)
    monkeypatch.setattr(env, "poses", lambda model, sim: poses)
    params = env.default_params().replace(camera_depth_noise=0.02)
    modelled = env.surface_gray(jax.random.key(0), params)
    images = jax.jit(lambda key: env.images(SimpleNamespace(noise_key=key, surface_gray=modelled), params))
    key = jax.random.key(3)
    first, again, next_step = (np.asarray(images(k)) for k in (key, key, jax.random.split(key)[0]))
    np.testing.assert_array_equal(first, again)
    np.testing.assert_array_equal(first[..., 0::2], next_step[..., 0::2])
    seen = first[..., 1::2] < 255 - 13  # off the far clip, where the noise shows
    assert np.count_nonzero(first[..., 1::2][seen] != next_step[..., 1::2][seen]) > seen.sum() // 2


def test_a_sorters_cameras_see_each_objects_own_shape():
    # The slot's drawing-only cylinder (MAX_OBJECT_SIZE) once hid every object's shape from the cameras.
    env = PandaSort()
    model, ids = copy.copy(env.mj_model), env.ids  # the env is shared: its model stays as built
    assert not set(ids.object_visual) & set(Scene.from_model(model).geoms)
    data = mujoco.MjData(model)

    def scene_depth():
        return np.asarray(image(model, data, camera=CAMERAS[0], resolution=128)[0])

    mujoco.mj_forward(model, data)
    empty = scene_depth()  # the objects parked far out of view
    floor = empty.max()  # past the table's edges the camera sees the floor, 0.75 m below the table top
    assert empty[empty < floor - 0.5].max() < DEPTH_RANGE, "the depth channel spans the table and all on it"
    size, seen = 0.03, {}
    for shape in (SHAPE_CUBE, SHAPE_CYLINDER, SHAPE_SPHERE):
        model.geom_size[ids.object_geom[0]] = np.asarray(object_geom_sizes(np.array([shape]), np.array([size])))[0]
        data.qpos[ids.object_qpos[0] : ids.object_qpos[0] + 7] = [0.5, -0.05, size, 1, 0, 0, 0]
        mujoco.mj_forward(model, data)
        seen[shape] = np.abs(scene_depth() - empty) > 0.005
    # The scene camera looks down at a slant: a cube (4s² from above) shows the most, and no two shapes alike.
    areas = {shape: np.count_nonzero(mask) for shape, mask in seen.items()}
    assert areas[SHAPE_CUBE] > max(areas[SHAPE_CYLINDER], areas[SHAPE_SPHERE]) > 0
    assert all(np.count_nonzero(seen[a] ^ seen[b]) >= 5 for a, b in itertools.combinations(seen, 2))

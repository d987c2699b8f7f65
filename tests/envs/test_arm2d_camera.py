"""arm2d's camera: pixels land where the geometry puts them, and the image follows the arm and nothing else."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm import envs
from jaxarm.envs.arm2d import Arm2d, Arm2dSim
from jaxarm.envs.arm2d.arm import link_end_positions
from jaxarm.envs.arm2d.camera import ARM_LEVEL, GOAL_LEVEL
from jaxarm.envs.observation import with_camera_views
from tests.envs.test_arm2d import start_state

RESOLUTION = 40
"""10 world units per pixel in the default 400-unit world: hand-placed shapes land on whole pixels."""


def image_of(env, params, angles, goal) -> np.ndarray:
    return np.asarray(start_state(env, params, angles, goal).obs["image"][..., 0])


def to_pixel(point, world=400.0, resolution=RESOLUTION) -> tuple[int, int]:
    """(row, column) of the pixel holding world `point` (rows run down the world's y)."""
    scale = resolution / world
    return int((world - point[1]) * scale), int(point[0] * scale)


def test_hand_placed_arm_and_goal_land_on_their_pixels():
    env = Arm2d(obs_mode="pixels", resolution=RESOLUTION)
    params = env.default_params()
    # Both links along +x from the base (200, 200): the arm covers x in [200, 400], y in 200 ± 10 (2 pixels tall).
    # The goal square, side 40, centred at (100, 100): x and y in [80, 120], pixels 8..11 and rows 28..31.
    image = image_of(env, params, [0.0, 0.0], [100.0, 100.0])
    goal_pixels = np.argwhere(image == round(GOAL_LEVEL * 255))
    np.testing.assert_array_equal(goal_pixels.min(axis=0), [28, 8])
    np.testing.assert_array_equal(goal_pixels.max(axis=0), [31, 11])
    arm_pixels = np.argwhere(image == round(ARM_LEVEL * 255))
    np.testing.assert_array_equal(np.unique(arm_pixels[:, 0]), [19, 20])
    assert arm_pixels[:, 1].min() == 20 and arm_pixels[:, 1].max() == RESOLUTION - 1
    # Nothing else is drawn: every lit pixel outside the goal is within one pixel of the arm's band.
    lit = np.argwhere(image > 0)
    outside_goal = lit[~((lit[:, 0] >= 28) & (lit[:, 0] <= 31) & (lit[:, 1] >= 8) & (lit[:, 1] <= 11))]
    assert outside_goal[:, 0].min() >= 18 and outside_goal[:, 0].max() <= 21 and outside_goal[:, 1].min() >= 19


@pytest.mark.parametrize("angles", [[0.3, 1.1], [2.0, -0.7], [4.0, 2.5]])
def test_the_finger_and_elbow_are_bright_where_geometry_puts_them(angles):
    env = Arm2d(obs_mode="pixels", resolution=RESOLUTION)
    params = env.default_params()
    image = image_of(env, params, angles, [380.0, 380.0])
    elbow, finger = np.asarray(link_end_positions(jnp.asarray(angles, jnp.float32), params))
    for point in (elbow, finger):
        row, column = to_pixel(point)
        # Within one pixel of the predicted one, the link is drawn at full brightness.
        window = image[max(row - 1, 0) : row + 2, max(column - 1, 0) : column + 2]
        assert window.max() == 255, (point, window)


def test_the_image_changes_when_the_arm_moves_and_not_otherwise():
    env = Arm2d(obs_mode="pixels+proprio")
    params = env.default_params()
    state = start_state(env, params, [0.5, 0.5], [100.0, 100.0])
    step = jax.jit(env.step)
    still = step(state, jnp.zeros(2), params)
    np.testing.assert_array_equal(still.obs["image"], state.obs["image"])
    np.testing.assert_array_equal(still.obs["proprio"], state.obs["proprio"])
    # The smallest move of one step at a tenth of full speed (0.01 rad: 2 world units at the finger, a third of
    # a 64-pixel image's pixel) still shows through the anti-aliased edges.
    moved = step(state, jnp.array([0.0, 0.1]), params)
    assert not np.array_equal(moved.obs["image"], state.obs["image"])
    # The goal is in the image only; the proprio part is the link ends' positions, as in the state observation.
    other_goal = start_state(env, params, [0.5, 0.5], [300.0, 100.0])
    assert not np.array_equal(other_goal.obs["image"], state.obs["image"])
    np.testing.assert_array_equal(other_goal.obs["proprio"], state.obs["proprio"])
    flat = start_state(envs.make("arm2d"), params, [0.5, 0.5], [100.0, 100.0]).obs
    np.testing.assert_allclose(state.obs["proprio"], flat[:4])


def test_obs_mode_and_resolution_are_checked():
    with pytest.raises(ValueError, match="obs_mode must be one of state, pixels, pixels\\+proprio"):
        Arm2d(obs_mode="rgb")
    with pytest.raises(ValueError, match=r"^resolution must be in \[8, 1024\], got 4$"):
        Arm2d(obs_mode="pixels", resolution=4)
    # Before: XLA's out-of-memory traceback (256 TB) at the first reset, and a float side's TypeError.
    with pytest.raises(ValueError, match=r"^resolution must be in \[8, 1024\], got 1000000$"):
        Arm2d(obs_mode="pixels", resolution=1_000_000)
    with pytest.raises(ValueError, match=r"^resolution must be an integer, got 16.5$"):
        Arm2d(obs_mode="pixels", resolution=16.5)
    spec = Arm2d(obs_mode="pixels", resolution=32).spec
    assert spec.observation["image"].shape == (32, 32, 1) and not spec.flat_observation
    with pytest.raises(ValueError, match="no single size"):
        _ = spec.observation_size


def test_sim_is_unchanged_by_the_observation_mode():
    key = jax.random.key(3)
    params = Arm2d().default_params()
    state_sim = Arm2d().reset(key, params).sim
    pixel_sim = Arm2d(obs_mode="pixels").reset(key, params).sim
    assert isinstance(pixel_sim, Arm2dSim)
    jax.tree.map(np.testing.assert_array_equal, state_sim, pixel_sim)


@pytest.mark.parametrize("obs_mode", ["pixels", "pixels+proprio"])
def test_a_privileged_camera_env_observes_the_state_observation_of_the_same_step(obs_mode):
    plain, privileged = Arm2d(), Arm2d(obs_mode=obs_mode, resolution=16, privileged=True)
    params = plain.default_params()
    assert privileged.spec.observation["privileged"] == jax.ShapeDtypeStruct((9,), jnp.float32)
    state, camera = plain.reset(jax.random.key(2), params), privileged.reset(jax.random.key(2), params)
    for action in ([0.0, 0.0], [1.0, -0.5], [-1.0, 1.0]):
        np.testing.assert_array_equal(camera.obs["privileged"], state.obs)
        state = plain.step(state, jnp.array(action), params)
        camera = privileged.step(camera, jnp.array(action), params)
    assert "privileged" not in Arm2d(obs_mode=obs_mode).spec.observation
    with pytest.raises(ValueError, match='"state" observes it alone'):
        Arm2d(privileged=True)


def test_video_frames_show_the_camera_beside_the_scene():
    env = Arm2d(obs_mode="pixels", resolution=RESOLUTION)
    params = env.default_params()
    state = start_state(env, params, [0.0, 0.0], [100.0, 100.0])
    frame = env.render(state, params)
    combined = with_camera_views(frame, state.obs)
    scale = frame.shape[0] // RESOLUTION
    assert combined.shape == (frame.shape[0], frame.shape[1] + scale * RESOLUTION, 3)
    np.testing.assert_array_equal(combined[:, : frame.shape[1]], frame)
    camera_tile = combined[: scale * RESOLUTION : scale, frame.shape[1] :: scale, 0]
    np.testing.assert_array_equal(camera_tile, state.obs["image"][..., 0])
    flat = envs.make("arm2d")
    np.testing.assert_array_equal(with_camera_views(frame, flat.reset(jax.random.key(0), params).obs), frame)


@pytest.mark.parametrize("episode_steps, staggered", [(5, True), (3, False)])
def test_a_batch_draws_new_episodes_images_as_one_env_at_a_time_does(episode_steps, staggered):
    """Staggered, three or four of 16 episodes end per step: their first images are drawn in two groups of two
    gathered envs. Together, every episode ends at once: eight groups. Either way the batch matches AutoReset
    env by env, and every observed image is what the camera sees in the env's sim."""
    env = Arm2d(obs_mode="pixels+proprio", resolution=16)
    params = env.default_params().replace(max_episode_steps=jnp.array(episode_steps, jnp.int32))
    num_envs = 16
    batch = envs.VmapEnv(envs.AutoReset(env), num_envs)
    one_at_a_time = jax.jit(jax.vmap(envs.AutoReset(env).step, in_axes=(0, 0, None)))
    state = batch.reset(jax.random.key(0), params)
    if staggered:
        state = state.replace(step_count=jnp.arange(num_envs, dtype=jnp.int32) % episode_steps)
    step = jax.jit(batch.step)
    starts = 0
    for action_key in jax.random.split(jax.random.key(1), 2 * episode_steps):
        action = jax.random.uniform(action_key, (num_envs, 2), minval=-1.0, maxval=1.0)
        expected, state = one_at_a_time(state, action, params), step(state, action, params)
        with_key_data = [s.replace(key=jax.random.key_data(s.key)) for s in (state, expected)]
        jax.tree.map(np.testing.assert_array_equal, *with_key_data)
        np.testing.assert_array_equal(state.obs["image"], jax.vmap(env.images, in_axes=(0, None))(state.sim, params))
        starts += int(np.sum(state.done))
    assert starts == 2 * num_envs

"""MuJoCo Playground's PandaPickCube through the adapter, on the CPU with MJX-JAX: the registry name and config
overrides, offline assets, the contract (shapes, finite values, auto-reset, the same key giving the same
episodes), a checkpoint of the envs' state, and the success criterion judged at the time limit.

One program (3 envs auto-resetting, 4 steps of an episode of 3) is compiled once for the module; every test that
steps reuses it.
"""

import pytest

pytest.importorskip("mujoco_playground", reason="MuJoCo Playground is not installed (the playground extra)")

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm import envs
from jaxarm.agents.common import checkpoint
from jaxarm.envs import AutoReset, VmapEnv
from jaxarm.envs.observation import PRIVILEGED
from jaxarm.interop import playground

TASK = "playground:PandaPickCube"
NUM_ENVS = 3
EPISODE = 3
"""Steps of an episode: the rollout of `STEPS` crosses one auto-reset."""
STEPS = 4

pytestmark = [pytest.mark.mjx, pytest.mark.xdist_group(TASK)]


@pytest.fixture(scope="module")
def pick():
    """(env, params with an episode of `EPISODE` steps, jitted reset, jitted rollout of `STEPS` steps)."""
    env = envs.make(TASK)
    params = envs.override_params(env.default_params(), {"max_episode_steps": EPISODE})
    batch = VmapEnv(AutoReset(env), NUM_ENVS)

    def rollout(state, key, action_scale):
        """Every state of `STEPS` steps from `state`, actions uniform in ±`action_scale`: EnvState [STEPS, B]."""

        def step(state, step_key):
            action = action_scale * jax.random.uniform(step_key, (NUM_ENVS, *env.spec.action_shape), minval=-1)
            state = batch.step(state, action, params)
            return state, state

        return jax.lax.scan(step, state, jax.random.split(key, STEPS))[1]

    return env, params, jax.jit(lambda key: batch.reset(key, params)), jax.jit(rollout)


def test_the_name_builds_once_from_the_vendored_menagerie():
    env = envs.make(TASK)
    assert env is envs.make(TASK)
    assert isinstance(env, playground.PlaygroundEnv) and env.impl == "jax" and env.uses_mjx
    assert playground.mjx_env.MENAGERIE_PATH == playground.MENAGERIE
    assert env.spec.observation_shape == (66,) and env.spec.action_shape == (8,)
    assert int(env.default_params().max_episode_steps) == 150  # Playground's episode_length


@pytest.mark.parametrize(
    ("task", "observation_shape", "action_shape"),
    [
        ("PandaPickCubeOrientation", (66,), (8,)),
        ("PandaPickCubeCartesian", (70,), (3,)),
        ("PandaOpenCabinet", (55,), (8,)),
    ],
)
def test_every_franka_task_builds_from_the_vendored_menagerie(task, observation_shape, action_shape):
    # PandaPickCubeCartesian recolours the geoms of menagerie's finger_1 mesh: the vendored Panda has one.
    spec = envs.make(f"playground:{task}").spec
    assert spec.observation_shape == observation_shape and spec.action_shape == action_shape


def test_config_overrides_are_kwargs_and_typos_name_the_closest_key():
    assert int(envs.make(TASK, episode_length=40).default_params().max_episode_steps) == 40
    with pytest.raises(TypeError, match="did you mean 'episode_length'"):
        envs.make(TASK, episode_lenght=40)
    with pytest.raises(KeyError, match="did you mean 'PandaPickCube'"):
        envs.make("playground:PandaPickCub")
    with pytest.raises(ValueError, match="no privileged_state"):
        envs.make(TASK, privileged=True)


def test_a_dict_observations_privileged_state_is_the_critics_part_alone():
    state, privileged, pixels = jnp.zeros(3), jnp.ones(5), jnp.zeros((8, 8, 3), jnp.uint8)
    both = {"state": state, "privileged_state": privileged}
    assert playground.observation(both, privileged=False) is state
    critics = playground.observation(both, privileged=True)
    assert critics.keys() == {"state", PRIVILEGED} and critics["state"] is state and critics[PRIVILEGED] is privileged
    assert playground.observation({**both, "pixels/view_0": pixels}, privileged=False).keys() == {
        "state",
        "pixels/view_0",
    }
    with pytest.raises(ValueError, match="no privileged_state"):
        playground.observation({"state": state}, privileged=True)


def test_params_scale_the_physics_of_playgrounds_model():
    env = envs.make(TASK)
    nominal = env.playground.mjx_model
    params = env.default_params().replace(friction_scale=0.5, mass_scale=2.0, actuator_gain_scale=3.0)
    scaled = playground.scaled_model(nominal, params)
    np.testing.assert_allclose(scaled.geom_friction[:, 0], 0.5 * nominal.geom_friction[:, 0])
    np.testing.assert_array_equal(scaled.geom_friction[:, 1:], nominal.geom_friction[:, 1:])
    np.testing.assert_allclose(scaled.body_mass, 2.0 * nominal.body_mass)
    np.testing.assert_allclose(scaled.actuator_gainprm[:, 0], 3.0 * nominal.actuator_gainprm[:, 0])
    np.testing.assert_allclose(scaled.actuator_biasprm[:, 1], 3.0 * nominal.actuator_biasprm[:, 1])
    np.testing.assert_array_equal(scaled.actuator_biasprm[:, 2], nominal.actuator_biasprm[:, 2])  # damping stays


def test_steps_auto_reset_at_the_time_limit_and_repeat_for_the_same_key(pick):
    env, _, reset, rollout = pick
    key = jax.random.key(0)
    start = reset(key)
    states = rollout(start, key, 1.0)
    assert states.obs.shape == (STEPS, NUM_ENVS, 66) and states.reward.shape == (STEPS, NUM_ENVS)
    assert np.all(np.isfinite(states.obs)) and np.all(np.isfinite(states.reward))
    ends = np.broadcast_to(np.arange(1, STEPS + 1)[:, None] == EPISODE, (STEPS, NUM_ENVS))
    np.testing.assert_array_equal(states.truncated, ends)
    assert not np.any(states.terminated)
    ended = jax.tree.map(lambda leaf: leaf[EPISODE - 1], states)
    np.testing.assert_array_equal(ended.last_episode.length, EPISODE)
    np.testing.assert_array_equal(ended.step_count, 0)  # the next episode has begun, with a new target
    targets = env.playground_state(states.sim).info["target_pos"]
    assert np.all(np.linalg.norm(targets[EPISODE - 1] - targets[0], axis=-1) > 1e-3)
    again = rollout(reset(key), key, 1.0)
    np.testing.assert_array_equal(again.obs, states.obs)
    np.testing.assert_array_equal(again.reward, states.reward)
    np.testing.assert_array_equal(env.playground_state(again.sim).data.qpos, env.playground_state(states.sim).data.qpos)
    np.testing.assert_array_equal(env.playground_state(again.sim).info["target_pos"], targets)


def test_a_batch_of_states_round_trips_through_a_checkpoint(pick, tmp_path):
    # orbax refuses arrays of size zero, which Playground's mjx.Data holds (act): the sim keeps none.
    _, _, reset, _ = pick
    state = reset(jax.random.key(2))
    checkpoint.save(tmp_path, 1, state)
    restored = checkpoint.restore(tmp_path, state)
    for leaf, same in zip(jax.tree.leaves(state.sim), jax.tree.leaves(restored.sim), strict=True):
        if jnp.issubdtype(leaf.dtype, jax.dtypes.prng_key):  # Playground's info["rng"]
            leaf, same = jax.random.key_data(leaf), jax.random.key_data(same)
        np.testing.assert_array_equal(leaf, same)


def test_success_is_the_box_at_its_target_when_the_time_limit_ends_the_episode(pick):
    env, _, reset, rollout = pick
    start = reset(jax.random.key(1))
    # Playground's reset poses no body (xpos is zero until the first step): the box's place is in qpos.
    box_qpos = env.mj_model.jnt_qposadr[env.mj_model.body("box").jntadr[0]]
    state = env.playground_state(start.sim)
    box = state.data.qpos[:, box_qpos : box_qpos + 3]
    # The arm holds still (zero actions) and the box rests: a target at the box, 1 cm and 3 cm beside it.
    offsets = jnp.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.03, 0.0]])
    state = state.replace(info={**state.info, "target_pos": box + offsets})
    start = start.replace(sim=start.sim.replace(arrays=env.layout.pack(state)))
    states = rollout(start, jax.random.key(1), 0.0)
    np.testing.assert_array_equal(states.episode.success[: EPISODE - 1], False)  # judged at the end alone
    np.testing.assert_array_equal(states.last_episode.success[EPISODE - 1], [True, True, False])
    assert playground.BOX_SUCCESS_RADIUS == 0.02


def test_a_run_config_names_the_task_and_its_overrides():
    from experiments import configs
    from jaxarm.agents.common.config import apply_overrides

    config = apply_overrides(
        configs.get("ppo_playground_pick", validate=False),
        [f"env={TASK}", "env_kwargs.episode_length=40", "env_params.friction_scale=0.8"],
    )
    env, params = config.make_env(randomized=False)
    assert int(params.max_episode_steps) == 40 and float(params.friction_scale) == pytest.approx(0.8)
    assert env.task == "PandaPickCube"


def test_a_task_on_warp_prints_no_overflow_lines_and_one_on_mjx_jax_keeps_its_model():
    from jaxarm.envs.panda.mjx_impl import Impl

    jax_env = envs.make(TASK)
    assert playground.quiet_model(jax_env._nominal_model, Impl.JAX) is jax_env._nominal_model
    pytest.importorskip("warp", reason="warp-lang is not installed (the warp extra)")
    assert envs.make(TASK, impl="warp")._nominal_model.opt._impl.warn_overflow == 0


def test_warp_follows_mjx_jax_and_its_physics_params():
    # Warp shares its contact buffer over the batch: the sim keeps it out of the envs' vmap (StateLayout).
    pytest.importorskip("warp", reason="warp-lang is not installed (the warp extra)")

    def trajectory(impl, params_of):
        env = envs.make(TASK, impl=impl, naconmax=24 * NUM_ENVS, naccdmax=24 * NUM_ENVS)
        batch, params = VmapEnv(AutoReset(env), NUM_ENVS), params_of(env.default_params())

        def run(key):
            def step(state, step_key):
                action = 0.5 * jax.random.uniform(step_key, (NUM_ENVS, *env.spec.action_shape), minval=-1)
                state = batch.step(state, action, params)
                return state, env.playground_state(state.sim).data.qpos

            return jax.lax.scan(step, batch.reset(key, params), jax.random.split(key, STEPS))[1]

        return np.asarray(jax.jit(run)(jax.random.key(0)))

    def nominal(params):
        return params

    def slippery(params):
        return params.replace(friction_scale=jnp.float32(0.5), actuator_gain_scale=jnp.float32(2.0))

    warp = trajectory("warp", nominal)
    np.testing.assert_allclose(warp, trajectory("jax", nominal), atol=1e-4)
    assert np.max(np.abs(trajectory("warp", slippery) - warp)) > 1e-3


def test_carry_info_keeps_the_named_info_keys_into_the_next_episode():
    # As Playground's training wrapper keeps its info: a pick that reached the box keeps its box-to-target reward on.
    env = envs.make(TASK, carry_info="reached_box")
    assert env.carry_info == ("reached_box",) and envs.make(TASK).carry_info == ()
    ended, _, _ = env._reset(jax.random.key(0), env.default_params())
    state = env.playground_state(ended)
    ended = ended.replace(arrays=env.layout.pack(state.replace(info={**state.info, "reached_box": jnp.float32(1.0)})))
    fresh, _, _ = env._reset(jax.random.key(1), env.default_params())
    carried = env.playground_state(env.carried_over(ended, fresh))
    assert float(carried.info["reached_box"]) == 1.0
    np.testing.assert_array_equal(carried.info["target_pos"], env.playground_state(fresh).info["target_pos"])
    np.testing.assert_array_equal(carried.data.qpos, env.playground_state(fresh).data.qpos)
    assert float(envs.make(TASK).playground_state(envs.make(TASK).carried_over(ended, fresh)).info["reached_box"]) == 0
    with pytest.raises(ValueError, match="no key 'reached'.*reached_box"):
        envs.make(TASK, carry_info="reached")

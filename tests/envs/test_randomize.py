"""Domain randomisation: ranges parse and sample as declared, every env of a batch draws its own params at each
reset and keeps them for its episode, and configs carry, check and report them."""

import copy
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm import envs
from jaxarm.agents.common.config import apply_overrides
from jaxarm.agents.ppo.config import PPOConfig
from jaxarm.envs.randomize import ParamRange, Randomized, RandomizedSim


def test_ranges_parse_uniform_and_log():
    assert ParamRange.parse("0.8..3") == ParamRange(0.8, 3.0)
    assert ParamRange.parse("log:0.5..2") == ParamRange(0.5, 2.0, log=True)
    assert ParamRange.parse("-1..1") == ParamRange(-1.0, 1.0)


@pytest.mark.parametrize("text", ["3..1", "log:0..1", "x", "1..2..3", "1..nan", "2"])
def test_bad_ranges_are_refused(text):
    with pytest.raises(ValueError, match="range"):
        ParamRange.parse(text)


def test_samples_lie_in_range_with_the_declared_spread():
    key, like = jax.random.key(0), jnp.zeros(20_000, jnp.float32)
    uniform = np.asarray(ParamRange(1.0, 3.0).sample(key, like))
    assert uniform.min() >= 1.0 and uniform.max() <= 3.0 and abs(uniform.mean() - 2.0) < 0.02
    log = np.asarray(ParamRange(0.25, 4.0, log=True).sample(key, like))
    assert log.min() >= 0.25 * (1 - 1e-6) and log.max() <= 4.0 * (1 + 1e-6)
    assert abs(np.median(log) - 1.0) < 0.05, "log-uniform: the median is the geometric mean"
    steps = np.asarray(ParamRange(0, 2).sample(key, jnp.zeros(3000, jnp.int32)))
    assert set(np.unique(steps)) == {0, 1, 2} and steps.dtype == np.int32


def test_each_env_draws_its_own_params_and_keeps_them_for_its_episode():
    env = Randomized(envs.make("arm2d"), {"goal_size": ParamRange(0.05, 0.2)})
    params = env.default_params()
    batch = envs.VmapEnv(envs.AutoReset(env), 64)
    state = jax.jit(batch.reset)(jax.random.key(0), params)
    assert isinstance(state.sim, RandomizedSim)
    sizes = np.asarray(state.sim.params.goal_size)
    assert sizes.min() >= 0.05 and sizes.max() <= 0.2 and len(np.unique(sizes)) == 64
    np.testing.assert_array_equal(state.sim.params.action_scale, np.full(64, params.action_scale))
    step = jax.jit(batch.step)
    after = step(state, jnp.zeros((64, *env.spec.action_shape)), params)
    np.testing.assert_array_equal(after.sim.params.goal_size, sizes)
    # Every env reaches its time limit together: each new episode draws again.
    for _ in range(int(params.max_episode_steps) - 1):
        after = step(after, jnp.zeros((64, *env.spec.action_shape)), params)
    assert bool(np.all(after.truncated))
    assert not np.any(np.asarray(after.sim.params.goal_size) == sizes)


def test_a_randomised_env_steps_as_the_plain_env_at_the_drawn_params():
    plain = envs.make("arm2d")
    env = Randomized(plain, {"action_scale": ParamRange(0.5, 1.5)})
    params = env.default_params()
    state = env.reset(jax.random.key(3), params)
    action = jnp.full(plain.spec.action_shape, 0.7)
    stepped = env.step(state, action, params)
    reference = plain.step(state.replace(sim=state.sim.inner), action, state.sim.params)
    np.testing.assert_array_equal(stepped.obs, reference.obs)
    assert float(stepped.reward) == float(reference.reward)


def test_a_fraction_of_episodes_take_corners_of_the_box_and_none_change_the_other_draws():
    ranges = {"goal_size": ParamRange(0.05, 0.2), "hold_steps": ParamRange(1.5, 6.5)}
    plain, cornered = (Randomized(envs.make("arm2d"), ranges, fraction) for fraction in (0.0, 0.25))
    params = plain.default_params()
    keys = jax.random.split(jax.random.key(0), 4000)
    drawn = jax.jit(jax.vmap(cornered.episode_params, in_axes=(0, None)))(keys, params)
    before = jax.jit(jax.vmap(plain.episode_params, in_axes=(0, None)))(keys, params)
    sizes, holds = np.asarray(drawn.goal_size), np.asarray(drawn.hold_steps)
    at_ends = np.isin(sizes, np.float32([0.05, 0.2])) & np.isin(holds, [2, 6])
    assert 0.22 < at_ends.mean() < 0.28  # a quarter, each param at an end together
    for values in (sizes[at_ends], holds[at_ends]):  # each end by a fair coin
        assert 0.4 < np.mean(values == values.max()) < 0.6
    np.testing.assert_array_equal(sizes[~at_ends], np.asarray(before.goal_size)[~at_ends])
    np.testing.assert_array_equal(holds[~at_ends], np.asarray(before.hold_steps)[~at_ends])
    assert holds.dtype == np.asarray(params.hold_steps).dtype


def test_corners_need_ranges_and_a_fraction():
    with pytest.raises(ValueError, match="randomize_corners=0.5 needs randomize"):
        apply_overrides(PPOConfig(env="arm2d"), ["randomize_corners=0.5"]).validate()
    with pytest.raises(ValueError, match="randomize_corners"):
        apply_overrides(PPOConfig(env="arm2d"), ["randomize_corners=2"])
    config = apply_overrides(PPOConfig(env="arm2d"), ["randomize.goal_size=0.05..0.2", "randomize_corners=0.5"])
    assert config.make_env()[0].corner_fraction == 0.5


def test_an_unknown_param_is_refused_by_name():
    with pytest.raises(ValueError, match="no_such_param"):
        Randomized(envs.make("arm2d"), {"no_such_param": ParamRange(0.0, 1.0)})


def test_configs_take_ranges_from_overrides_and_check_them():
    config = apply_overrides(PPOConfig(env="arm2d"), ["randomize.goal_size=0.05..0.2"])
    assert config.randomize == (("goal_size", "0.05..0.2"),)
    env, _ = config.make_env()
    assert isinstance(env, Randomized)
    assert not isinstance(config.make_eval_env()[0], Randomized), "evaluations run the nominal env"
    with pytest.raises(ValueError, match="randomize.goal_size"):
        apply_overrides(PPOConfig(env="arm2d"), ["randomize.goal_size=0.2..0.05"]).validate()
    with pytest.raises(ValueError, match="goal_sise"):
        apply_overrides(PPOConfig(env="arm2d"), ["randomize.goal_sise=0.05..0.2"]).validate()


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("goal_size=-40..-10", "goal_size=-40..-10 draws values goal_size may not take: it must be > 0"),
        ("world_size=0..400", "must be > 0"),
        ("hold_steps=-5..3", "must be >= 0"),
        ("goal_mode=0..7", "must be one of 0, 1, 2"),
        ("hold_steps=1..1e10", "must fit in int32"),
        ("hold_steps=2.2..2.7", "holds no whole number"),
        ("goal_bonus=-1e40..1", "must fit in float32 (at most 3.40282e+38 in magnitude)"),
    ],
)
def test_ranges_that_draw_values_a_param_may_not_take_are_refused(text, message):
    with pytest.raises(ValueError, match=f"randomize.*{re.escape(message)}"):
        apply_overrides(PPOConfig(env="arm2d"), [f"randomize.{text}"])
    apply_overrides(PPOConfig(env="arm2d"), ["randomize.goal_mode=0..2", "randomize.hold_steps=10..50"])


def test_a_range_of_the_time_limit_is_refused_since_it_would_change_nothing():
    # The time limit reads the params the caller passes, not those drawn per episode (as --perturb refuses it).
    message = "randomize.max_episode_steps: max_episode_steps sets the rollout's length; set it with env_params"
    with pytest.raises(ValueError, match=re.escape(message)):
        apply_overrides(PPOConfig(env="arm2d"), ["randomize.max_episode_steps=50..200"])
    with pytest.raises(ValueError, match=re.escape(message)):
        Randomized(envs.make("arm2d"), {"max_episode_steps": ParamRange(200, 200)})


def test_a_randomised_env_forwards_attributes_and_copies():
    env = Randomized(envs.make("panda_sort"), {"finger_friction": ParamRange(0.8, 3.0)})
    assert env.objects_count == 1 and env.uses_mjx and env.layout is env.env.layout
    assert copy.copy(env).ranges == env.ranges
    assert not hasattr(Randomized.__new__(Randomized), "layout")

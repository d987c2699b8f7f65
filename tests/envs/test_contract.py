"""The contract every registered env must keep (jit, vmap, spec, purity, time limit, auto-reset).

The whole contract runs on one env of each class (the first name of each of `envs.families()`); every other
registered name, a variant of one of those classes built with other constructor arguments, is reset and stepped
under jit and checked for its spec and finite values. Variants share their class's code, and MJX programs take
a minute or more each to compile on a 2-core CPU: the jitted reset and step come from `compiled`, shared with
the envs' own test files, in the same xdist worker as those files' tests (`same_worker`).
"""

import copy
import re
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm import envs
from jaxarm.envs.observation import IMAGE
from jaxarm.envs.panda.base import ArmOptions
from jaxarm.envs.peg_insert import PegInsert
from jaxarm.envs.randomize import ParamRange, Randomized
from jaxarm.envs.registry import constructor_kwargs
from tests.agents.probe_envs import HOST_CHECKS, HostCheckedEnv
from tests.envs.compiled import compiled, same_worker

ROLLOUT_STEPS = 8
CHEAP_NUM_ENVS = 1024
MJX_NUM_ENVS = 16
"""MJX envs compile for minutes on the 2-core CPU, and jaxlib 0.10.2's CPU runtime deadlocked on them at
>= 256 envs; every MJX env therefore runs one 16-env rollout, shared by the tests below."""

CAMERA_VARIANTS = ["arm2d_pixels"]
"""Variants whose observation differs in kind (a camera image in a dict), which get the whole contract too."""
FULL_CONTRACT = [names[0] for names in envs.families().values()] + CAMERA_VARIANTS
VARIANTS = [name for names in envs.families().values() for name in names[1:] if name not in CAMERA_VARIANTS]
WORKER_GROUPS = {
    "panda_sort": "panda_sort_contract",
    "panda_sort3": "panda_sort",
    "panda_sort_tosser": "panda_sort_tosser",
    "peg_insert": "peg_insert",
}
"""Env -> the xdist group its contract tests run in. panda_sort3 and peg_insert join their test files' groups,
whose programs they share. panda_sort's contract keeps a group of its own, so that its tests share their
rollout in one worker while test_panda_sort.py, the largest group, runs in the other: on two workers that
balance saves more than compiling the sorter's reset and step in both costs. Other envs may run anywhere."""


def with_worker_group(names: list[str]) -> list:
    """`names` as pytest params, each marked to run beside the tests that share its programs, and as `mjx` where
    it compiles MJX programs."""
    return [
        pytest.param(name, marks=[*worker_group(name), *([pytest.mark.mjx] if envs.uses_mjx(name) else [])])
        for name in names
    ]


def worker_group(name: str) -> list:
    return [same_worker(WORKER_GROUPS[name])] if name in WORKER_GROUPS else []


def contract_num_envs(env) -> int:
    return MJX_NUM_ENVS if env.uses_mjx else CHEAP_NUM_ENVS


def random_actions(key, env, shape):
    return jax.random.uniform(key, shape + env.spec.action_shape, minval=-1.0, maxval=1.0)


@pytest.fixture(scope="module", params=with_worker_group(FULL_CONTRACT))
def env_case(request):
    """(env, params, batch size, jitted rollout, the env's shared programs) per env class."""
    shared = compiled(request.param)
    env = shared.env
    num_envs = contract_num_envs(env)
    run = jax.jit(lambda params, key: rollout(env, params, key, num_envs, ROLLOUT_STEPS))
    return env, shared.params, num_envs, run, shared


@pytest.fixture(scope="module")
def env_and_params(env_case):
    return env_case[:2]


def rollout(env, params, key, num_envs, steps):
    """Runs `steps` random-action steps of a vmapped auto-reset env; returns the stacked states."""
    batch = envs.VmapEnv(envs.AutoReset(env), num_envs)

    def body(state, step_key):
        next_state = batch.step(state, random_actions(step_key, env, (num_envs,)), params)
        return next_state, next_state

    reset_key, steps_key = jax.random.split(key)
    state = batch.reset(reset_key, params)
    _, states = jax.lax.scan(body, state, jax.random.split(steps_key, steps))
    return states


def assert_trees_equal(first, second) -> None:
    jax.tree.map(np.testing.assert_array_equal, first, second)


def trees_equal(first, second) -> bool:
    return all(jax.tree.leaves(jax.tree.map(np.array_equal, first, second)))


def assert_spec_shapes_and_finite(env, states, steps: int, num_envs: int) -> None:
    """`states` [steps, num_envs] match `env.spec` (every observation part's shape and dtype), and every float in
    them is finite."""
    expected = jax.tree.map(lambda part: ((steps, num_envs, *part.shape), part.dtype), env.spec.observation)
    assert jax.tree.map(lambda leaf: (leaf.shape, leaf.dtype), states.obs) == expected
    assert states.reward.shape == (steps, num_envs)
    assert states.terminated.dtype == jnp.bool_ and states.truncated.dtype == jnp.bool_
    for leaf in jax.tree.leaves(states):
        if jnp.issubdtype(leaf.dtype, jnp.floating):
            assert np.all(np.isfinite(np.asarray(leaf)))


def test_every_registered_env_is_covered():
    assert sorted(FULL_CONTRACT + VARIANTS) == envs.names()
    assert {"arm2d", "panda_sort", "peg_insert"} <= set(FULL_CONTRACT)
    assert [envs.uses_mjx(name) for name in envs.names()] == [envs.make(name).uses_mjx for name in envs.names()]


@pytest.mark.parametrize("name", with_worker_group(VARIANTS))
def test_variant_resets_and_steps_under_jit(name):
    shared = compiled(name)
    reset_key, action_key = jax.random.split(jax.random.key(0))
    state = shared.step(
        shared.reset(reset_key, shared.params), random_actions(action_key, shared.env, ()), shared.params
    )
    states = jax.tree.map(lambda leaf: leaf[None, None], state)  # one step of one env
    assert_spec_shapes_and_finite(shared.env, states, 1, 1)


def test_spec_shapes_and_finite_values_under_jit_and_vmap(env_case):
    env, params, num_envs, run, _ = env_case
    assert_spec_shapes_and_finite(env, run(params, jax.random.key(0)), ROLLOUT_STEPS, num_envs)


def test_same_key_same_trajectory(env_case):
    _, params, _, run, _ = env_case
    first = run(params, jax.random.key(7))
    second = run(params, jax.random.key(7))
    other = run(params, jax.random.key(8))
    assert_trees_equal(first.obs, second.obs)
    np.testing.assert_array_equal(first.reward, second.reward)
    assert not trees_equal(first.obs, other.obs)


def test_time_limit_truncates_and_auto_reset_keeps_final_obs(env_case):
    # The same rollout (same keys, so the same resets and actions) with a 3-step limit and with the env's own:
    # on the third step the limited envs truncate, keep the observation the unlimited ones reach, and reset.
    _, params, _, run, _ = env_case
    key = jax.random.key(3)
    free = run(params, key)
    limited = run(envs.override_params(params, {"max_episode_steps": 3}), key)
    assert int(params.max_episode_steps) > ROLLOUT_STEPS
    assert not np.any(free.done[:3]), "an episode ended on its own within three random steps"
    assert not np.any(limited.done[:2])
    third = jax.tree.map(lambda leaf: leaf[2], limited)
    assert np.all(third.truncated) and not np.any(third.terminated)
    free_third = jax.tree.map(lambda leaf: leaf[2], free)
    assert_trees_equal(third.final_obs, free_third.obs)
    assert not trees_equal(third.obs, free_third.obs), "the truncated envs were reset"
    assert np.all(third.step_count == 0) and np.all(third.last_episode.length == 3)
    assert np.all(third.episode.length == 0)


def test_nan_actions_are_zeroed_inf_actions_clipped_and_both_counted(env_case):
    env, params, _, _, shared = env_case
    plain_step = shared.step
    state = shared.reset(jax.random.key(5), params)
    nan_step = plain_step(state, jnp.full(env.spec.action_shape, jnp.nan), params)
    zero_step = plain_step(state, jnp.zeros(env.spec.action_shape), params)
    assert_trees_equal(nan_step.obs, zero_step.obs)
    assert int(nan_step.episode.nan_actions) == 1 and int(zero_step.episode.nan_actions) == 0
    signs = jnp.where(jnp.arange(env.spec.action_size) % 2 == 0, 1.0, -1.0).reshape(env.spec.action_shape)
    inf_step = plain_step(state, signs * jnp.inf, params)
    bound_step = plain_step(state, jnp.where(signs > 0, env.spec.action_high, env.spec.action_low), params)
    assert_trees_equal(inf_step.obs, bound_step.obs)
    assert int(inf_step.episode.nan_actions) == 1 and int(bound_step.episode.nan_actions) == 0


def test_check_action_rejects_nan_and_wrong_shape(env_and_params):
    env, _ = env_and_params
    with pytest.raises(ValueError, match="NaN"):
        envs.check_action(np.full(env.spec.action_shape, np.nan), env.spec)
    with pytest.raises(ValueError, match="shape"):
        envs.check_action(np.zeros(env.spec.action_size + 1), env.spec)


def test_unknown_env_name_names_the_closest():
    with pytest.raises(KeyError, match="did you mean 'arm2d'"):
        envs.make("arm2dd")


def test_flat_env_kwargs_fill_a_panda_tasks_options_and_an_unknown_one_is_refused():
    flat = {"impl": "jax", "dynamics": "identified", "max_action_latency": 1}
    options = ArmOptions(impl="jax", max_action_latency=1)
    assert constructor_kwargs(PegInsert, flat) == {"dynamics": "identified", "options": options}
    assert constructor_kwargs(PegInsert, {"options": options}) == {"options": options}
    # One line naming the closest and every valid name (as `--show` lists them), not the constructor's own error.
    with pytest.raises(
        TypeError,
        match=re.escape("no env kwarg 'max_action_latancy' (did you mean 'max_action_latency'?); it takes dynamics,"),
    ):
        envs.make("peg_insert", max_action_latancy=1)
    with pytest.raises(TypeError, match=r"takes num_links, obs_mode, resolution, privileged$"):
        envs.make("arm2d", foo=1)


def test_a_diverged_step_terminates_with_zero_observation_and_reward():
    env = envs.make("arm2d")
    params = env.default_params()
    state = env.reset(jax.random.key(0), params)
    broken = jax.jit(env.step)(state, jnp.zeros(2), params.replace(base_pos=jnp.array([jnp.inf, 0.0])))
    assert bool(broken.terminated) and bool(broken.episode.diverged) and not bool(broken.episode.success)
    assert float(broken.reward) == 0.0 and np.all(np.asarray(broken.obs) == 0.0)
    healthy = jax.jit(env.step)(state, jnp.zeros(2), params)
    assert not bool(healthy.episode.diverged)


def test_a_non_finite_reset_observation_is_zeroed_and_flagged():
    env = envs.make("arm2d")
    params = env.default_params()
    # The override path refuses such params; per-env randomised params reach `reset` unchecked, inside jit.
    for broken in (params.replace(world_size=jnp.float32(0.0)), params.replace(link_lengths=jnp.full(2, jnp.nan))):
        state = jax.jit(env.reset)(jax.random.key(0), broken)
        assert np.all(np.asarray(state.obs) == 0.0) and np.all(np.asarray(state.final_obs) == 0.0)
        assert bool(state.episode.diverged)
    healthy = jax.jit(env.reset)(jax.random.key(0), params)
    assert np.any(np.asarray(healthy.obs) != 0.0) and not bool(healthy.episode.diverged)


def test_a_plain_env_stepped_past_its_end_keeps_the_episode_it_reported():
    env = envs.make("arm2d")
    params = envs.override_params(env.default_params(), {"max_episode_steps": 3})
    step = jax.jit(env.step)
    state = env.reset(jax.random.key(0), params)
    for _ in range(3):
        state = step(state, jnp.ones(2), params)
    assert bool(state.truncated) and int(state.last_episode.length) == 3
    reported = state.last_episode
    for _ in range(4):
        state = step(state, jnp.ones(2), params)
        assert bool(state.done)
        jax.tree.map(np.testing.assert_array_equal, state.last_episode, reported)
    # Auto-reset envs still report every episode, including one that ends on its first step.
    auto = envs.AutoReset(env)
    one_step = envs.override_params(params, {"max_episode_steps": 1})
    state = auto.reset(jax.random.key(0), one_step)
    for _ in range(3):
        state = jax.jit(auto.step)(state, jnp.ones(2), one_step)
        assert bool(state.truncated) and int(state.last_episode.length) == 1
        assert float(state.last_episode.return_) == float(state.reward)


def steps_of(batch, params, steps: int):
    """jitted: `steps` steps of `batch` from a state, with zero actions."""
    actions = jnp.zeros((batch.num_envs, *batch.spec.action_shape))

    def run(state):
        return jax.lax.fori_loop(0, steps, lambda _, s: batch.step(s, actions, params), state)

    return jax.jit(run)


@pytest.mark.parametrize("randomized", [False, True])
def test_a_fault_the_host_raises_on_is_checked_at_its_step_or_once_after_deferred_steps(randomized):
    env = HostCheckedEnv()
    batch = envs.VmapEnv(envs.AutoReset(Randomized(env, {}) if randomized else env), 8)
    # The fault is in the last step of every 4-step episode: after 6 steps the envs are 2 steps into the next.
    params = env.default_params().replace(fault_at=jnp.array(3, jnp.int32))
    state = jax.jit(batch.reset)(jax.random.key(0), params)
    with pytest.raises(Exception, match="probe fault in 8 envs"):
        jax.block_until_ready(steps_of(batch, params, 6)(state))
    HOST_CHECKS.clear()
    with envs.deferred_step_checks():
        stepped = jax.block_until_ready(steps_of(batch, params, 6)(state))
    assert HOST_CHECKS == {}
    np.testing.assert_array_equal(stepped.step_count, 2)
    with pytest.raises(Exception, match="probe fault in 8 envs"):
        jax.block_until_ready(jax.jit(batch.checked)(stepped))
    assert HOST_CHECKS == {"checked": 1}  # one host call for the whole batch
    clean = env.default_params()
    with envs.deferred_step_checks():
        stepped = steps_of(batch, clean, 6)(jax.jit(batch.reset)(jax.random.key(0), clean))
    checked = jax.block_until_ready(jax.jit(batch.checked)(stepped))
    assert_trees_equal((checked.sim, checked.obs, checked.episode), (stepped.sim, stepped.obs, stepped.episode))


def test_vmap_warns_above_an_envs_cpu_limit():
    env = copy.copy(envs.make("arm2d"))  # the registry's instance is shared
    env.cpu_max_envs = 4  # this copy only: arm2d itself has no limit
    with pytest.warns(UserWarning, match="8 envs on the CPU: above 4 envs"):
        envs.VmapEnv(envs.AutoReset(env), 8)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        envs.VmapEnv(envs.AutoReset(env), 4)
        envs.VmapEnv(envs.make("arm2d"), 1024)


WRAPPER_NUM_ENVS = 4
WRAPPER_STEPS = 4
WRAPPED = {
    "AutoReset": lambda env: envs.AutoReset(env),
    "VmapEnv": lambda env: envs.VmapEnv(env, WRAPPER_NUM_ENVS),
    "VmapEnv(AutoReset)": lambda env: envs.VmapEnv(envs.AutoReset(env), WRAPPER_NUM_ENVS),
    "Randomized": lambda env: Randomized(env, {"goal_size": ParamRange(20.0, 60.0)}),
    "VmapEnv(AutoReset(Randomized))": lambda env: envs.VmapEnv(
        envs.AutoReset(Randomized(env, {"goal_size": ParamRange(20.0, 60.0)})), WRAPPER_NUM_ENVS
    ),
}
"""Every wrapper of jaxarm.envs, alone and as runs stack them (`test_every_wrapper_is_covered`)."""
BUILT_ON_THE_TASK = {"reset", "reset_without_images", "step", "blank_image"}
"""`Env`'s methods built from `_reset`, `_transition` and `spec`, which an `Env` that wraps another inherits."""


def wrapper_types(wrapped) -> set[type]:
    """The classes of `wrapped` and of every env it wraps."""
    return {type(wrapped)} | (wrapper_types(wrapped.env) if "env" in vars(wrapped) else set())


def test_every_wrapper_is_covered():
    camera = envs.make("arm2d_pixels")
    covered = set().union(*(wrapper_types(wrap(camera)) for wrap in WRAPPED.values())) - {type(camera)}
    assert covered == {*envs.Wrapper.__subclasses__(), Randomized}


def test_an_env_that_wraps_another_forwards_every_hook_of_the_contract():
    # Env's own defaults (draws_images False, images raising) would shadow the wrapped env's hooks: each must be
    # overridden, or set on the instance.
    wrapped = WRAPPED["Randomized"](envs.make("arm2d_pixels"))
    hooks = {name for name in vars(envs.Env) if not name.startswith("_")} - BUILT_ON_THE_TASK
    assert {name for name in hooks if name not in vars(Randomized) and name not in vars(wrapped)} == set()
    assert wrapped.draws_images and wrapped.uses_mjx == wrapped.env.uses_mjx


@pytest.mark.parametrize("name", WRAPPED)
def test_every_wrapper_passes_camera_images_through(name):
    """A wrapped camera env draws every env's image at reset, at each step and at each auto-reset (a 2-step time
    limit), and its own `images` hook draws what its observation holds."""
    camera = envs.make("arm2d_pixels")
    wrapped = WRAPPED[name](camera)
    params = envs.override_params(camera.default_params(), {"max_episode_steps": 2})
    batch = (WRAPPER_NUM_ENVS,) if isinstance(wrapped, envs.VmapEnv) else ()
    step = jax.jit(wrapped.step)
    state = jax.jit(wrapped.reset)(jax.random.key(0), params)
    assert wrapped.draws_images
    np.testing.assert_array_equal(jax.jit(wrapped.images)(state.sim, params), state.obs[IMAGE])
    assert not np.any(jax.jit(wrapped.reset_without_images)(jax.random.key(0), params).obs[IMAGE])
    for index in range(WRAPPER_STEPS):
        sums = np.asarray(state.obs[IMAGE], np.int64).reshape(*batch, -1).sum(-1)
        assert np.all(sums > 0), f"{name}: a blank image after {index} steps"
        state = step(state, random_actions(jax.random.key(index), camera, batch), params)
    assert np.any(state.last_episode.length == 2), "no episode ended: the auto-resets' images went unchecked"

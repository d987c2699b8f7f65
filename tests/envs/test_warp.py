"""The Panda envs on MJX's two implementations: "jax" stays the default and runs without warp-lang, "warp"
fails clearly where it cannot run, and where warp-lang is importable: the implementations' trajectories from the
same states and actions (the same once both step the peg at one timestep without force limits; at their own
timesteps a strict xfail), the scripted pick-and-place scores on Warp, and a contact buffer too small for the
batch raises instead of dropping contacts.

Warp's tests compile Warp kernels and MJX programs for both implementations (minutes on a fresh machine);
they run wherever warp-lang is importable, on a CUDA GPU in practice.
"""

import copy
import os

os.environ.setdefault("MUJOCO_GL", "egl")

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from jaxarm import envs
from jaxarm.envs.panda.base import CONTROL_DT, WARP_TIMESTEP, ArmOptions
from jaxarm.envs.panda.mjx_impl import (
    Impl,
    constraint_capacity,
    contact_capacity,
    put_scene,
    resolve_impl,
    warp_available,
    with_geom_sizes,
)
from jaxarm.envs.panda_sort import SHAPE_CUBE, PandaSort
from jaxarm.envs.panda_sort.scripted import script_start, scripted_action
from jaxarm.envs.peg_insert import PegInsert

HORIZON = 10
"""Env steps compared between the implementations (0.4 s of simulated time)."""
NUM_ENVS = 16
TOLERANCE = {"qpos": 2e-3, "obs": 2e-2, "reward": 5e-2}
"""Largest |JAX − Warp| allowed at any step of the horizon: qpos in metres and radians; obs in the envs' own
units (positions, velocities, scaled peg offsets); reward per step. Both run float32 with the same solver
settings but their own contact sets and reduction orders, so contacts may settle on slightly different
forces; anything beyond these is a different simulation."""


# --- everywhere, without warp-lang -------------------------------------------------------------------


def test_jax_is_the_default_and_auto_picks_it_off_an_nvidia_gpu():
    assert PegInsert().impl == Impl.JAX
    if jax.devices()[0].platform == "cpu":
        assert resolve_impl("auto") == Impl.JAX


def test_an_unknown_impl_is_refused_by_name():
    with pytest.raises(ValueError, match="impl must be one of"):
        resolve_impl("mujoco")


@pytest.mark.skipif(warp_available(), reason="warp-lang is installed here")
def test_warp_without_warp_lang_says_what_is_missing():
    with pytest.raises(ValueError, match="warp-lang"):
        PegInsert(options=ArmOptions(impl="warp"))


def test_buffers_are_sized_from_the_scene_pairs():
    # The peg's pairs: capsule vs the block's 5 boxes (2 contacts each) and vs the table plane (2), all
    # condim 3 (4 pyramidal rows a contact); the Panda has 9 limited joints (7 arm, 2 fingers).
    model = PegInsert().mj_model
    assert contact_capacity(model) == 5 * 2 + 2
    assert constraint_capacity(model) == (5 * 2 + 2) * 4 + 9
    assert constraint_capacity(model, contacts=3) == 3 * 4 + 9


def test_resized_geoms_get_bounding_boxes_to_match():
    env = PandaSort(objects_count=1)
    box, sphere = env.ids.object_geom[0, 0], env.ids.object_geom[0, 2]
    assert env.mj_model.geom_type[box] == mujoco.mjtGeom.mjGEOM_BOX
    assert env.mj_model.geom_type[sphere] == mujoco.mjtGeom.mjGEOM_SPHERE
    size = jnp.array([[0.01, 0.02, 0.03], [0.04, 0.0, 0.0]])
    model = with_geom_sizes(env.mjx_model, np.array([box, sphere]), size, jnp.array([0.5, 0.04]))
    half_extents = np.asarray(model.geom_aabb).reshape(-1, 2, 3)[[box, sphere], 1]
    np.testing.assert_allclose(half_extents, [[0.01, 0.02, 0.03], [0.04, 0.04, 0.04]])
    np.testing.assert_allclose(np.asarray(model.geom_rbound)[[box, sphere]], [0.5, 0.04])


# --- where warp-lang is importable ---------------------------------------------------------------------


def sort_params(env, num_envs: int, key: jax.Array):
    """[num_envs] sorter params: per-env friction, mass and size randomisation, half the starts grasp-ready."""
    base = env.default_params()
    scale = jax.random.uniform(key, (num_envs,), minval=0.6, maxval=1.4)
    params = jax.tree.map(lambda leaf: jnp.broadcast_to(leaf, (num_envs, *leaf.shape)), base)
    return params.replace(
        object_friction=base.object_friction * scale,
        finger_friction=base.finger_friction * scale[::-1],
        mass_scale=scale,
        ready_start_prob=jnp.full((num_envs,), 0.5),
    )


def peg_params(env, num_envs: int, key: jax.Array):
    """[num_envs] peg params: per-env clearance and friction."""
    base = env.default_params()
    scale = jax.random.uniform(key, (num_envs,), minval=0.5, maxval=1.5)
    params = jax.tree.map(lambda leaf: jnp.broadcast_to(leaf, (num_envs, *leaf.shape)), base)
    return params.replace(clearance=base.clearance * scale, friction=base.friction * scale[::-1])


def actions_for(name: str, action_shape: tuple[int, ...], key: jax.Array) -> jax.Array:
    """[HORIZON, NUM_ENVS, A] actions: uniform in [-1, 1]; the peg's are pressed downwards (into the block)."""
    actions = jax.random.uniform(key, (HORIZON, NUM_ENVS, *action_shape), minval=-1.0, maxval=1.0)
    return actions.at[..., 2].set(-1.0) if name == "peg" else actions


def rollout(env, params, state, actions):
    """Steps the batch through `actions` [T, B, A]; returns ([T, B, nq] qpos, [T, B, O] obs, [T, B] reward)."""
    batch = envs.VmapEnv(env, actions.shape[1], batched_params=True)

    @jax.jit
    def run(state):
        def body(state, action):
            state = batch.step(state, action, params)
            return state, (state.sim.qpos, state.obs, state.reward)

        return jax.lax.scan(body, state, actions)[1]

    return jax.tree.map(np.asarray, run(state))


def make_env(name: str, impl: str) -> PandaSort | PegInsert:
    """The env compared as `name` ("sort1", "sort3" or "peg") on MJX implementation `impl`."""
    options = ArmOptions(impl=impl)
    if name == "peg":
        return PegInsert(options=options)
    if name == "sort3":
        return PandaSort(objects_count=3, target_first=True, options=options)
    return PandaSort(options=options)


def on_one_timestep_without_force_limits(env: PandaSort | PegInsert) -> PandaSort | PegInsert:
    """`env` stepping at WARP_TIMESTEP with no actuator force limit, on its own implementation: the two known
    differences between the implementations' Panda scenes (the timestep, and clamped servos' damping) removed."""
    mj_model = copy.copy(env.mj_model)
    mj_model.opt.timestep = WARP_TIMESTEP
    mj_model.actuator_forcelimited[:] = 0
    env.mj_model = mj_model
    env.substeps = round(CONTROL_DT / WARP_TIMESTEP)
    env.mjx_model, env._data0 = put_scene(mj_model, env.impl, NUM_ENVS)
    return env


def max_differences(name: str, prepare=lambda env: env) -> dict[str, np.ndarray]:
    """Per step, the largest |JAX − Warp| of qpos, obs and reward over NUM_ENVS envs of `name` (each env passed
    through `prepare`) started from the same (JAX-reset) states and driven by the same actions."""
    env_jax, env_warp = prepare(make_env(name, "jax")), prepare(make_env(name, "warp"))
    params_key, reset_key, action_key = jax.random.split(jax.random.key(3), 3)
    params = (peg_params if name == "peg" else sort_params)(env_jax, NUM_ENVS, params_key)
    start = envs.VmapEnv(env_jax, NUM_ENVS, batched_params=True).reset(reset_key, params)
    actions = actions_for(name, env_jax.spec.action_shape, action_key)
    jax_run = rollout(env_jax, params, start, actions)
    warp_run = rollout(env_warp, params, start, actions)
    return {
        field: np.abs(a - b).reshape(HORIZON, -1).max(axis=1)
        for field, a, b in zip(("qpos", "obs", "reward"), jax_run, warp_run, strict=True)
    }


def test_scripted_pick_and_place_scores_500_on_warp():
    pytest.importorskip("warp")
    from tests.envs.test_panda_sort import JittedStep, scripted_pick_and_place, with_object

    env = PandaSort(objects_count=1, options=ArmOptions(impl="warp"))
    params = env.default_params()
    size, yaw = 0.0375, np.pi / 4
    pose = [0.5, -0.1, size + 0.001, np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)]
    state = with_object(env, jax.jit(env.reset)(jax.random.key(0), params), SHAPE_CUBE, size, pose)
    state, correct, wrong, _ = scripted_pick_and_place(
        JittedStep(env), state, params, np.array(env.layout.bin_centers[SHAPE_CUBE])
    )
    assert list(correct[correct != 0]) == [500.0] and not np.any(wrong)
    assert bool(state.terminated) and bool(state.episode.success)


def test_warp_steps_the_panda_at_its_own_timestep():
    pytest.importorskip("warp")
    assert PegInsert(options=ArmOptions(impl="warp")).mj_model.opt.timestep == WARP_TIMESTEP
    assert PandaSort(options=ArmOptions(impl="warp")).substeps == round(CONTROL_DT / WARP_TIMESTEP)
    assert PandaSort(options=ArmOptions(impl="jax")).substeps == 4


def scripted_placements(env: PandaSort, num_envs: int, steps: int = 250) -> float:
    """Mean objects the scripted pick-and-place puts in their own bins over `num_envs` fresh episodes (random
    shapes, sizes and poses), each run until it ends."""
    params = env.default_params()
    batch = envs.VmapEnv(env, num_envs)
    state = jax.jit(batch.reset)(jax.random.key(5), params)
    bins = jnp.asarray(np.array(env.layout.bin_centers), jnp.float32)[state.sim.shape[:, 0]]
    act = jax.vmap(lambda obs, script, bin_xy: scripted_action(env, obs, script, params, bin_xy))

    @jax.jit
    def run(state):
        def body(carry, _):
            state, script, ended = carry
            action, script = act(state.obs, script, bins)
            # An ended episode keeps its last state: a plain env has no auto-reset.
            next_state = jax.tree.map(
                lambda new, old: jnp.where(ended.reshape(-1, *[1] * (new.ndim - 1)), old, new),
                batch.step(state, action, params),
                state,
            )
            return (next_state, script, ended | next_state.terminated), None

        script = jax.vmap(lambda one: script_start(env, one))(state)
        final, _, _ = jax.lax.scan(body, (state, script, jnp.zeros(num_envs, bool)), None, length=steps)[0]
        return final.info.correct_count.mean()

    return float(run(state))


def test_scripted_pick_and_place_places_most_objects_on_warp():
    pytest.importorskip("warp")
    # At MJX-JAX's 0.01 s step Warp placed 32% (1,024 envs, H100; see WARP_TIMESTEP); at 0.005 s 82% (1,024 envs,
    # H100), 80% (64) and 72% (32) on the CPU, against 91-95% on MJX-JAX. Within Franka's speed and acceleration
    # limits, on an H200: 67.9% of 1,024 envs, 65.2% of 256, and 59.4% of 32, too few to tell 68% from 60%.
    num_envs = 1024 if jax.default_backend() == "gpu" else 32
    env = PandaSort(objects_count=1, options=ArmOptions(impl="warp", max_envs=num_envs))
    assert scripted_placements(env, num_envs) >= 0.6


def test_warp_kernels_print_no_overflow_warnings():
    pytest.importorskip("warp")
    # The overflow bits stay set (the test below raises on them); only the GPU's printing is off.
    assert PandaSort(options=ArmOptions(impl="warp")).mjx_model.opt._impl.warn_overflow == 0
    assert PegInsert(options=ArmOptions(impl="warp")).mjx_model.opt._impl.warn_overflow == 0


def test_a_contact_buffer_too_small_for_the_batch_raises():
    pytest.importorskip("warp")
    # Room for one env's worst case, shared by 64 envs whose objects rest on the table (4+ contacts each).
    env = PandaSort(objects_count=1, options=ArmOptions(impl="warp", max_envs=1))
    params = env.default_params()
    batch = envs.VmapEnv(env, 64)
    state = jax.jit(batch.reset)(jax.random.key(0), params)
    with pytest.raises(Exception, match="MJX Warp overflow"):
        jax.block_until_ready(jax.jit(batch.step)(state, jnp.zeros((64, *env.spec.action_shape)), params))


def test_a_contact_buffer_too_small_raises_once_after_steps_that_defer_their_checks():
    pytest.importorskip("warp")
    env = PandaSort(objects_count=1, options=ArmOptions(impl="warp", max_envs=1))
    # Episodes of one step: the bits of the step that overflowed must outlive its episode.
    params = envs.override_params(env.default_params(), {"max_episode_steps": 1})
    batch = envs.VmapEnv(envs.AutoReset(env), 64)
    state = jax.jit(batch.reset)(jax.random.key(0), params)
    with envs.deferred_step_checks():
        stepped = jax.block_until_ready(jax.jit(batch.step)(state, jnp.zeros((64, *env.spec.action_shape)), params))
    np.testing.assert_array_equal(stepped.step_count, 0)
    assert np.all(stepped.sim.overflow != 0)
    with pytest.raises(Exception, match="MJX Warp overflow"):
        jax.block_until_ready(jax.jit(batch.checked)(stepped))


@pytest.mark.xfail(
    strict=True,
    reason="mujoco-mjx 3.17 (H100): kinematics, IK targets and a step at the resting controls agree to 1e-6, but "
    "after the IK moves the targets one physics step differs by 1 rad/s in qvel on joint 5, whose actuator "
    "saturates at 12 N m: under implicitfast, MJX-JAX keeps the damping (kv) of a saturated position actuator "
    "in its implicit step (0.06 rad/s) where MuJoCo C and Warp drop it (0.97 rad/s), and Warp steps at "
    "WARP_TIMESTEP for that reason; see BENCHMARKS.md",
)
@pytest.mark.parametrize("name", ["sort1", "peg", "sort3"])
def test_warp_follows_the_jax_trajectories(name):
    pytest.importorskip("warp")
    differences = max_differences(name)
    for field, per_step in differences.items():
        print(f"{name} {field}: max |jax - warp| per step {np.array2string(per_step, precision=2)}")
    for field, per_step in differences.items():
        assert np.all(np.isfinite(per_step)) and per_step.max() <= TOLERANCE[field], (field, per_step)


def test_warp_follows_the_peg_at_one_timestep_without_force_limits():
    pytest.importorskip("warp")
    # With the two known differences removed the peg's trajectories, its contacts in the hole included, agreed to
    # 1e-6 m in qpos (CPU, 2026-11-24). The sorter's arm agreed to 4e-4 rad over 3 steps, but its fingers and
    # object did not (0.14 in the object's quaternion by step 3): its gripper-object contacts differ.
    differences = max_differences("peg", on_one_timestep_without_force_limits)
    for field, per_step in differences.items():
        assert np.all(np.isfinite(per_step)) and per_step.max() <= TOLERANCE[field] / 100, (field, per_step)

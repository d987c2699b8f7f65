"""Every registered robot through one contract, on the peg task built for it (`peg_insert`, `env_kwargs.robot`): its
reset puts the tool where the task asks, pointing down; a step keeps the arm's targets within the robot's joint
limits; and the IK reaches: a scripted descent inserts the peg from every start of a batch."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.envs.peg_insert.model import HOLE_NOMINAL, PEG_LENGTH
from jaxarm.envs.registry import names, registered_kwargs
from jaxarm.robots import ROBOTS
from tests.envs.compiled import compiled, same_worker

PEG_ENVS = {
    registered_kwargs(name).get("robot", "panda"): name
    for name in names()
    if name.startswith("peg_insert") and "obs_mode" not in registered_kwargs(name)
}
"""Robot -> its registered peg env of state observations."""


def robot_params():
    return [pytest.param(robot, marks=same_worker(PEG_ENVS[robot])) for robot in sorted(ROBOTS)]


def test_every_robot_has_a_registered_peg_task():
    assert sorted(PEG_ENVS) == sorted(ROBOTS)


@pytest.mark.mjx
@pytest.mark.parametrize("robot", robot_params())
def test_the_reset_holds_the_peg_over_the_hole_pointing_down(robot):
    peg = compiled(PEG_ENVS[robot])
    assert peg.env.robot.name == robot and peg.env.arm_dof == len(ROBOTS[robot].arm_joints)
    state = peg.reset(jax.random.PRNGKey(0), peg.params.replace(home_noise=jnp.float32(0.0)))
    robot_ids = peg.env.ids.robot
    data = peg.env.kinematics(peg.env.mjx_model, state.sim)
    tcp = np.asarray(data.site_xpos[robot_ids.tcp_site])
    np.testing.assert_allclose(tcp[:2], HOLE_NOMINAL, atol=1e-4)
    assert tcp[2] > PEG_LENGTH
    down = np.asarray(data.site_xmat[robot_ids.tcp_site]).reshape(3, 3)[:, 2]
    np.testing.assert_allclose(down, [0.0, 0.0, -1.0], atol=1e-3)


@pytest.mark.mjx
@pytest.mark.parametrize("robot", robot_params())
def test_a_scripted_descent_inserts_from_every_start_within_the_joint_limits(robot):
    peg = compiled(PEG_ENVS[robot])
    limits = ROBOTS[robot].joint_limits
    keys = jax.random.split(jax.random.PRNGKey(1), 8)
    step = jax.jit(jax.vmap(peg.step, in_axes=(0, 0, None)))
    state = peg.batched_reset(keys, peg.params)
    inserted = np.zeros(len(keys), bool)
    for _ in range(80):
        # Towards the hole bottom (the observation's first three values), at most a full step per axis.
        state = step(state, jnp.clip(state.obs[:, :3] * 5.0, -1.0, 1.0), peg.params)
        inserted |= np.asarray(state.info.inserted)
        speeds = np.abs(np.asarray(state.sim.target_velocity))
        assert np.all(speeds <= limits.speed * (1 + 1e-5)), speeds.max(axis=0)
    assert inserted.all()

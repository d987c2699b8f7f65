"""The deployment package's numpy scoring against the sorter env's, on hand-placed states."""

import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm import deployable
from jaxarm.deploy import scoring
from jaxarm.deployable import panda_sort
from jaxarm.envs.panda_sort import make_layout, reward
from jaxarm.envs.panda_sort.objects import pose_index, velocity_index
from tests.deploy.test_controller import sorter_case


@pytest.mark.parametrize("tosser", [False, True])
def test_objects_score_as_in_the_env(tosser):
    layout = make_layout(tosser=tosser)
    bins = panda_sort.scoring_bins(layout)
    rng = np.random.default_rng(0)
    # Around and inside every bin, above and below its rim, on the table and below it.
    centres = np.repeat(np.array(layout.bin_centers), 40, axis=0)
    xy = centres + rng.uniform(-0.1, 0.1, centres.shape)
    z = rng.uniform(-0.1, 0.1, len(xy))
    position = np.concatenate([xy, z[:, None]], -1).astype(np.float32)
    shape = rng.integers(0, 3, len(xy))
    outcome = np.where(rng.random(len(xy)) < 0.2, scoring.ON_FLOOR, scoring.IN_PLAY)
    expected = reward.next_outcome(jnp.asarray(outcome), jnp.asarray(shape), jnp.asarray(position), layout)
    ours = scoring.next_outcome(outcome, shape, position, bins)
    np.testing.assert_array_equal(ours, np.asarray(expected))
    assert {scoring.IN_PLAY, scoring.IN_CORRECT_BIN, scoring.IN_WRONG_BIN, scoring.ON_FLOOR} <= set(ours.tolist())


def scoring_state(env, controller, sim, target: int) -> scoring.SortState:
    """What the numpy scoring reads of a (non-batched) sorter `sim`, with slot `target` the target; the tool
    centre by `controller`'s kinematics."""
    qpos = np.asarray(sim.qpos, np.float64)
    return scoring.SortState(
        position=qpos[pose_index(env.ids)[:, :3]],
        shape=np.asarray(sim.shape),
        size=np.asarray(sim.size, np.float64),
        outcome=np.asarray(sim.outcome),
        exit_xy=np.asarray(sim.exit_xy, np.float64),
        velocity=np.asarray(sim.qvel, np.float64)[velocity_index(env.ids)[:, :3]],
        target=target,
        tcp=controller.kinematics.pose(qpos[:7]).tcp,
        finger_q=qpos[7:9],
        finger_ctrl=np.asarray(sim.ctrl, np.float64)[7:],
    )


@pytest.mark.mjx
def test_target_and_shaping_potential_are_the_envs():
    env, params, sim, _, _, _, outcome, target, potential = sorter_case("ee")
    controller = deployable.controller(env, params)
    seen = scoring_state(env, controller, sim, int(sim.target))
    np.testing.assert_array_equal(
        scoring.next_outcome(seen.outcome, seen.shape, seen.position, controller.task.bins), outcome
    )
    # The target (slot 1) is out of play: the nearest in-play object takes over.
    assert scoring.next_target(outcome, seen.target, seen.position, seen.tcp) == int(target) == 0
    for slot in range(2):
        state = scoring_state(env, controller, sim, slot)
        ours = scoring.shaping_potential(state, controller.task.bins, panda_sort.sort_reward(env, params))
        np.testing.assert_allclose(ours, potential[slot], atol=1e-5)
    # With slot 0 (in play) the target, its reach term counts beside slot 1's full marks.
    assert potential[0, 0] > potential[1, 0] == 1.0

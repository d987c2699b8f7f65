"""The deployment loop's numpy observation and controller against the JAX envs', to 1e-5, on hand-placed states.

One program per env computes the env's own observation and servo targets for a batch of actions (and the
sorter's scoring, tests/deploy/test_scoring.py reads it); the numpy side runs the same states through
`jaxarm.deploy`.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm import deployable
from jaxarm.deploy import limits, peg, sort
from jaxarm.deploy.reading import ArmReading, HoleEstimate, ObjectEstimate
from jaxarm.envs.panda.base import CONTROL_DT, ArmOptions
from jaxarm.envs.panda.robot import tcp_pose_at
from jaxarm.envs.panda_sort import IN_CORRECT_BIN, IN_PLAY, MODE_JOINT, PandaSort, PandaSortSim
from jaxarm.envs.panda_sort.objects import pose_index, velocity_index
from jaxarm.envs.panda_sort.reward import next_outcome, next_target, shaping_potential
from jaxarm.envs.peg_insert.env import PegInsert, PegInsertSim
from jaxarm.robots import ROBOTS

pytestmark = pytest.mark.mjx
TOLERANCE = 1e-5
ACTIONS = 6


def hand_placed_sorter(env: PandaSort, rng: np.random.Generator) -> PandaSortSim:
    """Two objects, the second already in its bin; the arm near its start posture and moving, its servos' targets
    leading it."""
    model = env.mj_model
    qpos = model.qpos0.astype(np.float32).copy()
    arm_q = env.start_qpos + rng.uniform(-0.3, 0.3, 7)
    qpos[:7], qpos[7:9] = arm_q, [0.012, 0.013]
    positions = np.array([[0.45, -0.05, 0.02], [0.36, 0.36, 0.02]])
    yaw = np.array([0.4, -1.1])
    for slot, (position, angle) in enumerate(zip(positions, yaw, strict=True)):
        start = env.ids.object_qpos[slot]
        qpos[start : start + 7] = [*position, np.cos(angle / 2), 0.0, 0.0, np.sin(angle / 2)]
    qvel = rng.normal(0.0, 0.3, model.nv).astype(np.float32)
    ctrl = np.concatenate([arm_q + rng.uniform(-0.05, 0.05, 7), [0.01, 0.01]]).astype(np.float32)
    return PandaSortSim(
        qpos=jnp.asarray(qpos),
        qvel=jnp.asarray(qvel),
        qacc_warmstart=jnp.zeros(model.nv),
        ctrl=jnp.asarray(ctrl),
        target_velocity=jnp.asarray(rng.uniform(-2.0, 2.0, 7), jnp.float32),
        shape=jnp.array([1, 0], jnp.int32),
        size=jnp.array([0.02, 0.03]),
        colour=jnp.zeros((2, 3)),
        outcome=jnp.array([IN_PLAY, IN_CORRECT_BIN], jnp.int32),
        exit_xy=jnp.zeros((2, 2)),
        target=jnp.array(1, jnp.int32),
        potential=jnp.zeros(5),
        queued_actions=env.initial_action_queue(),
        noise_key=jax.random.key(0),
        pose_error=jnp.zeros((2, 3)),
        overflow=jnp.zeros((), jnp.int32),
    )


@functools.cache
def sorter_case(control_mode: str):
    """(env, params, sim, actions [B, A], the env's observation [O], ctrl [B, 9] (the servo targets sent, within
    Franka's limits), outcome [N], target, potential [2, 5] with each slot the target) for a two-object
    target-first sorter with the running target."""
    env = PandaSort(objects_count=2, target_first=True, running_target=True, control_mode=control_mode)
    params = env.default_params()
    sim = hand_placed_sorter(env, np.random.default_rng(0))
    rng = np.random.default_rng(1)
    actions = rng.uniform(-1.0, 1.0, (ACTIONS, env.spec.action_shape[0])).astype(np.float32)
    actions[0] = 0.0
    actions[1, :4] = [1.0, -1.0, 1.0, 1.0]  # beyond the leads in every direction

    @jax.jit
    def reference(sim, actions):
        model = env.episode_model(sim, params)
        data = env.kinematics(model, sim)
        obs = env._observe(model, data, sim, params, jax.random.key(1))
        ctrl = jax.vmap(lambda action: env.limited_ctrl(env._ctrl(model, data, action, params), sim)[0])(actions)
        positions = sim.qpos[env.ids.object_qpos[:, None] + np.arange(3)]
        outcome = next_outcome(sim.outcome, sim.shape, positions, env.layout)
        target = next_target(env.ids, data, sim.replace(outcome=outcome))
        potential = jnp.stack(
            [
                shaping_potential(env.ids, env.layout, data, sim.replace(target=jnp.array(slot)), params, True)
                for slot in range(2)
            ]
        )
        return obs, ctrl, outcome, target, potential

    return (env, params, sim, actions, *(np.asarray(value) for value in reference(sim, jnp.asarray(actions))))


def sorter_inputs(env: PandaSort, sim: PandaSortSim) -> tuple[ArmReading, ObjectEstimate]:
    qpos, qvel = np.asarray(sim.qpos, np.float64), np.asarray(sim.qvel, np.float64)
    reading = ArmReading(arm_q=qpos[:7], arm_qvel=qvel[:7], finger_q=qpos[7:9])
    pose, velocity = qpos[pose_index(env.ids)], qvel[velocity_index(env.ids)]
    objects = ObjectEstimate(pose, velocity, np.asarray(sim.shape), np.asarray(sim.size))
    return reading, objects


@pytest.mark.parametrize("control_mode", ["ee", MODE_JOINT])
def test_the_sorter_observes_and_acts_as_the_env(control_mode):
    env, params, sim, actions, obs, ctrl, *_ = sorter_case(control_mode)
    controller = deployable.controller(env, params)
    assert isinstance(controller, sort.SortController)
    reading, objects = sorter_inputs(env, sim)
    pose = controller.kinematics.pose(reading.arm_q)
    outcome, target, sim_ctrl = np.asarray(sim.outcome), int(sim.target), np.asarray(sim.ctrl, np.float64)
    ours = sort.observation(controller.task, pose, reading, objects, outcome, target, sim_ctrl)
    np.testing.assert_allclose(ours, obs, atol=TOLERANCE)
    # The target (slot 1, out of play: zeros) comes first.
    assert not np.any(ours[:26]) and np.any(ours[26:52])
    for action, expected in zip(actions, ctrl, strict=True):
        arm = sort.arm_targets(controller.task, controller.kinematics, pose, sim_ctrl, action.astype(np.float64))
        # What the deployment loop sends: the same limits from the same targets and their rate.
        arm = limits.limit_targets(arm, sim_ctrl[:7], np.asarray(sim.target_velocity, np.float64), CONTROL_DT).targets
        fingers = sort.finger_targets(controller.task, action)
        np.testing.assert_allclose(np.concatenate([arm, fingers]), expected, atol=TOLERANCE)
    # The actions move the targets: a test of a controller that ignores them would pass otherwise.
    assert np.ptp(ctrl[:, :7], axis=0).max() > 0.01


@pytest.mark.parametrize("running_target", [False, True])
@pytest.mark.parametrize("robot", sorted(ROBOTS))
def test_the_peg_observes_and_acts_as_the_env_on_every_robot(robot, running_target):
    env = PegInsert(running_target=running_target, options=ArmOptions(robot=robot))
    params = env.default_params()
    rng = np.random.default_rng(2)
    joints = env.arm_dof
    qpos = env.mj_model.qpos0.astype(np.float32).copy()
    qpos[:joints] = env.start_qpos + rng.uniform(-0.2, 0.2, joints)
    qvel = rng.normal(0.0, 0.3, env.mj_model.nv).astype(np.float32)
    hole = np.array([0.55, -0.04], np.float32)
    # The target the servos chase leads the tool by less than `max_lead` (1 cm), so each action moves it.
    tcp = tcp_pose_at(env.mj_model, env.ids.robot, qpos[:joints])[0]
    tcp_target = (tcp + [0.004, -0.003, 0.002]).astype(np.float32)
    velocity = rng.uniform(-0.5, 0.5, joints).astype(np.float32)
    sim = PegInsertSim(
        qpos=jnp.asarray(qpos),
        qvel=jnp.asarray(qvel),
        qacc_warmstart=jnp.zeros(env.mj_model.nv),
        # The servos' targets lead the arm, as when it moves: the running target's IK starts from them.
        ctrl=jnp.asarray(np.r_[qpos[:joints] + rng.uniform(-0.05, 0.05, joints), 0.01, 0.01], jnp.float32),
        target_velocity=jnp.asarray(velocity),
        tcp_target=jnp.asarray(tcp_target),
        hole=jnp.asarray(hole),
        initial_distance=jnp.array(0.2),
        distance=jnp.array(0.2),
        queued_actions=env.initial_action_queue(),
        noise_key=jax.random.key(0),
        hole_error=jnp.zeros(3),
        surface_gray=jnp.full(2, 0.5),
        overflow=jnp.zeros((), jnp.int32),
    )
    actions = rng.uniform(-1.0, 1.0, (ACTIONS, 3)).astype(np.float32)
    actions[0] = 0.0
    actions[1] = [1.0, -1.0, 1.0]  # beyond the lead in every direction

    @jax.jit
    def reference(sim, actions):
        model = env.episode_model(sim, params)
        data = env.kinematics(model, sim)
        obs = env._observe(model, data, sim, params, jax.random.key(1))

        def ctrl(action):
            target, arm = env._arm_targets(model, data, sim, action, params)
            return target, env.limited_ctrl(jnp.concatenate([arm, sim.ctrl[joints:]]), sim)[0][:joints]

        return obs, *jax.vmap(ctrl)(actions)

    obs, targets, arm = (np.asarray(value) for value in reference(sim, jnp.asarray(actions)))
    controller = deployable.controller(env, params)
    assert isinstance(controller, peg.PegController)
    arm_q, arm_qvel = qpos[:joints].astype(np.float64), qvel[:joints].astype(np.float64)
    reading = ArmReading(arm_q=arm_q, arm_qvel=arm_qvel, finger_q=qpos[joints : joints + 2])
    pose = controller.kinematics.pose(reading.arm_q)
    ours = peg.observation(controller.task, controller.kinematics, pose, reading, HoleEstimate(hole), tcp_target)
    np.testing.assert_allclose(ours, obs, atol=TOLERANCE)
    sim_ctrl = np.asarray(sim.ctrl, np.float64)
    for action, expected_target, expected in zip(actions, targets, arm, strict=True):
        target, ours_arm = peg.arm_targets(
            controller.task, controller.kinematics, pose, tcp_target.astype(np.float64), sim_ctrl, action
        )
        np.testing.assert_allclose(target, expected_target, atol=TOLERANCE)
        robot_limits = env.robot.joint_limits
        sent = limits.limit_targets(ours_arm, sim_ctrl[:joints], velocity.astype(np.float64), CONTROL_DT, robot_limits)
        np.testing.assert_allclose(sent.targets, expected, atol=TOLERANCE)
    assert np.ptp(arm, axis=0).max() > 1e-3

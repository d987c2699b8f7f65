"""The sorter as a deployable task: its `jaxarm.deploy.sort` controller, bins and reward read from a `PandaSort`
and its params; its scene with another model of its robot; one episode in stock MuJoCo, scored in numpy."""

from pathlib import Path

import mujoco
import numpy as np

from jaxarm.deploy import scoring, sort
from jaxarm.deploy.kinematics import ArmKinematics
from jaxarm.deploy.loop import DeploymentLoop
from jaxarm.deploy.mujoco_robot import MujocoRobot
from jaxarm.deploy.reading import ObjectEstimate
from jaxarm.deployable.base import Capture, Deployable
from jaxarm.envs.panda_sort import env as sort_env
from jaxarm.envs.panda_sort import model as sort_model
from jaxarm.envs.panda_sort.layout import Layout
from jaxarm.envs.panda_sort.objects import object_mass_inertia, pose_index, velocity_index
from jaxarm.envs.panda_sort.render import dress_objects


def scoring_bins(layout: Layout) -> scoring.Bins:
    return scoring.Bins(np.array(layout.bin_centers), layout.bin_half, layout.bin_wall_height)


def sort_task(env: sort_env.PandaSort, params) -> sort.SortTask:
    """The sorter's `SortTask` of `env` (of state observations or cameras: the controller is the same) with `params`."""

    def number(name: str) -> float:
        return float(getattr(params, name))

    return sort.SortTask(
        objects_count=env.objects_count,
        control_mode=env.control_mode,
        running_target=env.running_target,
        target_first=env.target_first,
        **{
            name: number(name)
            for name in (
                "ee_step",
                "ee_yaw_step",
                "joint_step",
                "max_lead",
                "max_yaw_lead",
                "max_joint_lead",
                "ik_damping",
                "ik_posture_gain",
                "carry_height",
            )
        },
        start_qpos=np.asarray(env.start_qpos, np.float64),
        home_tcp_rotation=np.asarray(env.home_tcp_rotation, np.float64),
        bins=scoring_bins(env.layout),
        tcp_min_z=sort_env.TCP_MIN_Z,
        finger_open=env.robot.finger_open,
    )


def sort_reward(env: sort_env.PandaSort, params) -> scoring.SortReward:
    """The sorter's reward params of `params`."""
    names = [field for field in scoring.SortReward.__dataclass_fields__ if field != "target_first"]
    return scoring.SortReward(**{name: float(getattr(params, name)) for name in names}, target_first=env.target_first)


def controller(env: sort_env.PandaSort, params) -> sort.SortController:
    return sort.SortController(sort_task(env, params), ArmKinematics(env.mj_model, env.robot))


def scene(env: sort_env.PandaSort, params, robot_xml: Path) -> mujoco.MjModel:
    """The env's scene with its robot's model `robot_xml`; the tosser's with its firm grip, as the env builds it."""
    return sort_model.build_model(
        env.objects_count, env.layout, firm_grip=env.tosser, robot=env.robot.name, robot_xml=robot_xml
    )


def dress_scene(model: mujoco.MjModel, env: sort_env.PandaSort, params, shape, size, colour) -> sort_model.ModelIds:
    """Writes an episode's objects (shapes [N], sizes [N], colours [N, 3]) and the params' masses and friction into
    the robot's scene `model` (in place), as the env's `episode_model` does; returns the scene's ids, resolved in
    it (another Panda model may number its bodies differently)."""
    ids = sort_model.resolve_ids(model, env.objects_count, env.robot.name)
    dress_objects(model, ids, shape, size, colour)
    geoms = ids.object_geom.ravel()
    model.geom_rbound[geoms] = np.linalg.norm(model.geom_size[geoms], axis=-1)
    spheres = ids.object_geom[:, 2]
    model.geom_rbound[spheres] = model.geom_size[spheres, 0]
    mass, inertia = (np.asarray(array) for array in object_mass_inertia(shape, size, params.density))
    model.body_mass[ids.object_body] = mass * float(params.mass_scale)
    model.body_inertia[ids.object_body] = inertia * float(params.mass_scale)
    model.pair_friction[ids.finger_pair, :2] = float(params.finger_friction)
    model.pair_friction[ids.object_pair, :2] = float(params.object_friction)
    return ids


def start_scene(
    model: mujoco.MjModel, data: mujoco.MjData, env: sort_env.PandaSort, params, sim
) -> sort_model.ModelIds:
    """Dresses the robot's scene `model` for the episode `sim` (the env's reset) and puts `data` at its start (in
    place; the servos' targets are the caller's to send); returns the scene's ids."""
    ids = dress_scene(model, env, params, sim.shape, sim.size, sim.colour)
    # The objects' new masses change the constants MuJoCo derives from them (their inverse weights).
    mujoco.mj_setConst(model, data)
    mujoco.mj_resetData(model, data)
    data.qpos[:] = sim.qpos
    return ids


def episode(
    robot: MujocoRobot,
    loop: DeploymentLoop,
    env: sort_env.PandaSort,
    params,
    sim,
    capture: Capture,
    pose_bias: np.ndarray,
) -> dict:
    """One sorter episode from `sim` (the env's reset), the objects' estimated centres off by `pose_bias` [3] (m);
    its success, return, steps and objects placed (scored from the true centres)."""
    model, data = robot.model, robot.data
    ids = start_scene(model, data, env, params, sim)
    robot.command(sim.ctrl)
    mujoco.mj_forward(model, data)
    bins, reward = scoring_bins(env.layout), sort_reward(env, params)
    shape, size = sim.shape, sim.size.astype(np.float64)
    tcp_site = ids.robot.tcp_site

    def world(outcome, exit_xy, target) -> scoring.SortState:
        return scoring.SortState(
            position=data.qpos[pose_index(ids)[:, :3]].copy(),
            shape=shape,
            size=size,
            outcome=outcome,
            exit_xy=exit_xy,
            velocity=data.qvel[velocity_index(ids)[:, :3]].copy(),
            target=target,
            tcp=data.site_xpos[tcp_site].copy(),
            finger_q=data.qpos[ids.robot.finger_qpos].copy(),
            finger_ctrl=loop.ctrl[7:].copy(),
        )

    loop.begin(sim.ctrl)
    state = world(sim.outcome.copy(), np.zeros((len(shape), 2)), int(sim.target))
    potential = scoring.shaping_potential(state, bins, reward)
    total, steps = 0.0, 0
    capture(data)
    while steps < int(params.max_episode_steps):
        steps += 1
        pose = data.qpos[pose_index(ids)].copy()
        pose[:, :3] += pose_bias
        estimate = ObjectEstimate(pose, data.qvel[velocity_index(ids)].copy(), shape, size)
        robot.command(loop.tick(robot.reading(), estimate))
        robot.step()
        capture(data)
        now = world(state.outcome, state.exit_xy, state.target)
        outcome = scoring.next_outcome(state.outcome, shape, now.position, bins)
        leaving = (state.outcome == scoring.IN_PLAY) & (outcome != scoring.IN_PLAY)
        exit_xy = np.where(leaving[:, None], now.position[:, :2], state.exit_xy)
        target = scoring.next_target(outcome, state.target, now.position, now.tcp)
        now = world(outcome, exit_xy, target)
        next_potential = scoring.shaping_potential(now, bins, reward)
        total += scoring.sort_reward(state.outcome, outcome, float(np.sum(next_potential - potential)), reward)
        state, potential = now, next_potential
        if not np.any(outcome == scoring.IN_PLAY):
            break
    placed = np.mean(state.outcome == scoring.IN_CORRECT_BIN)
    return {"success": bool(placed == 1.0), "return": total, "steps": steps, "placed": float(placed)}


DEPLOYABLE = Deployable(sort_env.PandaSort, controller, scene, episode)

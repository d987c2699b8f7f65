"""The peg insertion as a deployable task: its `jaxarm.deploy.peg` controller and reward read from a `PegInsert` and
its params; its scene with another model of its robot; one episode in stock MuJoCo, scored in numpy."""

from pathlib import Path

import mujoco
import numpy as np

from jaxarm.deploy import peg, scoring
from jaxarm.deploy.kinematics import ArmKinematics
from jaxarm.deploy.loop import DeploymentLoop
from jaxarm.deploy.mujoco_robot import MujocoRobot
from jaxarm.deploy.reading import HoleEstimate
from jaxarm.deployable.base import Capture, Deployable
from jaxarm.envs.peg_insert import env as peg_env
from jaxarm.envs.peg_insert import model as peg_model
from jaxarm.envs.peg_insert.render import paint_surfaces


def peg_task(env: peg_env.PegInsert, params) -> peg.PegTask:
    """The peg's `PegTask` of `env` (of state observations or cameras: the controller is the same) with `params`."""
    return peg.PegTask(
        running_target=env.running_target,
        ee_step=float(params.ee_step),
        max_lead=float(params.max_lead),
        ik_damping=float(params.ik_damping),
        ik_posture_gain=float(params.ik_posture_gain),
        start_qpos=np.asarray(env.start_qpos, np.float64),
        home_tcp_rotation=np.asarray(env.home_tcp_rotation, np.float64),
        hole_nominal=np.array(peg_model.HOLE_NOMINAL),
        hole_floor=peg_model.HOLE_FLOOR,
        position_scale=peg_env.POSITION_SCALE,
    )


def peg_reward(params) -> scoring.PegReward:
    names = scoring.PegReward.__dataclass_fields__
    return scoring.PegReward(**{name: float(getattr(params, name)) for name in names})


def controller(env: peg_env.PegInsert, params) -> peg.PegController:
    return peg.PegController(peg_task(env, params), ArmKinematics(env.mj_model, env.robot))


def scene(env: peg_env.PegInsert, params, robot_xml: Path) -> mujoco.MjModel:
    """The env's scene with its robot's model `robot_xml`, its walls at the params' clearance."""
    return peg_model.build_model(float(params.clearance), robot=env.robot.name, robot_xml=robot_xml)


def set_walls(model: mujoco.MjModel, ids: peg_model.PegIds, params) -> None:
    """The peg block's walls (`ids`' in `model`) at the params' clearance, as the env places them."""
    centres, halves = (np.asarray(array) for array in peg_model.hole_walls(np.float32(params.clearance)))
    model.geom_pos[ids.wall_geoms] = centres
    model.geom_size[ids.wall_geoms] = halves


def episode(
    robot: MujocoRobot,
    loop: DeploymentLoop,
    env: peg_env.PegInsert,
    params,
    sim,
    capture: Capture,
    pose_bias: np.ndarray,
) -> dict:
    """One peg episode from `sim` (the env's reset), the hole's estimated centre off by `pose_bias`' x and y (m);
    its success (inserted at any step), return and steps."""
    model, data = robot.model, robot.data
    ids = peg_model.resolve_ids(model, env.robot.name)
    model.body_pos[ids.block_body] = [*sim.hole, 0.0]
    paint_surfaces(model, ids, np.asarray(sim.surface_gray))  # as the env's cameras saw the episode
    set_walls(model, ids, params)  # the env's own scene has them at the default clearance
    mujoco.mj_resetData(model, data)
    data.qpos[:] = sim.qpos
    robot.command(sim.ctrl)
    mujoco.mj_forward(model, data)
    reward = peg_reward(params)
    radius, half_length = model.geom_size[ids.peg_geom, :2]
    hole_bottom = np.array([*sim.hole, peg_model.HOLE_FLOOR])

    def distance() -> float:
        return float(np.linalg.norm(data.site_xpos[ids.peg_tip] - hole_bottom))

    touched = [False]

    def check_table(data: mujoco.MjData) -> None:
        touched[0] |= scoring.capsule_below_plane(
            data.geom_xpos[ids.peg_geom],
            data.geom_xmat[ids.peg_geom].reshape(3, 3),
            radius,
            half_length,
            data.geom_xpos[ids.table_geom],
            data.geom_xmat[ids.table_geom].reshape(3, 3),
        )

    hole = HoleEstimate(sim.hole.astype(np.float64) + pose_bias[:2])
    loop.begin(sim.ctrl)
    initial = previous = distance()
    total, steps, success = 0.0, 0, False
    capture(data)
    while steps < int(params.max_episode_steps):
        steps += 1
        robot.command(loop.tick(robot.reading(), hole))
        robot.step(check_table)
        capture(data)
        now = distance()
        total += scoring.peg_reward(previous, now, initial, reward)
        success |= now < reward.insert_distance
        previous = now
        if touched[0] or now > reward.max_distance:
            break
    return {"success": bool(success), "return": total, "steps": steps}


DEPLOYABLE = Deployable(peg_env.PegInsert, controller, scene, episode)

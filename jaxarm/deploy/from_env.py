"""A jaxarm env's numbers for the deployment loop: `controller(env, params)` builds the task's numpy controller
from a `PandaSort` or `PegInsert` and its params (imports JAX; the rest of `jaxarm.deploy` does not)."""

import numpy as np

from jaxarm.deploy import peg, scoring, sort
from jaxarm.deploy.kinematics import ArmKinematics
from jaxarm.deploy.loop import Controller
from jaxarm.envs.panda_sort import env as sort_env
from jaxarm.envs.panda_sort.layout import Layout
from jaxarm.envs.peg_insert import env as peg_env
from jaxarm.envs.peg_insert import model as peg_model


def bins(layout: Layout) -> scoring.Bins:
    return scoring.Bins(np.array(layout.bin_centers), layout.bin_half, layout.bin_wall_height)


def sort_task(env: sort_env.PandaSort, params) -> sort.SortTask:
    """The sorter's `SortTask` of `env` (state observations) with `params`."""

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
        bins=bins(env.layout),
        tcp_min_z=sort_env.TCP_MIN_Z,
        finger_open=sort_env.FINGER_OPEN,
    )


def sort_reward(env: sort_env.PandaSort, params) -> scoring.SortReward:
    """The sorter's reward params of `params`."""
    names = [field for field in scoring.SortReward.__dataclass_fields__ if field != "target_first"]
    return scoring.SortReward(**{name: float(getattr(params, name)) for name in names}, target_first=env.target_first)


def peg_task(env: peg_env.PegInsert, params) -> peg.PegTask:
    """The peg's `PegTask` of `env` (state observations) with `params`."""
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


def runs(env) -> bool:
    """Whether the deployment loop runs `env` (or the env it wraps): a `PandaSort` or `PegInsert` with state
    observations."""
    env = getattr(env, "unwrapped", env)
    return isinstance(env, sort_env.PandaSort | peg_env.PegInsert) and env.obs_mode == "state"


def controller(env, params) -> Controller:
    """The numpy controller of `env` (one the loop `runs`) with `params`, posing the arm in the env's own model.
    ValueError for any other env."""
    env = getattr(env, "unwrapped", env)
    if not runs(env):
        raise ValueError(
            f"the deployment loop runs the sorter and the peg with state observations, not {type(env).__name__} "
            f"with {getattr(env, 'obs_mode', 'its')} observations"
        )
    kinematics = ArmKinematics(env.mj_model)
    if isinstance(env, sort_env.PandaSort):
        return sort.SortController(sort_task(env, params), kinematics)
    return peg.PegController(peg_task(env, params), kinematics)

"""The peg's glue: its `jaxarm.deploy.peg` task and reward read from a `PegInsert` and its params."""

import numpy as np

from jaxarm.deploy import peg, scoring
from jaxarm.envs.peg_insert import env as peg_env
from jaxarm.envs.peg_insert import model as peg_model


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

"""The sorter's glue: its `jaxarm.deploy.sort` task, bins and reward read from a `PandaSort` and its params."""

import numpy as np

from jaxarm.deploy import scoring, sort
from jaxarm.envs.panda_sort import env as sort_env
from jaxarm.envs.panda_sort.layout import Layout


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

"""Which envs the deployment loop runs, and their controllers."""

from jaxarm.deploy import peg, sort
from jaxarm.deploy.kinematics import ArmKinematics
from jaxarm.deploy.loop import Controller
from jaxarm.deployable import panda_sort, peg_insert
from jaxarm.envs.panda_sort import env as sort_env
from jaxarm.envs.peg_insert import env as peg_env


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
        return sort.SortController(panda_sort.sort_task(env, params), kinematics)
    return peg.PegController(peg_insert.peg_task(env, params), kinematics)

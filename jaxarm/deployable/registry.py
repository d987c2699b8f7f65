"""The tasks the deployment loop runs, one entry each: a new deployable task is its module and one line in
`DEPLOYABLES`."""

from jaxarm.deploy.loop import Controller
from jaxarm.deployable import panda_sort, peg_insert
from jaxarm.deployable.base import Deployable

DEPLOYABLES: tuple[Deployable, ...] = (panda_sort.DEPLOYABLE, peg_insert.DEPLOYABLE)


def find(env) -> Deployable | None:
    """The entry of `env` (or the env it wraps) if it is one of `DEPLOYABLES`' envs with state observations."""
    env = getattr(env, "unwrapped", env)
    if getattr(env, "obs_mode", None) != "state":
        return None
    return next((listed for listed in DEPLOYABLES if isinstance(env, listed.env_class)), None)


def entry(env) -> Deployable:
    """`find(env)`; ValueError naming the envs the loop runs where it runs no task of `env`."""
    found = find(env)
    if found is None:
        env = getattr(env, "unwrapped", env)
        names = ", ".join(listed.env_class.__name__ for listed in DEPLOYABLES)
        raise ValueError(
            f"the deployment loop runs {names} with state observations, not {type(env).__name__} "
            f"with {getattr(env, 'obs_mode', 'its')} observations"
        )
    return found


def runs(env) -> bool:
    """Whether the deployment loop runs `env` (or the env it wraps)."""
    return find(env) is not None


def controller(env, params) -> Controller:
    """The numpy controller of `env` (one the loop `runs`) with `params`, posing the arm in the env's own model.
    ValueError for any other env."""
    return entry(env).controller(getattr(env, "unwrapped", env), params)

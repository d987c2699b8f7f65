"""Pure-functional JAX environments: `make(name)`, `names()`, and the contract in `base`."""

from jaxarm._runtime import compiler_options
from jaxarm.envs.base import (
    Env,
    EnvSpec,
    EnvState,
    EpisodeStats,
    Observation,
    Transition,
    check_action,
    deferred_step_checks,
)
from jaxarm.envs.registry import (
    describe,
    families,
    make,
    names,
    override_params,
    register,
    registered_kwargs,
    uses_mjx,
)
from jaxarm.envs.wrappers import AutoReset, VmapEnv, Wrapper

__all__ = [
    "AutoReset",
    "Env",
    "EnvSpec",
    "EnvState",
    "EpisodeStats",
    "Observation",
    "Transition",
    "VmapEnv",
    "Wrapper",
    "check_action",
    "compiler_options",
    "deferred_step_checks",
    "describe",
    "families",
    "make",
    "names",
    "override_params",
    "register",
    "registered_kwargs",
    "uses_mjx",
]

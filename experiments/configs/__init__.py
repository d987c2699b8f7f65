"""Named run presets: `get(name)` returns a validated config, `names()` and `describe()` list them.

A preset is a function returning a frozen config, registered with `@preset` (registry.py) in its learner's
module of presets; each is imported below. The learner is the one `jaxarm.agents.registry` registers for
the config's class.
"""

# Importing a learner's preset module registers its presets.
from experiments.configs import ppo, td3  # noqa: F401
from experiments.configs.registry import PRESETS
from jaxarm.agents.common.config import RunConfig
from jaxarm.envs.registry import closest_match_hint

__all__ = ["describe", "get", "names"]


def names() -> list[str]:
    return sorted(PRESETS)


def describe() -> dict[str, str]:
    return {name: PRESETS[name].description for name in names()}


def get(name: str, validate: bool = True) -> RunConfig:
    """The preset `name`, validated (`validate=False`: as declared; validating builds its env, which starts JAX's
    backend); ValueError naming the closest preset for an unknown name."""
    if name not in PRESETS:
        raise ValueError(f"unknown config {name!r}{closest_match_hint(name, PRESETS)}; see --list")
    config = PRESETS[name].make()
    if validate:
        config.validate()
    return config

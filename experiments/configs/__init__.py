"""Named run presets: `get(name)` returns a validated config, `names()` and `describe()` list them.

A preset is a function returning a frozen config, registered with `@preset`; modules beside this one
define them (one module per learner). The learner is chosen by the config's type (`AGENT`).
"""

import importlib
from collections.abc import Callable

from jaxarm.agents.common.config import RunConfig
from jaxarm.envs.registry import closest_match_hint

_PRESETS: dict[str, tuple[Callable[[], RunConfig], str]] = {}
_MODULES = ("ppo", "td3")


def preset(description: str):
    """Decorator registering a config function under its own name with a one-line description."""

    def register(function: Callable[[], RunConfig]):
        if function.__name__ in _PRESETS:
            raise ValueError(f"preset {function.__name__!r} is defined twice")
        _PRESETS[function.__name__] = (function, description)
        return function

    return register


def _load_all() -> None:
    for module in _MODULES:
        importlib.import_module(f"experiments.configs.{module}")


def names() -> list[str]:
    _load_all()
    return sorted(_PRESETS)


def describe() -> dict[str, str]:
    return {name: _PRESETS[name][1] for name in names()}


def get(name: str) -> RunConfig:
    """The preset `name`, validated; ValueError naming the closest preset for an unknown name."""
    _load_all()
    if name not in _PRESETS:
        raise ValueError(f"unknown config {name!r}{closest_match_hint(name, _PRESETS)}; see --list")
    config = _PRESETS[name][0]()
    config.validate()
    return config


def make_trainer(config: RunConfig):
    """Builds the learner the config is for: `jaxarm.agents.<AGENT>.make_trainer(config)`."""
    return importlib.import_module(f"jaxarm.agents.{config.AGENT}").make_trainer(config)

"""The `@preset` decorator and the presets it has registered (see experiments/configs/__init__.py)."""

import dataclasses
from collections.abc import Callable

from jaxarm.agents.common.config import RunConfig


@dataclasses.dataclass(frozen=True)
class Preset:
    """A named run config: `make()` returns it; `description` is its line in `--list`."""

    make: Callable[[], RunConfig]
    description: str


PRESETS: dict[str, Preset] = {}


def preset(description: str):
    """Decorator registering a config function under its own name with a one-line description."""

    def register(function: Callable[[], RunConfig]):
        if function.__name__ in PRESETS:
            raise ValueError(f"preset {function.__name__!r} is defined twice")
        PRESETS[function.__name__] = Preset(function, description)
        return function

    return register

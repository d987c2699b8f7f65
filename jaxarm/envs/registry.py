"""Named envs: `make(name, **kwargs)` builds one (once per arguments), `names()` lists them, `override_params`
edits params. A namespace (`register_namespace`) names a family of envs another library defines, `PREFIX:NAME`
(`playground:PandaPickCube`): each is built on demand and none is listed, so that listing never imports that library.

Env kwargs are flat (`env_kwargs.impl=warp` in a config): an env whose constructor takes an options record (the
Panda tasks' `ArmOptions`) gets those naming its fields gathered into it (`constructor_kwargs`).

Factories import their module lazily so that making arm2d never imports MuJoCo.
"""

import dataclasses
import difflib
import importlib
import inspect
from collections.abc import Mapping
from typing import Any

import jax.numpy as jnp
import numpy as np

from jaxarm import ranges
from jaxarm.envs.base import Env


@dataclasses.dataclass(frozen=True)
class EnvEntry:
    """A registered env: `module:Class` to construct, fixed constructor kwargs, one line of description."""

    target: str
    kwargs: Mapping[str, Any]
    description: str

    def env_class(self) -> type[Env]:
        module_name, class_name = self.target.split(":")
        return getattr(importlib.import_module(module_name), class_name)

    def build(self, **kwargs):
        cls = self.env_class()
        return cls(**constructor_kwargs(cls, {**self.kwargs, **kwargs}))


OPTIONS = "options"
"""The constructor keyword of an env's options record."""


def options_class(cls: type) -> type | None:
    """The options record (a frozen dataclass) `cls`'s constructor takes: its `options` keyword's default's type;
    None for a constructor without one."""
    parameter = inspect.signature(cls).parameters.get(OPTIONS)
    return None if parameter is None else type(parameter.default)


def kwarg_defaults(cls: type) -> dict[str, Any]:
    """Every flat env kwarg `cls`'s constructor takes (each field of its options record as one) -> its default."""
    defaults = {
        name: parameter.default
        for name, parameter in inspect.signature(cls).parameters.items()
        if name != OPTIONS and parameter.kind not in (parameter.VAR_POSITIONAL, parameter.VAR_KEYWORD)
    }
    options = options_class(cls)
    if options is not None:
        defaults.update({field.name: field.default for field in dataclasses.fields(options)})
    return defaults


def constructor_kwargs(cls: type, kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """Flat env kwargs as `cls`'s constructor takes them: those naming a field of its options record (if it has one
    and `kwargs` gives none) gathered into one under `options`; the rest as they are. TypeError for a name `cls`
    does not take, listing those it does (the constructor's own error names neither)."""
    known = kwarg_defaults(cls)
    takes_any = any(parameter.kind == parameter.VAR_KEYWORD for parameter in inspect.signature(cls).parameters.values())
    for name in kwargs:
        if name not in known and name != OPTIONS and not takes_any:  # a `**kwargs` constructor checks its own
            raise TypeError(
                f"{cls.__name__} takes no env kwarg {name!r}{closest_match_hint(name, known)}; "
                f"it takes {', '.join(known)}"
            )
    options = options_class(cls)
    if options is None or OPTIONS in kwargs:
        return dict(kwargs)
    fields = {field.name for field in dataclasses.fields(options)}
    own = {name: value for name, value in kwargs.items() if name not in fields}
    return {**own, OPTIONS: options(**{name: value for name, value in kwargs.items() if name in fields})}


_REGISTRY: dict[str, EnvEntry] = {}
_NAMESPACES: dict[str, EnvEntry] = {}
"""Prefix -> the entry every `PREFIX:NAME` is built from, with NAME as its constructor's `task`."""


def register(name: str, target: str, description: str, **kwargs) -> None:
    """Registers `name` as `target` ("package.module:Class") built with `kwargs`."""
    if name in _REGISTRY:
        raise ValueError(f"env {name!r} is already registered")
    _REGISTRY[name] = EnvEntry(target, kwargs, description)


def register_namespace(prefix: str, target: str, description: str) -> None:
    """Registers every name `prefix:NAME` as `target` ("package.module:Class") built with `task=NAME`."""
    if prefix in _NAMESPACES:
        raise ValueError(f"env namespace {prefix!r} is already registered")
    _NAMESPACES[prefix] = EnvEntry(target, {}, description)


def closest_match_hint(name: str, candidates) -> str:
    """' (did you mean 'x'?)' for the closest candidate, or '' when nothing is close."""
    matches = difflib.get_close_matches(name, list(candidates), n=1)
    return f" (did you mean {matches[0]!r}?)" if matches else ""


def names() -> list[str]:
    """All registered env names, sorted."""
    return sorted(_REGISTRY)


def describe() -> dict[str, str]:
    """Env name -> one-line description."""
    return {name: _REGISTRY[name].description for name in names()}


def families() -> dict[str, list[str]]:
    """Env class ("package.module:Class") -> the names registered for it, sorted: the variants of one env."""
    grouped: dict[str, list[str]] = {}
    for name in names():
        grouped.setdefault(_REGISTRY[name].target, []).append(name)
    return grouped


def registered_kwargs(name: str) -> dict[str, Any]:
    """The constructor arguments env `name` is registered with (a variant such as arm2d_pixels fixes some)."""
    return dict(entry(name).kwargs)


_BUILT: dict[tuple, Any] = {}
"""(name, sorted kwargs) -> the env `make` built for them."""


def entry(name: str) -> EnvEntry:
    """The registration of `name` (a `PREFIX:NAME` of a namespace: its entry with `task=NAME`); KeyError naming the
    closest registered env for an unknown name."""
    if name in _REGISTRY:
        return _REGISTRY[name]
    prefix, _, task = name.partition(":")
    if task and prefix in _NAMESPACES:
        namespace = _NAMESPACES[prefix]
        return EnvEntry(namespace.target, {"task": task}, f"{namespace.description}: {task}")
    spaces = "".join(f", {prefix}:NAME" for prefix in sorted(_NAMESPACES))
    raise KeyError(f"unknown env {name!r}{closest_match_hint(name, _REGISTRY)}; known: {', '.join(names())}{spaces}")


def uses_mjx(name: str) -> bool:
    """Whether the env `name` steps MJX physics (`Env.uses_mjx`), read from its class: nothing is built."""
    return entry(name).env_class().uses_mjx


def draws_with_gl(name: str) -> bool:
    """Whether the env `name` draws with MuJoCo's OpenGL renderer (`Env.draws_with_gl`), read from its class."""
    return entry(name).env_class().draws_with_gl


def make(name: str, **kwargs):
    """The registered env `name`; `kwargs` override its static constructor arguments.

    An env is immutable once built, so every call with the same (hashable) arguments returns the same instance:
    a run's config checks, trainer and evaluations share one env, whose MJX scene takes seconds to build.
    """
    registered = entry(name)
    key = (name, tuple(sorted(kwargs.items())))
    try:
        hash(key)
    except TypeError:  # a list-valued kwarg from the CLI: built each time
        return registered.build(**kwargs)
    if key not in _BUILT:
        _BUILT[key] = registered.build(**kwargs)
    return _BUILT[key]


def override_params(params, overrides: Mapping[str, Any], prefix: str = "env param "):
    """Returns `params` with fields replaced by `overrides`, cast to each field's dtype and shape.

    Raises KeyError naming the closest field for an unknown name, ValueError for a value of the wrong shape or
    type, or outside the field's declared range (`jaxarm.ranges`), or breaking the params' order relations.
    Messages name a param as `prefix + name`.
    """
    fields = {field.name for field in dataclasses.fields(params)}
    updates = {}
    for name, value in overrides.items():
        if name not in fields:
            raise KeyError(f"unknown {prefix}{name}{closest_match_hint(name, fields)}")
        current = np.asarray(getattr(params, name))
        array = ranges.param_array(f"{prefix}{name}", value, current)
        if array.shape != current.shape:
            raise ValueError(f"{prefix}{name} needs shape {current.shape}, got {array.shape}")
        updates[name] = jnp.asarray(array)
    changed = params.replace(**updates)
    ranges.check_params(changed, updates, prefix)
    return changed


register("arm2d", "jaxarm.envs.arm2d:Arm2d", "2-link planar reaching arm (the classic tutorial arm)")
register(
    "arm2d_pixels",
    "jaxarm.envs.arm2d:Arm2d",
    "2-link arm seen by a 64x64 grayscale camera from above (links and goal), no state",
    obs_mode="pixels",
)
register(
    "arm2d_pixels_proprio",
    "jaxarm.envs.arm2d:Arm2d",
    "2-link arm: camera image (the goal is seen only there) and the link ends' positions",
    obs_mode="pixels+proprio",
)
register("arm2d_squid", "jaxarm.envs.arm2d:Arm2d", "5-link planar reaching arm ('squid arm')", num_links=5)
register(
    "panda_sort",
    "jaxarm.envs.panda_sort:PandaSort",
    "Franka Panda (MJX) sorting 1 object into shape bins, end-effector control",
)
register(
    "panda_sort3",
    "jaxarm.envs.panda_sort:PandaSort",
    "Panda sorter with 3 objects, one target at a time (observed first)",
    objects_count=3,
    target_first=True,
)
register(
    "panda_sort_blocker",
    "jaxarm.envs.panda_sort:PandaSort",
    "Panda sorter with a bar between objects and bins",
    blocker=True,
)
register(
    "panda_sort_pixels",
    "jaxarm.envs.panda_sort:PandaSort",
    "Panda sorter seen by an overhead and a wrist camera (64x64 gray and depth) with the tool's state",
    obs_mode="pixels+proprio",
)
register(
    "panda_sort_joint",
    "jaxarm.envs.panda_sort:PandaSort",
    "Panda sorter with joint-delta control",
    control_mode="joint",
)
register(
    "panda_sort_tosser",
    "jaxarm.envs.panda_sort:PandaSort",
    "Panda sorter with the bins out of reach: a tosser",
    tosser=True,
)
register(
    "peg_insert",
    "jaxarm.envs.peg_insert:PegInsert",
    "a robot arm (MJX; env_kwargs.robot, the Panda by default) inserting a peg into a square hole shifted at random, "
    "end-effector control",
)
register(
    "peg_insert_ur5e",
    "jaxarm.envs.peg_insert:PegInsert",
    "peg insertion on a Universal Robots UR5e with a two-finger gripper (the task's tutorial's arm)",
    robot="ur5e",
)
register(
    "peg_insert_pixels",
    "jaxarm.envs.peg_insert:PegInsert",
    "peg insertion seen by a scene and a wrist camera (64x64 gray and depth) with the arm's own state",
    obs_mode="pixels+proprio",
)
register_namespace(
    "playground",
    "jaxarm.interop.playground:PlaygroundEnv",
    "MuJoCo Playground's task of that registry name (the playground extra; jaxarm.interop.playground)",
)

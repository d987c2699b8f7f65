"""`--show`: every config field (type, value, docstring), the env's constructor arguments (value, default,
docstring) and the env's params (value, default, docstring).

The docs are the `Attributes:` sections of the config's and the params' class docstrings and the `Args:` sections
of the env classes', where each field or argument is documented once.
"""

import dataclasses
import enum
import re
import textwrap
import typing

import numpy as np

from jaxarm import envs, ranges
from jaxarm.agents.common.config import RunConfig
from jaxarm.envs.registry import kwarg_defaults, options_class

_ENTRY = re.compile(r"^\s{2,}(\w+): (.*)$")
_SECTION = re.compile(r"^\s{0,4}[A-Z]\w*( \(.*\))?:$")
"""A docstring section's header ("Attributes:", "Args:"), where the previous section ends."""


def attribute_docs(cls: type, section: str = "Attributes") -> dict[str, str]:
    """{field: its line(s) in the `Attributes:` (or another `section`'s) sections of `cls` and its bases'
    docstrings}."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        doc = klass.__dict__.get("__doc__") or ""
        header = re.search(rf"^\s*{section}( \(.*\))?:$", doc, re.MULTILINE)
        if header is None:
            continue
        current = None
        for line in doc[header.end() :].splitlines()[1:]:
            if _SECTION.match(line):
                break
            match = _ENTRY.match(line)
            if match and len(line) - len(line.lstrip()) <= 6:
                current = match.group(1)
                docs[current] = match.group(2).strip()
            elif current and line.strip():
                docs[current] += " " + line.strip()
            elif not line.strip() and current:
                current = None
    return docs


def _type_name(annotation) -> str:
    return annotation.__name__ if isinstance(annotation, type) else str(annotation).replace("typing.", "")


def _wrapped(doc: str) -> str:
    return textwrap.fill(doc, width=116, initial_indent=" " * 6, subsequent_indent=" " * 6)


def _allowed(field: dataclasses.Field, before: str = ", ", after: str = "") -> str:
    allowed = ranges.declared_range(field)
    return f"{before}{allowed.describe()}{after}" if allowed else ""


def config_lines(config: RunConfig) -> list[str]:
    """One line per config field: name, type, this config's value (and the class default where it differs), doc."""
    hints = typing.get_type_hints(type(config))
    docs = attribute_docs(type(config))
    lines = []
    for field in dataclasses.fields(config):
        value = getattr(config, field.name)
        default = field.default
        changed = "" if value == default else f"  (default {default!r})"
        marks = " [dynamic]" if field.metadata.get("dynamic") else ""
        lines.append(f"  {field.name} ({_type_name(hints[field.name])}{marks}{_allowed(field)}) = {value!r}{changed}")
        if field.name in docs:
            lines.append(_wrapped(docs[field.name]))
    return lines


def _plain(value) -> str:
    array = np.asarray(value)
    return str(array[()]) if array.ndim == 0 else np.array2string(array, separator=",", precision=4)


def env_param_lines(config: RunConfig) -> list[str]:
    """One line per env param: name, this config's training value (and the env default where it differs), doc."""
    env, params = config.make_env()
    defaults = env.default_params()
    docs = attribute_docs(type(params))
    lines = []
    for field in dataclasses.fields(params):
        value, default = _plain(getattr(params, field.name)), _plain(getattr(defaults, field.name))
        changed = "" if value == default else f"  (default {default})"
        lines.append(f"  env_params.{field.name}{_allowed(field, ' (', ')')} = {value}{changed}")
        if field.name in docs:
            lines.append(_wrapped(docs[field.name]))
    return lines


def env_kwarg_lines(config: RunConfig) -> list[str]:
    """One line per constructor argument of the config's env (each field of its options record, `ArmOptions`, as
    one): name, the value the config builds it with (and the default where it differs), doc (from the class's
    `Args:`, the options record's `Attributes:`)."""
    env, _ = config.make_env(randomized=False)  # the env itself, no Randomized wrapper
    cls = type(env)
    built = {**envs.registered_kwargs(config.env), **dict(config.env_kwargs)}
    docs = attribute_docs(cls, "Args")
    options = options_class(cls)
    if options is not None:
        docs.update(attribute_docs(options))
    defaults = kwarg_defaults(cls)
    lines = []
    for name, default in defaults.items():
        default = _enum_value(default)
        value = _enum_value(built.get(name, default))
        changed = "" if value == default else f"  (default {default!r})"
        lines.append(f"  env_kwargs.{name} = {value!r}{changed}")
        if name in docs:
            lines.append(_wrapped(docs[name]))
    return lines


def _enum_value(value):
    return value.value if isinstance(value, enum.Enum) else value


def describe(config: RunConfig, preset: str) -> str:
    """The text `--show` prints for `config` (the preset `preset` with any overrides)."""
    return "\n".join(
        [
            f"{preset}: {type(config).__name__} (set any field as key=value; lists as 64,64 or [64,64])",
            *config_lines(config),
            f"env {config.env!r} constructor arguments (env_kwargs.NAME=VALUE):",
            *env_kwarg_lines(config),
            f"env {config.env!r} params (env_params.NAME=VALUE; eval_env_params.NAME=VALUE for evaluation only):",
            *env_param_lines(config),
        ]
    )
